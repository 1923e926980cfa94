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


#: Percentiles of the Monte Carlo bands.
BAND_PERCENTILES = (5, 25, 50, 75, 95)


def band_percentiles(history_rad: np.ndarray) -> np.ndarray:
    """[5, T, 3] percentiles (BAND_PERCENTILES) over runs of [N, T, 3] alpha, beta, mu, in degrees."""
    return np.nanpercentile(np.degrees(history_rad), BAND_PERCENTILES, axis=0)


def write_bands_csv(t_s: np.ndarray, history_rad: np.ndarray, path: str | Path) -> Path:
    """bands_<controller>.csv: t and the BAND_PERCENTILES of alpha, beta, mu (deg) per sample time."""
    pct = band_percentiles(history_rad)
    names = [f"{y}_p{q}_deg" for y in ("alpha", "beta", "mu") for q in BAND_PERCENTILES]
    cols = [pct[j, :, i] for i in range(3) for j in range(len(BAND_PERCENTILES))]
    np.savetxt(path, np.column_stack([t_s, *cols]), delimiter=",", header=",".join(["t_s", *names]),
               comments="", fmt="%.6g")  # fmt: skip
    return Path(path)


def plot_mc_bands(
    t_s: np.ndarray, history_rad: np.ndarray, reference_rad: np.ndarray, path: str | Path, title: str = ""
) -> Path:
    """Monte Carlo bands of alpha, beta, mu: 5-95 and 25-75 percentiles and the median.

    Args:
        t_s: [T] sample times, s.
        history_rad: [N, T, 3] alpha, beta, mu of every run, rad.
        reference_rad: [3] references, rad.
        path: PNG path.
        title: figure title.
    """
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    names = ("alpha", "beta", "mu")
    pct = band_percentiles(history_rad)
    for i, (ax, name) in enumerate(zip(axes, names, strict=True)):
        p5, p25, p50, p75, p95 = pct[:, :, i]
        ax.fill_between(t_s, p5, p95, alpha=0.25, color="C0", lw=0, label="5-95%")
        ax.fill_between(t_s, p25, p75, alpha=0.45, color="C0", lw=0, label="25-75%")
        ax.plot(t_s, p50, color="C0", lw=1.2, label="median")
        ax.axhline(np.degrees(reference_rad[i]), color="k", ls="--", lw=0.8, label="reference")
        ax.set_ylabel(f"{name} [deg]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="upper right")
    axes[-1].set_xlabel("t [s]")
    fig.suptitle(title or f"Monte Carlo bands (N = {history_rad.shape[0]})")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_terminal_errors(errors_deg: Mapping[str, np.ndarray], path: str | Path) -> Path:
    """Histograms of terminal alpha, beta, mu errors (deg) per controller ([N, 3] arrays)."""
    fig, axes = plt.subplots(3, 1, figsize=(9, 9))
    for i, (ax, name) in enumerate(zip(axes, ("alpha", "beta", "mu"), strict=True)):
        vals = [np.clip(e[:, i], -10.0, 10.0) for e in errors_deg.values()]
        finite = np.concatenate([v[np.isfinite(v)] for v in vals]) if vals else np.zeros(1)
        lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (-1.0, 1.0)
        bins = np.linspace(min(lo, -0.5), max(hi, 0.5), 61)
        for label, v in zip(errors_deg, vals, strict=True):
            ax.hist(v[np.isfinite(v)], bins=bins, alpha=0.5, label=label)
        for x in (-0.5, 0.5):
            ax.axvline(x, color="k", ls=":", lw=0.8)
        ax.set_xlabel(f"terminal {name} error [deg] (mean over the last 1 s; clipped to +-10)")
        ax.set_ylabel("runs")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
