"""What the teacher ``smc-brake-zoom`` says along a flight: on its own trajectories and on a student's.

The teacher's labels are state-based: it brakes (alpha reference 1.0 rad) while 600 < V < 1200 - 600
max(gamma, 0) ft/s. For the Monte Carlo's runs engaged at V0 >= 1200 ft/s, each controller flies 30 s and
the teacher's braking flag is evaluated at every 0.1 s sample of its trajectory: the share of samples labelled
"brake", and the share of runs in which the flag is raised at all.

    python experiments/teacher_recipe/zoom_labels.py --mc-seed 11 --policy P [--policy P ...] \\
        --out experiments/teacher_recipe/results/zoom_labels_mc11.json

Monte Carlo seed 11 is the tuning seed of this study.
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
from harv_jax.control import smc_brake as sb
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.montecarlo.rollout import sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, RECORD_EVERY = 3000, 10  # 30 s, a sample every 0.1 s
V_ZOOM_ENGAGE_FPS = 1200.0


def braking_share(name: str, options: ControllerOptions, inputs, runs: np.ndarray) -> dict[str, float]:
    """Fly ``name`` on the selected runs; the teacher's braking flag along the trajectories."""
    ctrl = build_controller(name, options)
    schedule = sb.zoom_schedule()
    take = lambda a: a[runs]  # noqa: E731
    params = jax.tree.map(take, inputs.params)

    def fly(p, x0, key):
        return closed_loop(ctrl, p, x0, REF, key, N_STEPS, record_every=RECORD_EVERY).traj.x_wind

    x = jax.jit(jax.vmap(fly))(params, take(inputs.x0_wind), take(inputs.keys))
    flag = jax.vmap(jax.vmap(lambda xw: sb.braking_reference(xw, REF, schedule)[1]))(x)
    flag = np.asarray(flag)
    v = np.asarray(x[..., 0])
    return {
        "brake_label_share": float(flag.mean()),
        "runs_with_a_brake_label": float(flag.any(axis=1).mean()),
        "v_at_10s_fps_median": float(np.median(v[:, 100])),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--n", type=int, default=1000, help="Monte Carlo runs (those engaged >= 1200 ft/s fly)")
    ap.add_argument("--policy", action="append", default=[], help="a policy to fly RL-only (repeatable)")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    inputs = sample_mc_inputs(jax.random.key(a.mc_seed), a.n, harv())
    runs = np.flatnonzero(np.asarray(inputs.x0_wind)[:, 0] >= V_ZOOM_ENGAGE_FPS)
    rows = {"smc-brake-zoom": braking_share("smc-brake-zoom", ControllerOptions(), inputs, runs)}
    for p in a.policy:
        rows[f"rl {p}"] = braking_share("rl", ControllerOptions(policy=p), inputs, runs)
    for name, row in rows.items():
        print(name, row, flush=True)
    out = {
        "command": " ".join(["python", *sys.argv]),
        "mc_seed": a.mc_seed,
        "runs_engaged_at_or_above_1200_fps": int(runs.size),
        "seconds_flown": N_STEPS * DT_S,
        "rows": rows,
    }
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
