"""Recipes side by side at equal budget: learning curves of the training evaluation (every period, each seed's
policy RL-only on the same 64 upsets + 8 spins, 60 s) against env steps and wall time, and the last period's
IQM with a 95% bootstrap CI over seeds.

    python experiments/teacher_recipe/ablation.py NAME=RUN_DIR [NAME=RUN_DIR ...] --out results/ablation

Reads each run's ``metrics.csv``; writes ``ablation.json`` and ``ablation.png`` into ``--out``.
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from harv_jax.evaluation.seed_stats import iqm, iqm_ci

METRICS = {"eval/recovered": "recovered (eval batch)", "eval/t_recover_mean_s": "mean recovery time, s"}


def read_curves(run: Path) -> dict[str, np.ndarray]:
    """env_steps [P], wall_s [P] and, per metric, [P, S] per-seed values from ``metrics.csv``."""
    rows = list(csv.DictReader(open(run / "metrics.csv")))
    out = {"env_steps": np.array([float(r["env_steps"]) for r in rows]),
           "wall_s": np.array([float(r["wall_s"]) for r in rows])}  # fmt: skip
    for key in METRICS:
        cols = sorted(
            (c for c in rows[0] if c.startswith(f"{key}/seed")), key=lambda c: int(c.rsplit("seed", 1)[1])
        )
        out[key] = np.array([[float(r[c]) for c in cols] for r in rows])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="NAME=RUN_DIR")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = {}
    for spec in a.runs:
        name, _, path = spec.partition("=")
        curves[name] = read_curves(Path(path))
    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharey="row")
    result = {}
    for name, c in curves.items():
        result[name] = {
            "env_steps": c["env_steps"][-1],
            "wall_s": c["wall_s"][-1],
            "seeds": c["eval/recovered"].shape[1],
        }
        for row, key in enumerate(METRICS):
            per_seed = c[key][-1]
            result[name][key] = {"per_seed": per_seed.tolist(), **iqm_ci(per_seed)}
            curve = np.array([iqm(v) for v in c[key]])
            for col, x in enumerate(("env_steps", "wall_s")):
                axes[row, col].plot(c[x], curve, marker="o", label=name)
    for row, label in enumerate(METRICS.values()):
        axes[row, 0].set_ylabel(f"IQM over seeds: {label}")
    axes[1, 0].set_xlabel("env steps per seed")
    axes[1, 1].set_xlabel("wall time, s (compile included)")
    axes[0, 0].legend()
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    fig.suptitle("Training evaluation (64 upsets + 8 spins, RL-only) at equal budget")
    fig.tight_layout()
    a.out.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.out / "ablation.png", dpi=110)
    (a.out / "ablation.json").write_text(json.dumps(result, indent=2) + "\n")
    for name, r in result.items():
        rec, t = r["eval/recovered"], r["eval/t_recover_mean_s"]
        line = f"{name:16s} recovered IQM {rec['iqm']:.3f} [{rec['ci_low']:.3f}, {rec['ci_high']:.3f}]  "
        line += f"mean time IQM {t['iqm']:.1f} s [{t['ci_low']:.1f}, {t['ci_high']:.1f}]"
        print(line + f"  wall {r['wall_s']:.0f} s")


if __name__ == "__main__":
    main()
