"""A trained policy as a ``Controller``: the RL-only controller of the paper's comparisons.

The policy sees the env's observation (``harv_jax.task.spaces.observation``: V, alpha, beta, p, q, r,
mu, gamma and the references, physical units) and returns a normalized action in [-1, 1]^3, mapped
affinely to the deflection limits exactly as the env does. A policy of 12 observations (trained with
``[env] observe_engage_airspeed = true``) also sees the airspeed of its first observation, which the
controller keeps in its state (:class:`RLEngageState`). Position and rate limits are then applied
by the plant's actuator model, so "RL-only" is subject only to actuator saturation, as in the paper.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.task.spaces import action_to_command, observation, with_engage_airspeed


@struct.dataclass
class RLEngageState:
    """State of a policy that observes the engagement airspeed.

    Attributes:
        params: the aircraft (its deflection limits).
        v_engage_fps: airspeed of the first observation, ft/s (set at the first ``apply``).
        engaged: whether ``apply`` has run (``v_engage_fps`` is set).
    """

    params: AircraftParams
    v_engage_fps: jnp.ndarray
    engaged: jnp.ndarray


def engage_step(
    obs: jnp.ndarray, v_engage_fps: jnp.ndarray, engaged: jnp.ndarray
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """(observation [12], engagement airspeed to keep) from an [11] observation: at the first step
    (``engaged`` false) the engagement airspeed is this observation's airspeed, afterwards the kept one."""
    v = jnp.where(engaged, v_engage_fps, obs[0]).astype(obs.dtype)
    return with_engage_airspeed(obs, v), v


def make_rl_controller(
    act: Callable[[jax.Array], jax.Array],
    stochastic: Callable[[jax.Array, jax.Array], jax.Array] | None = None,
    engage_airspeed: bool = False,
) -> Controller:
    """Build the RL-only controller.

    Args:
        act: deterministic policy ``obs [11] -> action [3]`` in [-1, 1] (``policy.load(p).deterministic``).
        stochastic: optional ``(key, obs) -> action``; when given, ``apply`` samples with its key.
        engage_airspeed: the policy takes 12 observations, the 12th the airspeed of the first observation
            (``harv_jax.task.spaces.ENGAGE_OBS_NAMES``).

    Returns:
        Controller whose ``info`` holds the normalized action ``action`` [3].
    """

    def init(params: AircraftParams) -> AircraftParams:
        return params

    def apply(params, x_wind, reference_rad, key):
        obs = observation(x_wind, reference_rad)
        a = act(obs) if stochastic is None else stochastic(key, obs)
        a = jnp.clip(a, -1.0, 1.0)
        return action_to_command(a, params.u_min_rad, params.u_max_rad), params, {"action": a}

    def init_engage(params: AircraftParams) -> RLEngageState:
        dtype = jnp.result_type(params.mass_slug)
        return RLEngageState(params=params, v_engage_fps=jnp.zeros((), dtype), engaged=jnp.asarray(False))

    def apply_engage(state: RLEngageState, x_wind, reference_rad, key):
        obs, v = engage_step(observation(x_wind, reference_rad), state.v_engage_fps, state.engaged)
        a = act(obs) if stochastic is None else stochastic(key, obs)
        a = jnp.clip(a, -1.0, 1.0)
        cmd = action_to_command(a, state.params.u_min_rad, state.params.u_max_rad)
        return (
            cmd,
            state.replace(v_engage_fps=v.astype(state.v_engage_fps.dtype), engaged=jnp.asarray(True)),
            {"action": a},
        )

    if engage_airspeed:
        return Controller(init=init_engage, apply=apply_engage)
    return Controller(init=init, apply=apply)
