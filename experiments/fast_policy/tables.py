"""Markdown tables of evaluate.py results (experiments/recovery_policy/evaluate.py JSONs).

python experiments/fast_policy/tables.py results/eval_fast_seed30.json [results/eval_recovery_seed30.json]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def _f(x: float | None, fmt: str = "{:.1f}") -> str:
    return "–" if x is None else fmt.format(x)


def rows(path: Path) -> list[str]:
    """One table row per controller: nominal and randomized Monte Carlo, spin."""
    r = json.loads(path.read_text())
    out = []
    ctrls = [("SMC (default gains)", r["smc"])] + [(Path(k).name, v) for k, v in r["policies"].items()]
    for name, c in ctrls:
        n, z, s = c["nominal"], c["randomized"], c["spin"]
        ratio = n.get("t_recover_p50_ratio_to_smc", 1.0)
        paired = n.get("paired_vs_smc", {}).get("ratio_p50", 1.0)
        spin = f"{_f(s['t_recover_s'])}, {s['control_tv_rad']:.1f}" if s["recovered"] else "no"
        out.append(
            f"| {name} | {n['recovery_rate']:.1%} | "
            f"{_f(n['t_recover_p50_s'])} / {_f(n['t_recover_p95_s'])} | "
            f"{_f(ratio, '{:.2f}')} ({_f(paired, '{:.2f}')}) | {n['control_tv_mean_rad']:.2f} | "
            f"{z['recovery_rate']:.1%} | {_f(z['t_recover_p50_s'])} | {spin} |"
        )
    return out


def mean_std(path: Path) -> str:
    """Mean +- std over the policies of one file (nominal median, p95, TV, randomized median)."""
    r = json.loads(path.read_text())["policies"].values()

    def ms(xs: list[float]) -> str:
        return f"{np.mean(xs):.1f} ± {np.std(xs):.1f}"

    return (
        f"| {path.name} | {ms([p['nominal']['recovery_rate'] * 100 for p in r])}% | "
        f"{ms([p['nominal']['t_recover_p50_s'] for p in r])} | "
        f"{ms([p['nominal']['t_recover_p95_s'] for p in r])} | "
        f"{ms([p['nominal']['control_tv_mean_rad'] for p in r])} | "
        f"{ms([p['randomized']['recovery_rate'] * 100 for p in r])}% | "
        f"{ms([p['randomized']['t_recover_p50_s'] for p in r])} | "
        f"{sum(p['spin']['recovered'] for p in r)}/{len(r)} |"
    )


if __name__ == "__main__":
    head = (
        "| controller | nominal recovered | median / p95 (s) | median ratio to SMC (paired) | TV (rad) | "
        "randomized recovered | randomized median (s) | 30 s spin: recovery (s), TV (rad) |"
    )
    print(head + "\n|---|---:|---:|---:|---:|---:|---:|---:|")
    for p in sys.argv[1:]:
        print("\n".join(rows(Path(p))))
    print()
    for p in sys.argv[1:]:
        print(mean_std(Path(p)))
