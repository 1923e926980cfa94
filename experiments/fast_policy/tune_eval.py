"""Tuning evaluation: RL-only vs the SMC on the Monte Carlo seed 123, 256 runs, nominal (the tuning set).

    python experiments/fast_policy/tune_eval.py RUN/policy/policy_seed0.npz [...] --out eval.json

Per policy: recovery rate, median / p95 recovery, control TV, the paired per-run ratio to the SMC, and the
medians of the runs that start above / below 900 ft/s (where the zoom climb costs time).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "recovery_policy"))
from evaluate import mc, paired  # noqa: E402

from harv_jax.aircraft import harv  # noqa: E402
from harv_jax.control.rl import make_rl_controller  # noqa: E402
from harv_jax.control.smc import make_smc  # noqa: E402
from harv_jax.evaluation.montecarlo.rollout import sample_mc_inputs  # noqa: E402
from harv_jax.policy import resolve_policy  # noqa: E402


def _split(t: np.ndarray, fast: np.ndarray) -> dict:
    def med(m):
        x = t[m & np.isfinite(t)]
        return float(np.median(x)) if x.size else None

    return {"t_p50_fast_s": med(fast), "t_p50_slow_s": med(~fast)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("policies", nargs="+")
    ap.add_argument("--runs", type=int, default=256)
    ap.add_argument("--mc-seed", type=int, default=123)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    inputs = sample_mc_inputs(jax.random.key(args.mc_seed), args.runs, harv())
    fast = np.asarray(inputs.x0_wind[:, 0]) > 900.0
    row, t_smc, _ = mc(make_smc(), inputs)
    result = {"runs": args.runs, "mc_seed": args.mc_seed, "smc": row | _split(t_smc, fast), "policies": {}}
    for spec in args.policies:
        row, t, _ = mc(make_rl_controller(resolve_policy(spec).deterministic), inputs)
        row |= _split(t, fast) | {"paired_vs_smc": paired(t, t_smc)}
        result["policies"][spec] = row
        keys = ("recovery_rate", "t_recover_p50_s", "t_recover_p95_s", "control_tv_mean_rad")
        print(spec, {k: row[k] for k in keys}, _split(t, fast), row["paired_vs_smc"], flush=True)
    print("smc", {k: result["smc"][k] for k in keys + ("t_p50_fast_s", "t_p50_slow_s")})
    args.out.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
