"""Fit the teacher's time to recover, the potential of the progress reward (``harv_jax.training.time_to_go``).

The teacher (``smc-brake-zoom``) flies the Monte Carlo's runs of a fitting seed for 60 s; every 0.1 s
sample before the run's recovery time (and 5 s past it) is labelled with the time the teacher still needed
(its recovery time less the sample's time; runs it did not recover are left out). A 10-32-32-1 network is
fitted on the first 80% of the runs and scored (R^2, RMSE) on the other 20%.

    python experiments/teacher_recipe/time_to_go_fit.py --mc-seed 5 \\
        --out experiments/teacher_recipe/time_to_go_smc_brake_zoom.npz

Monte Carlo seed 5 is used for this fit only (the study tunes on seed 11 and reports on 2027).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.metrics import settle_time_s
from harv_jax.evaluation.monte_carlo import sample_mc_inputs
from harv_jax.task.criteria import default_criterion, recovered_mask
from harv_jax.task.spec import ALPHA_TARGET_RAD
from harv_jax.training import time_to_go

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, RECORD_EVERY, SAMPLE_S = 6000, 10, 0.1  # 60 s, a sample every 0.1 s
PAST_RECOVERY_S, HOLD_SAMPLES, TRAIN_SHARE = 5.0, 100, 0.8


def teacher_flights(name: str, mc_seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(states [n, T, 10], recovered mask [n, T]) of ``name`` on the Monte Carlo's runs of ``mc_seed``."""
    inputs = sample_mc_inputs(jax.random.key(mc_seed), n, harv())
    ctrl = build_controller(name, ControllerOptions())

    def fly(p, x0, key):
        x = closed_loop(ctrl, p, x0, REF, key, N_STEPS, record_every=RECORD_EVERY).traj.x_wind
        return x, recovered_mask(x, REF, default_criterion())

    x, ok = jax.jit(jax.vmap(fly))(inputs.params, inputs.x0_wind, inputs.keys)
    return np.asarray(x), np.asarray(ok)


def labels(ok: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time to go [n, T] s, sample used [n, T], run recovered [n]) from the per-sample criterion."""
    recovered = ok[:, -HOLD_SAMPLES:].all(axis=1)
    # samples from which the criterion holds to the end (NaN: not at the end), in seconds
    t_rec = np.asarray(jax.vmap(settle_time_s, in_axes=(0, None))(jnp.asarray(ok), 1.0), float) * SAMPLE_S
    t = np.arange(ok.shape[1]) * SAMPLE_S
    used = recovered[:, None] & (t[None] <= t_rec[:, None] + PAST_RECOVERY_S)
    return np.maximum(t_rec[:, None] - t[None], 0.0), used, recovered


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mc-seed", type=int, default=5)
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--teacher", default="smc-brake-zoom")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    x, ok = teacher_flights(a.teacher, a.mc_seed, a.runs)
    y, used, recovered = labels(ok)
    train = (np.arange(a.runs) < TRAIN_SHARE * a.runs)[:, None]
    net = time_to_go.fit(x[used & train], y[used & train])
    held = used & ~train
    pred = np.asarray(time_to_go.predict_s(net, jnp.asarray(x[held])))
    rmse = float(np.sqrt(np.mean((pred - y[held]) ** 2)))
    r2 = 1.0 - float(np.mean((pred - y[held]) ** 2) / np.var(y[held]))
    about = {
        "command": " ".join(["python", *sys.argv]),
        "teacher": a.teacher,
        "mc_seed": a.mc_seed,
        "runs": a.runs,
        "runs_recovered": int(recovered.sum()),
        "samples_fitted": int((used & train).sum()),
        "held_out_runs": int((~train[:, 0] & recovered).sum()),
        "held_out_r2": round(r2, 4),
        "held_out_rmse_s": round(rmse, 3),
    }
    print(json.dumps(about, indent=2))
    a.out.parent.mkdir(parents=True, exist_ok=True)
    time_to_go.save(a.out, net, about)
    a.out.with_suffix(".json").write_text(json.dumps(about, indent=2) + "\n")


if __name__ == "__main__":
    main()
