"""Figures of the optimal-recovery study: each controller's time against the optimum, and the search."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from harv_jax import atomic


def plot_vs_optimal(
    t_optimal_s: np.ndarray, t_controllers_s: Mapping[str, np.ndarray], path: str | Path, title: str = ""
) -> Path:
    """Left: each controller's recovery time against the optimum's, run by run (the diagonal: equal).
    Right: CDF over runs of the ratio controller / optimum. Not-recovered runs count at the run length."""
    fig, (ax_s, ax_c) = plt.subplots(1, 2, figsize=(11, 4.5))
    t_opt = np.asarray(t_optimal_s, float)
    hi = max([float(np.max(t_opt))] + [float(np.max(t)) for t in t_controllers_s.values()]) * 1.05
    for name, t in t_controllers_s.items():
        t = np.asarray(t, float)
        ax_s.scatter(t_opt, t, s=10, alpha=0.6, label=name)
        r = np.sort(t / np.maximum(t_opt, 1e-9))
        ax_c.step(r, np.arange(1, r.size + 1) / r.size, where="post", label=name)
    ax_s.plot([0, hi], [0, hi], "k--", lw=1, label="equal")
    ax_s.set(
        xlabel="optimal recovery time (s)",
        ylabel="controller's recovery time (s)",
        xlim=(0, hi),
        ylim=(0, hi),
    )
    ax_c.set(xlabel="recovery time / optimal (ratio)", ylabel="fraction of runs", xscale="log")
    ax_c.axvline(1.0, color="k", lw=1, ls="--")
    for ax in (ax_s, ax_c):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    atomic.save_figure(fig, path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_search_progress(
    objective: np.ndarray, round_t_recover_s: np.ndarray, iterations_per_round: int, path: str | Path
) -> Path:
    """Left: the surrogate against iteration (median and 25-75 % over runs, relative to each run's first
    value). Right: the true (re-simulated) recovery time of the current knots at the warm start and after
    each round (median over the runs that recover)."""
    fig, (ax_j, ax_t) = plt.subplots(1, 2, figsize=(11, 4))
    j = np.asarray(objective, float)
    rel = j / np.where(np.abs(j[:1]) > 0, j[:1], 1.0)
    it = np.arange(1, j.shape[0] + 1)
    ax_j.plot(it, np.nanmedian(rel, axis=1), label="median over runs")
    ax_j.fill_between(it, *np.nanpercentile(rel, [25, 75], axis=1), alpha=0.3, label="25-75 %")
    ax_j.set(xlabel="gradient step", ylabel="surrogate / its first value", title="search objective")
    t = np.asarray(round_t_recover_s, float)
    x = np.arange(t.shape[0]) * iterations_per_round
    med = [float(np.nanmedian(row)) if np.any(np.isfinite(row)) else np.nan for row in t]
    ax_t.plot(x, med, "o-", label="median (recovered runs)")
    ax_t.set(
        xlabel="gradient step", ylabel="re-simulated recovery time (s)", title="true score of the iterate"
    )
    for ax in (ax_j, ax_t):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    atomic.save_figure(fig, path, dpi=110)
    plt.close(fig)
    return Path(path)
