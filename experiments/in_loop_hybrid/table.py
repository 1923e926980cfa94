"""Markdown table of the in-loop study's Monte Carlo folders (``results/mc_*/summary.json``)."""

from __future__ import annotations

import json
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
ROWS = (
    ("mc_seed5_in_loop", "smc", "SMC (default gains)"),
    ("mc_seed5_shipped", "rl", "RL-only, shipped:recovery"),
    ("mc_seed5_shipped", "hybrid", "gated hybrid, shipped:recovery (trained alone)"),
    ("mc_seed5_in_loop", "hybrid", "gated hybrid, in-loop-trained policy"),
    ("mc_seed5_in_loop_rl_alone", "rl", "in-loop-trained policy flown alone (RL-only)"),
    ("mc_seed5_in_loop_randomized", "smc", "SMC, randomized aircraft"),
    ("mc_seed5_in_loop_randomized", "hybrid", "gated hybrid, in-loop-trained, randomized aircraft"),
)


def main() -> None:
    print(
        "| controller | recovered | t_rec p50 / p95 s | TV mean rad | alt. loss mean ft "
        "| policy unmodified | ζ mean α/β/μ |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for folder, name, label in ROWS:
        path = RESULTS / folder / "summary.json"
        if not path.is_file():
            continue
        c = json.loads(path.read_text())["controllers"][name]
        t = c["recovery_time_s"]
        ts = "–" if t["p50"] is None else f"{t['p50']:.1f} / {t['p95']:.1f}"
        h = c.get("hybrid") or {}
        z = h.get("zeta_mean_by_channel")
        zs = "/".join(f"{z[k]:.2f}" for k in ("alpha", "beta", "mu")) if z else "–"
        pu = (
            f"{100 * h['policy_unmodified_fraction']:.3f}%"
            if h.get("policy_unmodified_fraction") is not None
            else "–"
        )
        print(
            f"| {label} | {100 * c['recovery_rate']:.1f}% | {ts} | "
            f"{c['control_tv']['mean']:.2f} | {c['altitude_loss_ft']['mean']:.0f} | {pu} | {zs} |"
        )


if __name__ == "__main__":
    main()
