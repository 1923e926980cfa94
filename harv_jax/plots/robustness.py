"""Figures of a robustness sweep: recovery rate, mean recovery time and control TV against each level."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from harv_jax import atomic


def _nan(v: float | None) -> float:
    return np.nan if v is None else float(v)


def plot_robustness(doc: dict[str, Any], out_dir: Path) -> list[Path]:
    """One figure per disturbance (``robustness_<name>.png``): three panels against the level, a line per
    controller; the margin's recovery bar dashed on the first panel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    for name, d in doc["disturbances"].items():
        fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), constrained_layout=True)
        for c, block in d["controllers"].items():
            lv = np.array([r["level"] for r in block["rows"]])
            rec = 100 * np.array([_nan(r["recovery_rate"]) for r in block["rows"]])
            t = np.array([_nan(r["t_recover_mean_nr_at_run_s"]) for r in block["rows"]])
            tv = np.array([r["control_tv_mean_rad"] for r in block["rows"]])
            axes[0].plot(lv, rec, "o-", label=c)
            axes[1].plot(lv, t, "o-", label=c)
            axes[2].plot(lv, tv, "o-", label=c)
        axes[0].axhline(100 * doc["margin_recovery"], ls="--", c="k", lw=0.8)
        axes[0].set_ylabel("recovered [%]")
        axes[1].set_ylabel(f"mean recovery time [s] (not recovered: {doc['duration_s']:g} s)")
        axes[2].set_ylabel("control TV, mean over runs [rad]")
        axes[2].set_yscale("log")
        for ax in axes:
            ax.set_xlabel(f"{name} level [{d['unit']}]")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=8)
        fig.suptitle(f"{name}: {doc['runs']} runs per level, seed {doc['seed']}")
        path = out_dir / f"robustness_{name}.png"
        atomic.save_figure(fig, path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
