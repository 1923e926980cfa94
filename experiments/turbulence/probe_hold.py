"""What turbulence does to the recovery criterion's channels over the hold window: per-run statistics of
the air-relative tracking errors and body rates over the last 10 s, raw and first-order low-passed.

    python experiments/turbulence/probe_hold.py --runs 64 --mc-seed 101 --out results/probe_hold_mc101.json

For each controller and turbulence level (none, light, moderate, severe) every run flies 60 s of the
Monte Carlo; over its last 10 s the script records the mean of each error, the largest deviation from that
mean (raw and filtered with time constants 1, 2, 4 and 8 s, the filter started at the first sample), the
largest body-rate norm (raw and filtered), and the hold's mean airspeed and altitude. Monte Carlo seed 101
is this probe's (the criterion's measurements use others).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.registry import build_controller
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.evaluation.montecarlo.inputs import sample_mc_inputs
from harv_jax.task.criteria import tracking_errors
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S
from harv_jax.task.turbulent_criterion import lowpass

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, HOLD = 6000, 1000
TAUS_S = (1.0, 2.0, 4.0, 8.0)
LEVELS = ("none", "light", "moderate", "severe")


def stats(x_all: jnp.ndarray) -> dict[str, jnp.ndarray]:
    e = tracking_errors(x_all, REF)
    pqr = x_all[:, 3:6]
    sig = jnp.concatenate([e, pqr], axis=-1)  # [T, 6]
    out = {
        "mean_e": jnp.mean(e[-HOLD:], axis=0),
        "max_dev_raw": jnp.max(jnp.abs(e[-HOLD:] - jnp.mean(e[-HOLD:], axis=0)), axis=0),
        "max_abs_raw": jnp.max(jnp.abs(e[-HOLD:]), axis=0),
        "omega_max_raw": jnp.max(jnp.linalg.norm(pqr[-HOLD:], axis=-1)),
        "v_mean": jnp.mean(x_all[-HOLD:, 0]),
        "h_mean": jnp.mean(x_all[-HOLD:, 9]),
    }
    for tau in TAUS_S:
        f = lowpass(sig, tau, DT_S)[-HOLD:]
        out[f"max_abs_f{tau:g}"] = jnp.max(jnp.abs(f[:, :3]), axis=0)
        out[f"omega_max_f{tau:g}"] = jnp.max(jnp.linalg.norm(f[:, 3:], axis=-1))
    return out


def run(name: str, level: str, n: int, seed: int) -> dict[str, np.ndarray]:
    spec = DisturbanceSpec(turbulence=level)
    inputs = sample_mc_inputs(jax.random.key(seed), n, harv(), disturbances=spec)
    ctrl = build_controller(name)

    def one(i):
        r = jax.tree.map(lambda a: a[i], inputs)
        res = closed_loop(ctrl, r.params, r.x0_wind, REF, r.keys, N_STEPS, disturbance=r.disturbance,
                          disturbance_key=r.disturbance_keys, max_delay_steps=r.max_delay_steps)  # fmt: skip
        m, x_all = score(res, REF, r.params)
        return {"recovered": m.recovered, **stats(x_all)}

    out = jax.jit(jax.vmap(one))(jnp.arange(n))
    return {k: np.asarray(v, np.float64) for k, v in out.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=64)
    ap.add_argument("--mc-seed", type=int, default=101)
    ap.add_argument("--controllers", default="smc,smc-brake-zoom")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    rows = []
    for name in a.controllers.split(","):
        for level in LEVELS:
            r = run(name, level, a.runs, a.mc_seed)
            row = {"controller": name, "turbulence": level, "recovered_raw": float(r["recovered"].mean())}
            for k, v in r.items():
                if k == "recovered":
                    continue
                row[k] = {
                    "p50": np.percentile(v, 50, axis=0).tolist(),
                    "p95": np.percentile(v, 95, axis=0).tolist(),
                }
            rows.append(row)
            print(json.dumps({k: row[k] for k in ("controller", "turbulence", "recovered_raw")}), flush=True)
    cmd = (
        f"python experiments/turbulence/probe_hold.py --runs {a.runs} --mc-seed {a.mc_seed} "
        f"--controllers {a.controllers}"
    )
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps({"command": cmd, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
