"""Would picking each seed's best period help? Every period policy of each seed flies RL-only on a
validation Monte Carlo seed; the period with the lowest share of runs slower than the SMC by > 1 s (then the
lowest mean / SMC) is picked, and the pick and the last period fly the test Monte Carlo seed.

    python experiments/teacher_recipe/period_select.py RUN VAL_SEED N_VAL TEST_SEED N_TEST PERIODS OUT
    python experiments/teacher_recipe/period_select.py runs/tuning_v23_teacher_zoom_wide_seed7 \\
        1234 500 11 1000 5,6,7,8 \\
        experiments/teacher_recipe/results/tuning_v23_teacher_zoom_wide_seed7/period_select.json

RUN is a training run folder with ``policy/period_<p>/policy_seed<i>.npz`` (5 seeds). "Mean" counts a run
not recovered at 60 s. Writes JSON: ``val`` per seed and period, ``test`` for the pick and the last period.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.evaluation.montecarlo.paired import paired_vs_reference
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
RUN_LENGTH_S = 60.0


def times(ctrl, inp) -> tuple[tuple[np.ndarray, np.ndarray], float]:
    """(per-run recovery times, recovered flags) and the mean control TV, rad."""
    m = run_mc(ctrl, inp, REF, 6000)[0].metrics
    tv_rad = float(np.asarray(m.control_tv_rad, np.float64).sum(-1).mean())
    return (np.asarray(m.t_recover_s), np.asarray(m.recovered)), tv_rad


def rl(path: Path):
    return build_controller("rl", ControllerOptions(policy=str(path)))


def main() -> None:
    run = Path(sys.argv[1])
    val_seed, n_val, test_seed, n_test = map(int, sys.argv[2:6])
    periods = [int(p) for p in sys.argv[6].split(",")]
    val = sample_mc_inputs(jax.random.key(val_seed), n_val, harv())
    test = sample_mc_inputs(jax.random.key(test_seed), n_test, harv())
    smc_val, _ = times(build_controller("smc"), val)
    smc_test, _ = times(build_controller("smc"), test)
    out = {"val": {}, "test": {}}
    for s in range(5):
        best = None
        for p in periods:
            t, tv = times(rl(run / "policy" / f"period_{p:04d}" / f"policy_seed{s}.npz"), val)
            vs = paired_vs_reference(*t, *smc_val, RUN_LENGTH_S)
            slower, ratio = vs["slower_fraction"], vs["mean_ratio"]
            out["val"][f"s{s}p{p}"] = {"slower": slower, "ratio": ratio, "tv": tv}
            print(s, p, "val", round(slower, 3), round(ratio, 3), round(tv, 2), flush=True)
            if best is None or (slower, ratio) < best[0]:
                best = ((slower, ratio), p)
        for p in sorted({best[1], periods[-1]}):
            t, tv = times(rl(run / "policy" / f"period_{p:04d}" / f"policy_seed{s}.npz"), test)
            vs = paired_vs_reference(*t, *smc_test, RUN_LENGTH_S)
            r = {"slower": vs["slower_fraction"], "ratio": vs["mean_ratio"], "tv": tv, "picked": p == best[1]}
            out["test"][f"s{s}p{p}"] = r
            print(s, p, "test", r, flush=True)
    Path(sys.argv[7]).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
