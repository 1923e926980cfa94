"""Probe: train with the reset bank extended by states along the teacher's own recoveries.

256 upsets of Monte Carlo seed 9 (used for this probe only) are flown by ``smc-brake-zoom``; from each, the
state and deflections at a uniform time between engagement and the teacher's recovery time join the 256
developed spins of the ``[spin]`` reset bank, so that with ``[spin] reset_prob = 0.4`` a fifth of the episodes
start in a spin and a fifth on the way of a teacher's recovery (a start-state curriculum in the spirit of
jump-start RL, without flying the teacher: every step of an episode is the policy's). This script replaces
the bank builder of ``harv_jax.env.env_settings`` for its own process, then runs ``harv-jax train`` with the
arguments given (``--guide-v0-min FPS``, read here: the guide states only from upsets engaged at least that
fast; default 0):

    python experiments/teacher_recipe/guide_probe.py \\
        --preset experiments/teacher_recipe/v42_teacher_zoom_wide_guide.toml \\
        --seed 7 --out runs/tuning_v42_teacher_zoom_wide_guide_seed7
"""

from __future__ import annotations

import sys

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.cli import main as cli_main
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.env import env_settings
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.montecarlo.rollout import sample_mc_inputs
from harv_jax.task.criteria import default_criterion, recovered_mask
from harv_jax.task.spec import ALPHA_TARGET_RAD
from harv_jax.task.spin_bank import SpinBank

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N, SEED = 256, 9
V0_MIN_FPS = [0.0]  # --guide-v0-min FPS: guide states only from upsets engaged at least this fast


def guide_states(v0_min_fps: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(states [N, 10], deflections [N, 3]) at a uniform time along the teacher's recoveries from the first N
    upsets engaged at or above ``v0_min_fps``."""
    inputs = sample_mc_inputs(jax.random.key(SEED), 8 * N, harv())
    runs = np.flatnonzero(np.asarray(inputs.x0_wind)[:, 0] >= v0_min_fps)[:N]
    inputs = jax.tree.map(lambda a: a[runs], inputs)
    ctrl = build_controller("smc-brake-zoom", ControllerOptions())

    def fly(p, x0, key):
        tr = closed_loop(ctrl, p, x0, REF, key, 3000, record_every=10).traj
        return tr.x_wind, tr.delta_rad, recovered_mask(tr.x_wind, REF, default_criterion())

    x, d, ok = (np.asarray(a) for a in jax.jit(jax.vmap(fly))(inputs.params, inputs.x0_wind, inputs.keys))
    T = ok.shape[1]
    last_out = np.where((~ok).any(1), T - 1 - np.argmax((~ok)[:, ::-1], 1), 0)
    u = np.random.default_rng(SEED).uniform(size=N)
    idx = np.minimum((u * last_out).astype(int), T - 1)
    return x[np.arange(N), idx], d[np.arange(N), idx]


_SPIN_BANK = env_settings.build_spin_bank


def _with_guide_states(config, nested) -> SpinBank:
    """The ``[spin]`` bank with the guide states after its spins."""
    bank = _SPIN_BANK(config, nested)
    gx, gd = guide_states(V0_MIN_FPS[0])
    print("guide states:", gx.shape, "V median", np.median(gx[:, 0]), flush=True)
    return SpinBank(
        x_wind=jnp.concatenate([jnp.asarray(bank.x_wind), jnp.asarray(gx, bank.x_wind.dtype)]),
        delta_rad=jnp.concatenate([jnp.asarray(bank.delta_rad), jnp.asarray(gd, bank.delta_rad.dtype)]),
        spin_s=jnp.concatenate([jnp.asarray(bank.spin_s), jnp.zeros(N, bank.spin_s.dtype)]),
        spinning=jnp.concatenate([jnp.asarray(bank.spinning), jnp.zeros(N, bool)]),
    )


def main() -> None:
    args = sys.argv[1:]
    if "--guide-v0-min" in args:
        i = args.index("--guide-v0-min")
        V0_MIN_FPS[0] = float(args[i + 1])
        del args[i : i + 2]
    env_settings.build_spin_bank = _with_guide_states
    sys.argv = ["harv-jax", "train", *args]
    cli_main()


if __name__ == "__main__":
    main()
