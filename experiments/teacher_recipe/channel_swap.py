"""Which of a student's three commands costs it against the SMC: the policy flies with some of its commands
replaced by the teacher's (``smc-brake-zoom``, computed on the same state every step), paired against the
SMC on the same Monte Carlo runs.

    python experiments/teacher_recipe/channel_swap.py POLICY.npz --mc-seed 11 \\
        --out experiments/teacher_recipe/results/channel_swap.json

Channels are the policy's action order (elevator, aileron, rudder). Monte Carlo seed 11 is the tuning seed
of this study.
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
from harv_jax.evaluation.montecarlo.paired import paired_vs_reference, times_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, DURATION_S = 6000, 60.0
TEACHER = "smc-brake-zoom"
CHANNELS = ("elevator", "aileron", "rudder")
#: Which channels fly the teacher's command, per row.
MASKS = ((0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0, 1, 1), (1, 1, 1))
BANDS_FPS = ((0, 600), (600, 1000), (1000, 2000))


def swapped(policy: Controller, teacher: Controller, mask: tuple[int, ...]) -> Controller:
    """The policy with the channels where ``mask`` is 1 replaced by the teacher's command."""
    m = jnp.asarray(mask, jnp.float32)

    def init(params):
        return (policy.init(params), teacher.init(params))

    def apply(state, x_wind, reference_rad, key):
        u_p, s_p, _ = policy.apply(state[0], x_wind, reference_rad, key)
        u_t, s_t, _ = teacher.apply(state[1], x_wind, reference_rad, key)
        return m * u_t + (1.0 - m) * u_p, (s_p, s_t), {}

    return Controller(init, apply)


def flown(ctrl: Controller, inputs) -> tuple[np.ndarray, np.ndarray]:
    """Per-run recovery time, s (not recovered: the run length), and control TV summed over the surfaces."""
    m = run_mc(ctrl, inputs, REF, N_STEPS)[0].metrics
    t = times_nr_at_run_s(m.t_recover_s, m.recovered, DURATION_S)
    return t, np.asarray(m.control_tv_rad, np.float64).sum(-1)


def slower(t: np.ndarray, t_smc: np.ndarray) -> float:
    """Share of runs recovered more than 1 s after the SMC (times count a not-recovered run at the run
    length)."""
    yes = np.ones(t.shape, bool)
    return paired_vs_reference(t, yes, t_smc, yes, DURATION_S)["slower_fraction"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("policy", help="policy file (.npz)")
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--n", type=int, default=1000, help="Monte Carlo runs")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    inputs = sample_mc_inputs(jax.random.key(a.mc_seed), a.n, harv())
    v0 = np.asarray(inputs.x0_wind[:, 0], np.float64)
    t_smc, tv_smc = flown(build_controller("smc", ControllerOptions()), inputs)
    policy = build_controller("rl", ControllerOptions(policy=a.policy))
    teacher = build_controller(TEACHER, ControllerOptions())
    rows = []
    for mask in MASKS:
        t, tv = flown(swapped(policy, teacher, mask), inputs)
        bands = {f"{lo}-{hi}": (v0 > lo) & (v0 <= hi) for lo, hi in BANDS_FPS}
        row = {
            "teacher_on": [c for c, on in zip(CHANNELS, mask, strict=True) if on],
            "recovered": float(np.mean(t < DURATION_S)),
            "mean_over_smc": float(t.mean() / t_smc.mean()),
            "slower": slower(t, t_smc),
            "tv_rad": float(tv.mean()),
            "slower_by_v0": {name: slower(t[sel], t_smc[sel]) for name, sel in bands.items()},
        }
        rows.append(row)
        print(json.dumps(row), flush=True)
    doc = {
        "policy": a.policy,
        "teacher": TEACHER,
        "mc_seed": a.mc_seed,
        "runs": a.n,
        "smc": {"mean_s": float(t_smc.mean()), "tv_rad": float(tv_smc.mean())},
        "rows": rows,
    }
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
