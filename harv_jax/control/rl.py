"""A trained policy as a ``Controller``: the RL-only controller of the paper's comparisons.

The policy sees the env's observation (``harv_jax.task.spaces.observation``: V, alpha, beta, p, q, r,
mu, gamma and the references, physical units) and returns a normalized action in [-1, 1]^3, mapped
affinely to the deflection limits exactly as the env does. Position and rate limits are then applied
by the plant's actuator model, so "RL-only" is subject only to actuator saturation, as in the paper.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.task.spaces import action_to_command, observation


def make_rl_controller(
    act: Callable[[jax.Array], jax.Array],
    stochastic: Callable[[jax.Array, jax.Array], jax.Array] | None = None,
) -> Controller:
    """Build the RL-only controller.

    Args:
        act: deterministic policy ``obs [11] -> action [3]`` in [-1, 1]
            (``policy.load(p).deterministic``).
        stochastic: optional ``(key, obs) -> action``; when given, ``apply`` samples with its key.

    Returns:
        Controller whose ``info`` holds the normalized action ``action`` [3].
    """

    def command(params: AircraftParams, obs: jnp.ndarray, key: jax.Array):
        a = act(obs) if stochastic is None else stochastic(key, obs)
        a = jnp.clip(a, -1.0, 1.0)
        return action_to_command(a, params.u_min_rad, params.u_max_rad), {"action": a}

    def init(params: AircraftParams) -> AircraftParams:
        return params

    def apply(params, x_wind, reference_rad, key):
        cmd, info = command(params, observation(x_wind, reference_rad), key)
        return cmd, params, info

    return Controller(init=init, apply=apply)
