"""The SMC behind a measurement low-pass filter under sensor noise: recovery, mean time, TV and chatter.

python experiments/robustness/filters.py [--runs 128] [--seed 11] > experiments/robustness/results/filters.txt
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.filters import with_measurement_filter
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", type=int, default=128)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--controller", default="smc")
    args = ap.parse_args()
    ref = jnp.array([ALPHA_TARGET_RAD, 0.0, 0.0])
    base = build_controller(args.controller, ControllerOptions())
    variants = {"unfiltered": base}
    variants.update({f"order 2 at {f:g} Hz": with_measurement_filter(base, f, 2) for f in (4.0, 2.0, 1.0)})
    for noise in (0.0, 1.0, 3.0):
        inputs = sample_mc_inputs(
            jax.random.key(args.seed), args.runs, harv(), disturbances=DisturbanceSpec(noise_scale=noise)
        )
        for label, ctrl in variants.items():
            out, _ = run_mc(ctrl, inputs, ref, 6000, record_every=100)
            m = out.metrics
            t_mean = np.where(m.recovered, m.t_recover_s, 60.0).mean()
            print(
                f"{args.controller}, noise {noise:g}x, {label}: recovered {m.recovered.mean():.3f}, mean "
                f"{t_mean:.2f} s, TV {np.sum(m.control_tv_rad, -1).mean():.1f} rad, chatter "
                f"{np.sum(m.chatter_index_rad2, -1).mean():.3g} rad^2",
                flush=True,
            )


if __name__ == "__main__":
    main()
