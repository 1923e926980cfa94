"""The criterion in turbulence on paired runs: every controller flies the same Monte Carlo runs in still
air and in light, moderate and severe Dryden turbulence, each condition scored by its own criterion.

    python experiments/turbulence/paired.py --runs 1000 --mc-seed 8191 --out results/paired_mc8191.json

Per controller and level: the recovered share, the mean recovery time (not recovered at the run length)
and its ratio to the same controller's still-air mean, and the share of runs recovered in turbulence whose
still-air twin is not recovered (the criterion must not let turbulence excuse a run that fails in still
air). Monte Carlo seed 8191 was used nowhere before this study (the probe, ``probe_hold.py``, used 101).
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
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.evaluation.montecarlo.inputs import sample_mc_inputs
from harv_jax.evaluation.montecarlo.paired import mean_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import run_mc
from harv_jax.optimal.outputs import cpu_model
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS = 6000
LEVELS = ("none", "light", "moderate", "severe")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--mc-seed", type=int, default=8191)
    ap.add_argument("--controllers", default="smc,smc-brake-zoom,rl,hybrid")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    run_s = N_STEPS * DT_S
    rows = []
    for name in a.controllers.split(","):
        ctrl = build_controller(name, ControllerOptions())
        base = None
        for level in LEVELS:
            inputs = sample_mc_inputs(
                jax.random.key(a.mc_seed), a.runs, harv(), disturbances=DisturbanceSpec(turbulence=level)
            )
            out, _ = run_mc(ctrl, inputs, REF, N_STEPS, DT_S)
            rec = np.asarray(out.metrics.recovered, bool)
            t = np.asarray(out.metrics.t_recover_s, np.float64)
            mean = mean_nr_at_run_s(t, rec, run_s)
            row = {"controller": name, "turbulence": level, "recovered": float(rec.mean()), "mean_s": mean}
            if base is None:
                base = (rec, mean)
            else:
                row["mean_vs_still_air"] = mean / base[1]
                row["recovered_here_not_in_still_air"] = float(np.mean(rec & ~base[0]))
                row["recovered_in_still_air_not_here"] = float(np.mean(base[0] & ~rec))
            rows.append(row)
            print(json.dumps(row), flush=True)
    cmd = (
        f"python experiments/turbulence/paired.py --runs {a.runs} --mc-seed {a.mc_seed} "
        f"--controllers {a.controllers}"
    )
    a.out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"command": cmd, "cpu": cpu_model(), "policy": "shipped:teacher", "rows": rows}
    a.out.write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
