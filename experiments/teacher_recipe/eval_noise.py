"""RL-only under sensor noise (and delay): recovered share, mean recovery time, control TV per policy.

    python experiments/teacher_recipe/eval_noise.py RUNS MC_SEED POLICY [POLICY ...]

Conditions: clean, noise 1x (the env's per-channel maxima), noise 1x + 20 ms delay, noise 3x
(``harv_jax.evaluation.montecarlo.disturbances``); the same runs for every policy.
"""

from __future__ import annotations

import sys

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD

CONDITIONS = {
    "clean": DisturbanceSpec(),
    "noise1": DisturbanceSpec(noise_scale=1.0),
    "noise1+delay20": DisturbanceSpec(noise_scale=1.0, delay_ms=20.0),
    "noise3": DisturbanceSpec(noise_scale=3.0),
}


def main() -> None:
    n, seed, policies = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3:]
    ref = jnp.array([ALPHA_TARGET_RAD, 0.0, 0.0])
    for label, spec in CONDITIONS.items():
        inputs = sample_mc_inputs(jax.random.key(seed), n, harv(), disturbances=spec)
        for pol in policies:
            ctrl = build_controller("rl", ControllerOptions(policy=pol))
            out, _ = run_mc(ctrl, inputs, ref, 6000, record_every=100)
            m = out.metrics
            tv = np.sum(m.control_tv_rad, -1).mean()
            t_mean = np.where(m.recovered, m.t_recover_s, 60.0).mean()
            print(
                f"{label} rl {pol}: recovered {m.recovered.mean():.3f}, mean {t_mean:.2f} s, TV {tv:.1f} rad"
            )


if __name__ == "__main__":
    main()
