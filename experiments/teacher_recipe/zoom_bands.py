"""Mean recovery time, the share of runs slower than the SMC by > 1 s and the mean control TV (summed over
the surfaces, as ``harv-jax mc``), by the airspeed at engagement: the SMC, the braking SMCs,
``smc-brake-zoom`` without the integral term of its sliding surface, and policies.

    python experiments/teacher_recipe/zoom_bands.py --mc-seed 11 [--policy P ...] \\
        --out experiments/teacher_recipe/results/zoom_bands_mc11.json

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
from harv_jax.control import smc_brake as sb
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.control.smc import default_gains
from harv_jax.evaluation.montecarlo.paired import times_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, DURATION_S = 6000, 60.0
BANDS_FPS = ((0, 400), (400, 600), (600, 800), (800, 1000), (1000, 1200), (1200, 1400), (1400, 2000))


def times_and_tv(ctrl, inputs) -> tuple[np.ndarray, np.ndarray]:
    """Per-run recovery time, s, with a run not recovered at the run length; per-run control TV, rad."""
    m = run_mc(ctrl, inputs, REF, N_STEPS)[0].metrics
    tv_rad = np.asarray(m.control_tv_rad, np.float64).sum(-1)
    return times_nr_at_run_s(m.t_recover_s, m.recovered, DURATION_S), tv_rad


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--policy", action="append", default=[], help="a policy to fly RL-only (repeatable)")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    inputs = sample_mc_inputs(jax.random.key(a.mc_seed), a.n, harv())
    v0 = np.asarray(inputs.x0_wind)[:, 0]
    no_integral = default_gains().replace(lambda2_ps2=jnp.zeros(3))
    controllers = {name: build_controller(name) for name in ("smc", "smc-brake", "smc-brake-zoom")}
    controllers["smc-brake-zoom, no integral"] = sb.make_smc_brake(
        gains=no_integral, schedule=sb.zoom_schedule()
    )
    for p in a.policy:
        controllers[f"rl {p}"] = build_controller("rl", ControllerOptions(policy=p))
    flown = {name: times_and_tv(c, inputs) for name, c in controllers.items()}
    t = {name: tt for name, (tt, _) in flown.items()}
    rows = []
    for name, (tt, tv) in flown.items():
        slower = tt - t["smc"] > 1.0
        bands = [
            {
                "v_lo_fps": lo,
                "v_hi_fps": hi,
                "runs": int(m.sum()),
                "mean_s": float(tt[m].mean()),
                "slower_than_smc_by_1s": float(slower[m].mean()),
                "tv_rad": float(tv[m].mean()),
            }  # fmt: skip
            for lo, hi in BANDS_FPS
            if (m := (v0 >= lo) & (v0 < hi)).any()
        ]
        row = {"controller": name, "mean_over_smc": float(tt.mean() / t["smc"].mean()),
               "slower_than_smc_by_1s": float(slower.mean()), "tv_rad": float(tv.mean()),
               "bands": bands}  # fmt: skip
        rows.append(row)
        cells = " ".join(
            f"{b['mean_s']:6.2f}/{b['slower_than_smc_by_1s']:.2f}/{b['tv_rad']:.2f}" for b in bands
        )
        print(f"{name}: {row['mean_over_smc']:.3f}x smc, slower {row['slower_than_smc_by_1s']:.3f} | {cells}")
    cmd = " ".join(["python experiments/teacher_recipe/zoom_bands.py", f"--mc-seed {a.mc_seed}", f"--n {a.n}",
                    *(f"--policy {p}" for p in a.policy)])  # fmt: skip
    a.out.write_text(json.dumps({"command": cmd, "rows": rows}, indent=2) + "\n")


if __name__ == "__main__":
    main()
