"""The braking SMC's schedule against the SMC on the same Monte Carlo runs: which (alpha_brake, V_switch)
makes the best teacher by the mean recovery time and the share of runs slower than the SMC by > 1 s.

    python experiments/teacher_recipe/brake_grid.py --mc-seed 11 --out results/brake_grid_mc11.json
    python experiments/teacher_recipe/brake_grid.py --zoom --mc-seed 11 --out results/zoom_grid_mc11.json

``--zoom`` sweeps the bound of ``smc-brake-zoom`` instead (alpha_brake 1.0 rad while
V_switch < V < V_zoom - k_zoom max(gamma, 0)): V_switch x V_zoom x k_zoom, also by the control TV.
(The ``--blend`` sweep of ``results/blend_grid_mc11.json`` ran at commit d2131df, with the blended
schedule that has since left the package.)
Monte Carlo seed 11 is the tuning seed of this study (the final evaluation uses others).
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
from harv_jax.evaluation.montecarlo.paired import mean_nr_at_run_s, paired_vs_reference
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, DURATION_S = 6000, 60.0
#: The (alpha_brake, V_switch) grid, in the row order of the results: V_switch outer.
GRID = {"v_switch_fps": (500.0, 600.0, 700.0, 800.0), "alpha_brake_rad": (0.8, 1.0, 1.2)}
#: The ``--zoom`` grid of smc-brake-zoom's bound.
ZOOM_GRID = {
    "v_switch_fps": (500.0, 600.0, 700.0),
    "v_zoom_fps": (1200.0, 1300.0),
    "zoom_slope_fps_per_rad": (300.0, 600.0, 900.0, 1200.0),
}


def times(ctrl, inputs):
    m = run_mc(ctrl, inputs, REF, N_STEPS)[0].metrics
    rec = np.asarray(m.recovered, bool)
    tv = float(np.asarray(m.control_tv_rad, np.float64).sum(-1).mean())
    return np.where(rec, np.asarray(m.t_recover_s, np.float64), np.nan), rec, tv


def controller(setting: dict[str, float]):
    """The braking SMC of one grid point: the schedule of ``brake_schedule(**setting)``."""
    return make_smc_brake(schedule=brake_schedule(**setting))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--zoom", action="store_true", help="sweep smc-brake-zoom's bound instead")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    inputs = sample_mc_inputs(jax.random.key(a.mc_seed), a.n, harv())
    t_smc, r_smc, tv_smc = times(make_smc(), inputs)
    smc_mean_s = mean_nr_at_run_s(t_smc, r_smc, DURATION_S)
    grid = ZOOM_GRID if a.zoom else GRID
    if a.zoom:
        rows = [{"controller": "smc", "mean_s": smc_mean_s, "tv_rad": tv_smc}]
    else:
        rows = [{"alpha_brake_rad": None, "v_switch_fps": None, "mean_s": smc_mean_s, "tv_rad": tv_smc}]
    for values in itertools.product(*grid.values()):
        setting = dict(zip(grid, values, strict=True))
        t, r, tv = times(controller(setting), inputs)
        vs = paired_vs_reference(t, r, t_smc, r_smc, DURATION_S)
        if not a.zoom:  # the row's key order of the committed results
            setting = {"alpha_brake_rad": setting["alpha_brake_rad"], "v_switch_fps": setting["v_switch_fps"]}
        row = {**setting, "recovered": float(r.mean()),
               "mean_s": mean_nr_at_run_s(t, r, DURATION_S), "tv_rad": tv, **vs}  # fmt: skip
        rows.append(row)
        print(json.dumps(row), flush=True)
    flag = " --zoom" if a.zoom else ""
    cmd = f"python experiments/teacher_recipe/brake_grid.py{flag} --mc-seed {a.mc_seed} --n {a.n}"
    a.out.write_text(json.dumps({"command": cmd, "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
