"""A trained policy as a ``Controller``: the RL-only controller of the paper's comparisons.

The policy sees the env's observation (``harv_jax.task.spaces.observation``: V, alpha, beta, p, q, r,
mu, gamma and the references, physical units) and returns a normalized action in [-1, 1]^3, mapped
affinely to the deflection limits exactly as the env does. A policy of 12 or 14 observations (trained with
``[env] observe_engage_airspeed`` or ``observe_tracking_integral``) also sees the airspeed of its first
observation or the integral of its tracking error, which the controller keeps in its state
([`RLMemoryState`][]). Position and rate limits are then applied
by the plant's actuator model, so "RL-only" is subject only to actuator saturation, as in the paper.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.task.spaces import (
    ObservationLayout,
    ObservationMemory,
    action_to_command,
    observation,
    observation_memory_init,
)
from harv_jax.task.spec import DT_S


@struct.dataclass
class RLMemoryState:
    """State of a policy whose observation keeps components of earlier observations.

    Attributes:
        params: the aircraft (its deflection limits).
        obs_memory: the kept components (``harv_jax.task.spaces.ObservationMemory``).
    """

    params: AircraftParams
    obs_memory: ObservationMemory


def make_rl_controller(
    act: Callable[[jax.Array], jax.Array],
    stochastic: Callable[[jax.Array, jax.Array], jax.Array] | None = None,
    layout: ObservationLayout = ObservationLayout(),
) -> Controller:
    """Build the RL-only controller.

    Args:
        act: deterministic policy ``obs [layout.size] -> action [3]`` in [-1, 1]
            (``policy.load(p).deterministic``).
        stochastic: optional ``(key, obs) -> action``; when given, ``apply`` samples with its key.
        layout: the policy's observation layout (default the paper's 11; ``layout_of_size`` of the policy's
            input size): with the engagement airspeed or the tracking-error integral the controller keeps
            them in its state, computed as the env computes them.

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

    def init_memory(params: AircraftParams) -> RLMemoryState:
        return RLMemoryState(
            params=params, obs_memory=observation_memory_init(jnp.result_type(params.mass_slug))
        )

    def apply_memory(state: RLMemoryState, x_wind, reference_rad, key):
        obs, memory = layout.extend(observation(x_wind, reference_rad), state.obs_memory, DT_S)
        cmd, info = command(state.params, obs, key)
        return cmd, state.replace(obs_memory=memory), info

    if layout.has_memory:
        return Controller(init=init_memory, apply=apply_memory)
    return Controller(init=init, apply=apply)
