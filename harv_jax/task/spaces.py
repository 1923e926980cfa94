"""Observation and action spaces of the paper's task, and the mapping of states and actions to them.

Observation [11] (paper Table "Observation and Action Space"; physical units, ft/s, rad, rad/s):
[V, alpha, beta, p, q, r, mu, gamma, alpha_d, beta_d, mu_d]: the first ``NUM_MEASURED`` components of the
wind-axis state, then the target.

Action [3] in [-1, 1],
mapped affinely to [u_min, u_max] per channel (de, da, dr). The env (``harv_jax.env``) and the learned
controllers (``control.rl``, ``control.hybrid.law``) both use these functions, so a policy sees in flight
exactly what it saw in training.
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
    """Inverse of [`action_to_command`][]: deflections [3], rad -> normalized action [3]."""
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


def check_policy_sizes(observation_size: int, action_size: int) -> None:
    """ValueError naming the sizes unless a policy maps the 11 observations to the 3 actions."""
    if (observation_size, action_size) != (OBSERVATION_SIZE, ACTION_SIZE):
        raise ValueError(
            f"a policy that maps {observation_size} observations to {action_size} actions does not fit this "
            f"task; allowed: {OBSERVATION_SIZE} observations -> {ACTION_SIZE} actions"
        )
