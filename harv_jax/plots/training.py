"""The training curve of a run: mean episode return +- std over seeds, and episode outcomes, vs env steps."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from harv_jax import atomic


def plot_training_curve(path: Path, history: list[dict[str, Any]], title: str) -> Path:
    """Mean episode return +- std over seeds vs env steps (the paper's reward-vs-steps figure)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = np.array([row["env_steps"] for row in history], np.float64)
    ret = np.stack([np.asarray(row["episode_return"], np.float64).reshape(-1) for row in history])
    mean, std = np.nanmean(ret, axis=1), np.nanstd(ret, axis=1)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    ax = axes[0]
    ax.plot(steps, mean, color="C0", label=f"mean over {ret.shape[1]} seed(s)")
    ax.fill_between(steps, mean - std, mean + std, color="C0", alpha=0.25, label="+- 1 std")
    for s in range(ret.shape[1]):
        ax.plot(steps, ret[:, s], color="C0", lw=0.6, alpha=0.4)
    ax.set_xlabel("env steps per seed")
    ax.set_ylabel("mean episode return")
    ax.grid(alpha=0.3)
    ax.legend()
    ax = axes[1]
    for k, label, c in (
        ("episode/recovered", "recovered at episode end", "C2"),
        ("episode/terminated", "terminated (left envelope)", "C3"),
    ):
        if k in history[0]:
            v = np.stack([np.asarray(row[k], np.float64).reshape(-1) for row in history])
            m, s = np.nanmean(v, axis=1), np.nanstd(v, axis=1)
            ax.plot(steps, m, color=c, label=label)
            ax.fill_between(steps, m - s, m + s, color=c, alpha=0.2)
    ax.set_xlabel("env steps per seed")
    ax.set_ylabel("fraction of episodes")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.suptitle(textwrap.fill(title, width=110))  # a long command stays inside the figure
    fig.tight_layout()
    atomic.save_figure(fig, path, dpi=120)
    plt.close(fig)
    return path
