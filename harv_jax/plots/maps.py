"""Heat maps of the recovery envelope: outcome and recovery time per controller, side by side."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import BoundaryNorm, ListedColormap  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from harv_jax import atomic

#: Colours of the ``Outcome`` codes 0..4 (RECOVERED, TIMEOUT, DEPARTED, GROUND_HIT, NONFINITE). TIMEOUT and
#: DEPARTED (left the envelope on the way) are both "not recovered by the end of the run": amber and orange,
#: not a red that reads as a loss -- a longer run may recover them.
OUTCOME_COLORS: tuple[str, ...] = ("#2ca02c", "#ffd24d", "#f28e2b", "#7f3f00", "#000000")


def outcome_labels(outcome_names: tuple[str, ...], duration_s: float | None = None) -> list[str]:
    """Legend text of each outcome code; with ``duration_s`` the unrecovered ones say "by T s"."""
    by = f" by {duration_s:g} s" if duration_s is not None else ""
    text = {
        "RECOVERED": "recovered",
        "TIMEOUT": f"not recovered{by} (stayed in the envelope)",
        "DEPARTED": f"not recovered{by} (left the envelope on the way)",
        "GROUND_HIT": "hit the ground",
        "NONFINITE": "non-finite state",
    }
    return [text.get(n, n.lower()) for n in outcome_names]


def _axes_row(n: int, height_in: float = 4.4) -> tuple[plt.Figure, np.ndarray]:
    fig, axes = plt.subplots(
        1, n, figsize=(max(6.4, 0.8 + 4.6 * n), height_in), squeeze=False, sharey=True, layout="constrained"
    )
    return fig, axes[0]


def _save(fig: plt.Figure, path: str | Path) -> Path:
    path = Path(path)
    atomic.save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def plot_outcome_maps(
    x: np.ndarray,
    y: np.ndarray,
    outcomes: Mapping[str, np.ndarray],
    outcome_names: tuple[str, ...],
    x_label: str,
    y_label: str,
    path: str | Path,
    title: str = "",
    duration_s: float | None = None,
) -> Path:
    """Categorical maps of the outcome code per controller (green = recovered).

    Args:
        x: [n_x] grid x values (display units).
        y: [n_y] grid y values (display units).
        outcomes: controller -> [n_y, n_x] int outcome codes.
        outcome_names: names of codes 0, 1, ... (``OUTCOME_NAMES``).
        x_label, y_label: axis labels with units.
        path: PNG path.
        title: figure title.
        duration_s: run length, s: unrecovered outcomes are labelled "not recovered by T s".
    """
    n_codes = len(outcome_names)
    cmap = ListedColormap(OUTCOME_COLORS[:n_codes])
    norm = BoundaryNorm(np.arange(-0.5, n_codes + 0.5), n_codes)
    fig, axes = _axes_row(len(outcomes))
    for ax, (name, code) in zip(axes, outcomes.items(), strict=True):
        ax.pcolormesh(x, y, code, cmap=cmap, norm=norm, shading="nearest")
        ax.set_title(f"{name}: recovered {100.0 * np.mean(code == 0):.1f}%")
        ax.set_xlabel(x_label)
    axes[0].set_ylabel(y_label)
    labels = outcome_labels(outcome_names, duration_s)
    handles = [Patch(color=OUTCOME_COLORS[i], label=lab) for i, lab in enumerate(labels)]
    ncol = min(n_codes, 3, max(1, int(fig.get_figwidth() // 3.0)))  # a legend column needs about 3 in
    fig.legend(handles=handles, loc="outside lower center", ncol=ncol, fontsize=8, frameon=False)
    fig.suptitle(title or "recovery outcome", fontsize=10)
    return _save(fig, path)


def plot_time_maps(
    x: np.ndarray,
    y: np.ndarray,
    times_s: Mapping[str, np.ndarray],
    x_label: str,
    y_label: str,
    path: str | Path,
    title: str = "",
) -> Path:
    """Maps of the recovery time per controller on one colour scale; NaN (not recovered) is grey.

    Args:
        x: [n_x] grid x values (display units).
        y: [n_y] grid y values (display units).
        times_s: controller -> [n_y, n_x] recovery time, s (NaN where not recovered).
        x_label, y_label: axis labels with units.
        path: PNG path.
        title: figure title.
    """
    finite = np.concatenate([t[np.isfinite(t)].ravel() for t in times_s.values()] + [np.zeros(0)])
    vmin, vmax = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    if vmax <= vmin:
        vmax = vmin + 1.0
    cmap = plt.get_cmap("viridis").with_extremes(bad="#d0d0d0")
    fig, axes = _axes_row(len(times_s))
    mesh = None
    for ax, (name, t) in zip(axes, times_s.items(), strict=True):
        mesh = ax.pcolormesh(
            x, y, np.ma.masked_invalid(t), cmap=cmap, vmin=vmin, vmax=vmax, shading="nearest"
        )
        ok = np.isfinite(t)
        med = f", median {np.median(t[ok]):.1f} s" if ok.any() else ""
        ax.set_title(f"{name}{med}")
        ax.set_xlabel(x_label)
    axes[0].set_ylabel(y_label)
    fig.suptitle(title or "recovery time (grey: not recovered)", fontsize=10)
    fig.colorbar(mesh, ax=list(axes), label="recovery time [s]", shrink=0.9)
    return _save(fig, path)
