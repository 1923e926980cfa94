"""Observation and action spaces of the paper's task, and the mapping of states and actions to them.

Observation [11] (paper Table "Observation and Action Space"; physical units, ft/s, rad, rad/s):
[V, alpha, beta, p, q, r, mu, gamma, alpha_d, beta_d, mu_d]: the first ``NUM_MEASURED`` components of the
wind-axis state, then the target. A policy trained with ``[env] observe_engage_airspeed = true`` sees a
12th component, ``V_engage``: the airspeed of the first observation of the recovery (ft/s, held for the whole
recovery), so it can make choices that depend on how fast the recovery began. Action [3] in [-1, 1],
mapped affinely to [u_min, u_max] per channel (de, da, dr). The env (``harv_jax.env``) and the learned
controllers (``control.rl``, ``control.hybrid``) both use these functions, so a policy sees in flight exactly
what it saw in training.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from harv_jax.task.spec import (
    ALPHA_MAX_RAD,
    ALPHA_MIN_RAD,
    GAMMA_MAX_RAD,
    RATE_MAX_RADPS,
    V_MAX_FPS,
    V_MIN_FPS,
)

#: Names of the observation components, in order (paper: s = {V, alpha, beta, p, q, r, mu, gamma,
#: alpha_d, beta_d, mu_d}); units ft/s, rad, rad/s.
OBS_NAMES: tuple[str, ...] = ("V", "alpha", "beta", "p", "q", "r", "mu", "gamma", "alpha_d", "beta_d", "mu_d")
OBSERVATION_SIZE = len(OBS_NAMES)
ACTION_SIZE = 3
#: Names of the observation with the engagement airspeed (``observe_engage_airspeed``), in order.
ENGAGE_OBS_NAMES: tuple[str, ...] = (*OBS_NAMES, "V_engage")
ENGAGE_OBSERVATION_SIZE = len(ENGAGE_OBS_NAMES)
#: Number of leading observation components that are measured (sensor noise applies to them).
NUM_MEASURED = 8

_PI = math.pi
_RATE = RATE_MAX_RADPS
#: Observation bounds (paper Table "Observation and Action Space"); the targets get the alpha range
#: (alpha_d) and [-pi, pi] (beta_d, mu_d). Observations are clipped to these bounds, so they only bind
#: on a terminal observation (the envelope is the same box) or through sensor noise at the edge.
OBS_LOW = np.array(
    [V_MIN_FPS, ALPHA_MIN_RAD, -_PI, -_RATE, -_RATE, -_RATE, -_PI, -GAMMA_MAX_RAD, ALPHA_MIN_RAD, -_PI, -_PI],
    dtype=np.float32,
)
OBS_HIGH = np.array(
    [V_MAX_FPS, ALPHA_MAX_RAD, _PI, _RATE, _RATE, _RATE, _PI, GAMMA_MAX_RAD, ALPHA_MAX_RAD, _PI, _PI],
    dtype=np.float32,
)


def action_to_command(action: jnp.ndarray, u_min_rad: jnp.ndarray, u_max_rad: jnp.ndarray) -> jnp.ndarray:
    """Affine map of a normalized action [3] in [-1, 1] to deflections in [u_min, u_max], rad."""
    return u_min_rad + 0.5 * (action + 1.0) * (u_max_rad - u_min_rad)


def command_to_action(cmd_rad: jnp.ndarray, u_min_rad: jnp.ndarray, u_max_rad: jnp.ndarray) -> jnp.ndarray:
    """Inverse of :func:`action_to_command`: deflections [3], rad -> normalized action [3]."""
    return 2.0 * (cmd_rad - u_min_rad) / (u_max_rad - u_min_rad) - 1.0


def clean_observation(x_wind: jnp.ndarray, target_rad: jnp.ndarray) -> jnp.ndarray:
    """[11] observation of a wind-axis state [10] and target [3] without noise or clipping."""
    return jnp.concatenate([x_wind[:NUM_MEASURED], target_rad])


def finish_observation(obs: jnp.ndarray) -> jnp.ndarray:
    """Non-finite components -> 0, then clipped to the observation box [11]."""
    obs = jnp.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)
    return jnp.clip(obs, jnp.asarray(OBS_LOW, obs.dtype), jnp.asarray(OBS_HIGH, obs.dtype))


def observation(x_wind: jnp.ndarray, target_rad: jnp.ndarray) -> jnp.ndarray:
    """[11] noise-free observation as the policy sees it in the env (non-finite -> 0, clipped to the box)."""
    return finish_observation(clean_observation(x_wind, target_rad))


def engage_observation_size(observe_engage_airspeed: bool) -> int:
    """Observation size with (12) or without (11) the engagement airspeed."""
    return ENGAGE_OBSERVATION_SIZE if observe_engage_airspeed else OBSERVATION_SIZE


def observes_engage_airspeed(observation_size: int) -> bool:
    """Whether a policy of ``observation_size`` inputs expects the engagement airspeed (12) or not (11);
    ValueError for any other size."""
    if observation_size not in (OBSERVATION_SIZE, ENGAGE_OBSERVATION_SIZE):
        raise ValueError(
            f"a policy with {observation_size} observations does not fit this task; allowed: "
            f"{OBSERVATION_SIZE} ({', '.join(OBS_NAMES)}) or {ENGAGE_OBSERVATION_SIZE} (and V_engage)"
        )
    return observation_size == ENGAGE_OBSERVATION_SIZE


def with_engage_airspeed(obs: jnp.ndarray, v_engage_fps: jnp.ndarray) -> jnp.ndarray:
    """[11] observation -> [12] with the engagement airspeed appended (clipped to the airspeed bounds)."""
    v = jnp.clip(jnp.asarray(v_engage_fps, obs.dtype), V_MIN_FPS, V_MAX_FPS)
    return jnp.concatenate([obs, v[None]])
