"""Where a controller's control TV comes from: per surface, before and after the run's recovery time.

    python experiments/teacher_recipe/tv_split.py --controller smc,smc-brake-zoom \\
        --policy runs/daggerw4_v23_seed7/policy/policy_seed0.npz --runs 300 --mc-seed 11 \\
        --out experiments/teacher_recipe/results/tv_split_mc11.json

Every controller flies the runs of ``harv-jax mc --runs N --seed S`` (``--runs``, ``--mc-seed``; nominal
aircraft, 60 s, common random numbers). The total variation sum_k |delta_{k+1} - delta_k| of each
surface's deflection (the TV of ``harv-jax mc``) is split at the run's recovery time (a run not recovered
counts whole as before), and averaged over the runs; also the mean recovery time (not recovered: 60 s) and,
as a check of the split, the Monte Carlo's own mean TV of the same runs.
Monte Carlo seed 11 is the tuning seed of this study.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.base import Controller
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.montecarlo.paired import times_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, DURATION_S = 6000, 60.0
CHUNK_RUNS = 100


def deflections_rad(ctrl: Controller, inputs, n: int) -> np.ndarray:
    """[n, N_STEPS, 3] surface deflections of ``ctrl`` on the first ``n`` runs, in chunks of CHUNK_RUNS."""
    fly = jax.jit(jax.vmap(lambda p, x0, k: closed_loop(ctrl, p, x0, REF, k, N_STEPS).traj.delta_rad))
    out = []
    for s in range(0, n, CHUNK_RUNS):
        sl = slice(s, min(s + CHUNK_RUNS, n))
        params = jax.tree.map(lambda a, sl=sl: a[sl], inputs.params)
        out.append(np.asarray(fly(params, inputs.x0_wind[sl], inputs.keys[sl]), np.float64))
    return np.concatenate(out)


def split(ctrl: Controller, inputs, n: int) -> dict:
    """Mean recovery time, the Monte Carlo's mean TV, and the mean TV per surface before and after the
    recovery time."""
    m = run_mc(ctrl, inputs, REF, N_STEPS)[0].metrics
    t_rec = times_nr_at_run_s(m.t_recover_s, m.recovered, DURATION_S)
    step_tv = np.abs(np.diff(deflections_rad(ctrl, inputs, n), axis=1))  # [n, T-1, 3]
    t_end = np.arange(1, N_STEPS) * DT_S  # end time of each step's change
    before = (t_end[None, :] <= t_rec[:, None])[..., None]
    return {
        "t_mean_s": float(t_rec.mean()),
        "tv_rad": float(step_tv.sum((1, 2)).mean()),
        "tv_rad_monte_carlo": float(np.asarray(m.control_tv_rad, np.float64).sum(-1).mean()),
        "tv_before_rad": (step_tv * before).sum(1).mean(0).tolist(),
        "tv_after_rad": (step_tv * ~before).sum(1).mean(0).tolist(),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--controller", default="smc,smc-brake-zoom", help="registry names, comma-separated")
    ap.add_argument("--policy", action="append", default=[], help="policy file (.npz), flown RL-only")
    ap.add_argument("--runs", type=int, default=300)
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    if a.runs < 1:
        ap.error(f"--runs {a.runs}: allowed: >= 1")
    inputs = sample_mc_inputs(jax.random.key(a.mc_seed), a.runs, harv())
    flown = [(name, build_controller(name, ControllerOptions())) for name in a.controller.split(",") if name]
    flown += [(p, build_controller("rl", ControllerOptions(policy=p))) for p in a.policy]
    rows = {}
    for name, ctrl in flown:
        rows[name] = split(ctrl, inputs, a.runs)
        print(json.dumps({name: rows[name]}), flush=True)
    doc = {
        "mc_seed": a.mc_seed,
        "runs": a.runs,
        "duration_s": DURATION_S,
        "channels": ["elevator", "aileron", "rudder"],
        "controllers": rows,
    }
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
