"""The SMC's boundary layer against sensor noise: the SMC with phi (the half-width of sat(s / phi), rad/s, the
same on the three channels) behind the 0.1 Hz extended-state observer, on the same Monte Carlo runs clean,
under the training env's noise, delay, model error and lag, and with the model error at 2x its ranges.

    python experiments/robustness/smc_boundary_layer.py --seed 11 --runs 256 --phi 0.2,0.4,0.8 \\
        --out experiments/robustness/results/smc_boundary_layer_mc11.json

Prints and writes one row per phi: recovered share, mean recovery time (a run not recovered at 60 s),
control TV and chatter index per condition, and TV and chatter under the disturbances against clean.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.observer import with_state_observer
from harv_jax.control.smc import default_gains, make_smc
from harv_jax.evaluation.montecarlo.disturbances import parse_disturbances
from harv_jax.evaluation.montecarlo.paired import mean_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, DURATION_S = 6000, 60.0
#: The conditions, each a ``--disturbances`` list with its levels.
CONDITIONS = {
    "clean": ("none", None),
    "nogust": ("noise,delay,model,lag", None),
    "model2": ("noise,delay,model,lag", {"model": 2.0}),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--runs", type=int, default=256)
    ap.add_argument("--phi", default="0.2,0.4,0.8", help="comma list of boundary-layer half-widths, rad/s")
    ap.add_argument("--eso-hz", type=float, default=0.1, help="the extended-state observer's bandwidth, Hz")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    inputs = {
        name: sample_mc_inputs(jax.random.key(a.seed), a.runs, harv(), disturbances=parse_disturbances(d, lv))
        for name, (d, lv) in CONDITIONS.items()
    }
    rows = []
    for phi in (float(x) for x in a.phi.split(",")):
        gains = default_gains().replace(phi_radps=jnp.full((3,), phi, jnp.float32))
        ctrl = with_state_observer(make_smc(gains=gains), a.eso_hz, estimate_bias=True)
        row = {"phi": phi, "eso_hz": a.eso_hz}
        for name, inp in inputs.items():
            m = run_mc(ctrl, inp, REF, N_STEPS)[0].metrics
            row[name] = {
                "rec": float(np.asarray(m.recovered, bool).mean()),
                "mean_s": mean_nr_at_run_s(m.t_recover_s, m.recovered, DURATION_S),
                "tv": float(np.asarray(m.control_tv_rad, np.float64).sum(-1).mean()),
                "chatter": float(np.asarray(m.chatter_index_rad2, np.float64).sum(-1).mean()),
            }
        row["tv_ratio"] = row["nogust"]["tv"] / row["clean"]["tv"]
        row["chatter_ratio"] = row["nogust"]["chatter"] / row["clean"]["chatter"]
        rows.append(row)
        print(json.dumps(row), flush=True)
    cmd = (
        f"python experiments/robustness/smc_boundary_layer.py --seed {a.seed} --runs {a.runs} "
        f"--phi {a.phi} --eso-hz {a.eso_hz:g}"
    )
    a.out.write_text(json.dumps({"command": cmd, "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
