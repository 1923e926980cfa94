"""A disturbance added to the table: its model, carried with its level into the one disturbed step.

The built-in disturbances (noise, delay, gust, turbulence, model error, lag) are flown by
``dynamics.disturbed_step`` itself. A row of ``task.disturbance_table`` with a [`DisturbanceModel`][] adds
one more: the Monte Carlo commands take its ``--disturbances`` name and level option, the robustness
sweep its levels, a training preset its ``[randomization]`` key (the env's per-episode maximum, drawn
U(0, 1) times it), and the disturbed step flies it in the env and the Monte Carlo alike:

    state_0   = init(level, key_0)                 at engagement
    wind     += wind_fps(state_k, level)           the air mass's body-axis velocity, ft/s (optional)
    y_k       = measure(y_k, state_k, level)       what the sensors report, the wind state [10] (optional)
    state_k+1 = step(state_k, level, key_k, dt_s)  after the plant step

``level`` is the run's (or the episode's) level in the row's unit, a traced scalar; level 0 must act as
none. Each added disturbance draws from keys of its own (folded from the step's key with a tag of its
name), so that adding one changes none of the other draws.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import jax
import jax.numpy as jnp


@dataclass(frozen=True)
class DisturbanceModel:
    """What an added disturbance does between a controller and the aircraft (module docstring).

    Attributes:
        init: (level, key) -> its state at engagement (a pytree; may be empty).
        step: (state, level, key, dt_s) -> its state one plant step later.
        wind_fps: (state, level) -> [3] body-axis velocity of the air mass it adds, ft/s; None: none.
        measure: (x_wind [10], state, level) -> the wind state the sensors report; None: unchanged.
    """

    init: Callable[[jnp.ndarray, jax.Array], Any]
    step: Callable[[Any, jnp.ndarray, jax.Array, Any], Any]
    wind_fps: Callable[[Any, jnp.ndarray], jnp.ndarray] | None = None
    measure: Callable[[jnp.ndarray, Any, jnp.ndarray], jnp.ndarray] | None = None


#: Models by name, in the table's order: a static part of ``DisturbanceParams`` (one compiled loop per set).
Models = tuple[tuple[str, DisturbanceModel], ...]


def model_key(key: jax.Array, name: str) -> jax.Array:
    """``key`` folded with a tag of ``name``: the added disturbance's own draws."""
    return jax.random.fold_in(key, zlib.crc32(name.encode()) & 0x7FFFFFFF)


def init_states(models: Models, levels: dict[str, jnp.ndarray], key: jax.Array | None) -> dict[str, Any]:
    """Each model's state at engagement (``key`` None: every model's init from a fixed key)."""
    if not models:
        return {}
    base = jax.random.key(0) if key is None else key
    return {name: m.init(levels[name], model_key(base, name)) for name, m in models}


def step_states(
    models: Models, states: dict[str, Any], levels: dict[str, jnp.ndarray], key: jax.Array, dt_s: Any
) -> dict[str, Any]:
    """Each model's state one plant step later."""
    return {name: m.step(states[name], levels[name], model_key(key, name), dt_s) for name, m in models}


def added_wind_fps(
    models: Models, states: dict[str, Any], levels: dict[str, jnp.ndarray]
) -> jnp.ndarray | None:
    """[3] the body-axis air velocity the models add, ft/s (None: none adds any)."""
    winds = [m.wind_fps(states[name], levels[name]) for name, m in models if m.wind_fps is not None]
    return None if not winds else sum(winds[1:], winds[0])


def measure(
    models: Models, x_wind: jnp.ndarray, states: dict[str, Any], levels: dict[str, jnp.ndarray]
) -> jnp.ndarray:
    """The wind state [10] after each model's ``measure``, in the table's order."""
    for name, m in models:
        if m.measure is not None:
            x_wind = m.measure(x_wind, states[name], levels[name])
    return x_wind
