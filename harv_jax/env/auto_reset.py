"""Auto-reset: a step that starts the next episode when one ends (the gymnax convention)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp


def with_auto_reset(
    step_no_reset: Callable[..., tuple],
    reset: Callable[..., tuple],
    critic_observation: Callable[[Any], jnp.ndarray] | None = None,
) -> Callable[..., tuple]:
    """``step(key, state, action, params) -> (obs, state, reward, done, info)`` with auto-reset.

    Built from ``step_no_reset`` (-> obs, state, reward, terminated, truncated, info) and ``reset``; the
    state needs a ``wind`` attribute. When ``done`` the returned obs and state are the new episode's; ``info``
    gains ``final_obs`` and ``final_state_wind`` of the state the finished episode reached (module docstring)
    and, with ``critic_observation`` (state -> the critic's observation), ``final_critic_obs``.
    """

    def step(key: jax.Array, state: Any, action: jnp.ndarray, params: Any):
        k_step, k_reset = jax.random.split(key)
        del key
        obs, new_state, rew, terminated, truncated, info = step_no_reset(k_step, state, action, params)
        done = terminated | truncated
        obs_reset, state_reset = reset(k_reset, params)
        info["final_obs"] = obs
        info["final_state_wind"] = new_state.wind
        if critic_observation is not None:
            info["final_critic_obs"] = critic_observation(new_state)
        state_out = jax.tree.map(lambda r, s: jnp.where(done, r, s), state_reset, new_state)
        obs_out = jnp.where(done, obs_reset, obs)
        return obs_out, state_out, rew, done, info

    return step
