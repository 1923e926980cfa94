"""Per-run recovery times of policies against the SMC, binned by initial speed (where the time goes).

python experiments/fast_policy/per_run.py POLICY.npz [...] --mc-seed 0 --runs 1000 --out per_run.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "recovery_policy"))
from evaluate import mc  # noqa: E402

from harv_jax.aircraft import harv  # noqa: E402
from harv_jax.control.rl import make_rl_controller  # noqa: E402
from harv_jax.control.smc import make_smc  # noqa: E402
from harv_jax.evaluation.montecarlo.rollout import sample_mc_inputs  # noqa: E402
from harv_jax.policy import resolve_policy  # noqa: E402

BINS_FPS = (100.0, 500.0, 900.0, 1200.0, 1500.0)


def binned(t: np.ndarray, t_smc: np.ndarray, v0: np.ndarray) -> list[dict]:
    """Median recovery time of the policy and the SMC and the fraction of runs the policy wins, per V0 bin."""
    out = []
    for lo, hi in zip(BINS_FPS[:-1], BINS_FPS[1:], strict=True):
        m = (v0 >= lo) & (v0 < hi)
        both = m & np.isfinite(t) & np.isfinite(t_smc)
        out.append({"v0_fps": [lo, hi], "runs": int(m.sum()), "t_p50_s": float(np.nanmedian(t[m])),
                    "smc_t_p50_s": float(np.nanmedian(t_smc[m])),
                    "fraction_faster": float(np.mean(t[both] < t_smc[both]))})  # fmt: skip
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("policies", nargs="+")
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--mc-seed", type=int, default=0)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    inputs = sample_mc_inputs(jax.random.key(args.mc_seed), args.runs, harv())
    v0 = np.asarray(inputs.x0_wind[:, 0])
    _, t_smc, _ = mc(make_smc(), inputs)
    result = {"runs": args.runs, "mc_seed": args.mc_seed, "policies": {}}
    for spec in args.policies:
        _, t, _ = mc(make_rl_controller(resolve_policy(spec).deterministic), inputs)
        result["policies"][spec] = binned(t, t_smc, v0)
        for row in result["policies"][spec]:
            print(Path(spec).name, row, flush=True)
    args.out.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
