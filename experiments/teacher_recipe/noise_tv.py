"""Control TV under noise, delay, model error and lag against the clean TV, for policies behind the observer.

    python experiments/teacher_recipe/noise_tv.py POLICY [POLICY ...] --runs 256 --mc-seed 11 --out FILE.json

Each policy flies RL-only unfiltered (``rl``), behind the 0.3 Hz observer (``rl+obs0.3``) and in the default
hybrid behind it (``hybrid+obs0.3``), on the same Monte Carlo runs (nominal start states, 60 s), clean and
under ``--disturbances noise,delay,model,lag`` at their default levels (noise 1x, 20 ms, 1x the randomization
ranges with the model-based parts on the nominal aircraft, 0.03 s lag). Writes recovered share, mean recovery
time (not recovered at 60 s), mean control TV and chatter index per condition, and the TV and chatter ratios.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec, parse_disturbances
from harv_jax.evaluation.montecarlo.paired import mean_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.optimal.outputs import cpu_model
from harv_jax.task.spec import ALPHA_TARGET_RAD

DURATION_S = 60.0
N_STEPS = 6000
REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
CONTROLLERS = ("rl", "rl+obs0.3", "hybrid+obs0.3")
CONDITIONS = {
    "clean": DisturbanceSpec(),
    "noise,delay,model,lag": parse_disturbances("noise,delay,model,lag"),
}


def one(name: str, policy: str, spec: DisturbanceSpec, runs: int, seed: int) -> dict[str, float]:
    inputs = sample_mc_inputs(jax.random.key(seed), runs, harv(), disturbances=spec)
    out, _ = run_mc(build_controller(name, ControllerOptions(policy=policy)), inputs, REF, N_STEPS)
    m = out.metrics
    rec = np.asarray(m.recovered, bool)
    t = np.where(rec, np.asarray(m.t_recover_s, np.float64), np.nan)
    return {
        "recovered": float(rec.mean()),
        "t_mean_nr_s": mean_nr_at_run_s(t, rec, DURATION_S),
        "tv_mean_rad": float(np.asarray(m.control_tv_rad, np.float64).sum(-1).mean()),
        "chatter_mean_rad2": float(np.asarray(m.chatter_index_rad2, np.float64).mean()),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("policies", nargs="+")
    ap.add_argument("--runs", type=int, default=256)
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    rows = []
    for policy in args.policies:
        for name in CONTROLLERS:
            res = {c: one(name, policy, spec, args.runs, args.mc_seed) for c, spec in CONDITIONS.items()}
            clean, dist = res["clean"], res["noise,delay,model,lag"]
            row = {
                "policy": policy,
                "controller": name,
                **res,
                "tv_ratio": dist["tv_mean_rad"] / clean["tv_mean_rad"],
                "chatter_ratio": dist["chatter_mean_rad2"] / clean["chatter_mean_rad2"],
            }
            rows.append(row)
            print(
                f"| {policy} | {name} | {100 * clean['recovered']:.1f}%, {clean['t_mean_nr_s']:.2f} s, "
                f"{clean['tv_mean_rad']:.2f} | {100 * dist['recovered']:.1f}%, {dist['t_mean_nr_s']:.2f} s, "
                f"{dist['tv_mean_rad']:.2f} | {row['tv_ratio']:.2f} | {row['chatter_ratio']:.2f} |",
                flush=True,
            )
    meta = {"runs": args.runs, "mc_seed": args.mc_seed, "cpu": cpu_model(), "jax": jax.__version__}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"meta": meta, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
