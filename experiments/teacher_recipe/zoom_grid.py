"""The zoom-aware braking schedule against the SMC on the same Monte Carlo runs: which bound
(V_switch, V_zoom, k_zoom) of ``smc-brake-zoom`` makes the best teacher by the mean recovery time, the share
of runs slower than the SMC by > 1 s and the control TV.

    python experiments/teacher_recipe/zoom_grid.py --mc-seed 11 --out results/zoom_grid_mc11.json

The braking SMC brakes (alpha_d -> 1.0 rad) while V_switch < V < V_zoom - k_zoom max(gamma, 0). Monte Carlo
seed 11 is the tuning seed of this study (the final evaluation uses others).
"""

from __future__ import annotations

import argparse
import itertools
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.smc import make_smc
from harv_jax.control.smc_brake import brake_schedule, make_smc_brake
from harv_jax.evaluation.monte_carlo import run_mc, sample_mc_inputs
from harv_jax.evaluation.paired import mean_nr_at_run_s, paired_vs_reference
from harv_jax.task.spec import ALPHA_TARGET_RAD

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, DURATION_S = 6000, 60.0
GRID = {
    "v_switch_fps": (500.0, 600.0, 700.0),
    "v_zoom_fps": (1200.0, 1300.0),
    "zoom_slope_fps_per_rad": (300.0, 600.0, 900.0, 1200.0),
}


def times(ctrl, inputs):
    m = run_mc(ctrl, inputs, REF, N_STEPS)[0].metrics
    rec = np.asarray(m.recovered, bool)
    tv = float(np.asarray(m.control_tv_rad, np.float64).sum(-1).mean())
    return np.where(rec, np.asarray(m.t_recover_s, np.float64), np.nan), rec, tv


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    inputs = sample_mc_inputs(jax.random.key(a.mc_seed), a.n, harv())
    t_smc, r_smc, tv_smc = times(make_smc(), inputs)
    rows = [{"controller": "smc", "mean_s": mean_nr_at_run_s(t_smc, r_smc, DURATION_S), "tv_rad": tv_smc}]
    for vs, vz, k in itertools.product(*GRID.values()):
        sched = brake_schedule(v_switch_fps=vs, v_zoom_fps=vz, zoom_slope_fps_per_rad=k)
        t, r, tv = times(make_smc_brake(schedule=sched), inputs)
        vs_smc = paired_vs_reference(t, r, t_smc, r_smc, DURATION_S)
        row = {"v_switch_fps": vs, "v_zoom_fps": vz, "zoom_slope_fps_per_rad": k,
               "recovered": float(r.mean()), "mean_s": mean_nr_at_run_s(t, r, DURATION_S), "tv_rad": tv,
               **vs_smc}  # fmt: skip
        rows.append(row)
        print(json.dumps(row), flush=True)
    cmd = f"python experiments/teacher_recipe/zoom_grid.py --mc-seed {a.mc_seed} --n {a.n}"
    a.out.write_text(json.dumps({"command": cmd, "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
