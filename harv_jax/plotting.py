"""Figures in the paper's layout: (V, alpha, beta) / (p, q, r) / (mu, gamma, h - h0) / (de, da, dr)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from harv_jax.units import DEG_PER_RAD  # noqa: E402

_PANELS = (
    (
        ("V", "V [ft/s]", 1.0),
        ("alpha", "alpha [deg]", DEG_PER_RAD),
        ("beta", "beta [deg]", DEG_PER_RAD),
    ),
    (
        ("p", "p [deg/s]", DEG_PER_RAD),
        ("q", "q [deg/s]", DEG_PER_RAD),
        ("r", "r [deg/s]", DEG_PER_RAD),
    ),
    (
        ("mu", "mu [deg]", DEG_PER_RAD),
        ("gamma", "gamma [deg]", DEG_PER_RAD),
        ("dh", "h - h0 [ft]", 1.0),
    ),
    (
        ("de", "de [deg]", DEG_PER_RAD),
        ("da", "da [deg]", DEG_PER_RAD),
        ("dr", "dr [deg]", DEG_PER_RAD),
    ),
)


def plot_time_histories(
    t_s: np.ndarray,
    runs: Mapping[str, Mapping[str, np.ndarray]],
    path: str | Path,
    title: str = "",
    references: Mapping[str, float] | None = None,
    t_marker_s: float | None = None,
) -> Path:
    """Overlay time histories of one or more runs in a 4 x 3 grid (the paper's four figures).

    Args:
        t_s: [T] time, s.
        runs: label -> columns (``V, alpha, beta, p, q, r, mu, gamma, h, de, da, dr``; rad, ft).
        path: PNG path to write.
        title: figure title.
        references: optional column -> reference value (rad) drawn dashed.
        t_marker_s: optional time of a vertical marker (e.g. controller engagement).
    """
    fig, axes = plt.subplots(4, 3, figsize=(13, 11), sharex=True)
    for row, panel in zip(axes, _PANELS, strict=True):
        for ax, (name, label, scale) in zip(row, panel, strict=True):
            for run_label, cols in runs.items():
                y = cols["h"] - cols["h"][0] if name == "dh" else cols[name]
                ax.plot(t_s, np.asarray(y) * scale, label=run_label, lw=1.0)
            if references and name in references:
                ax.axhline(references[name] * scale, color="k", ls="--", lw=0.8)
            if t_marker_s is not None:
                ax.axvline(t_marker_s, color="grey", ls=":", lw=0.8)
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    if len(runs) > 1:
        axes[0, 0].legend(fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
