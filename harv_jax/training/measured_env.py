"""The policy behind its measurement path: the env's observation through a low-pass or an observer.

``make_measured_env(env, path)`` returns an env with the plain env's interface whose observation is what a
policy flown behind ``path`` sees: the sensors' measurement (the air data plus the episode's sensor noise,
``dynamics.disturbed_step.measured``, as the Monte Carlo's controllers get it) through the same measurement
path the registry puts in front of a controller (``control.registry.with_measurement_path``: a
Butterworth low-pass, the model-based observer or the extended-state observer, built on the nominal
aircraft as the Monte Carlo builds its controllers), turned into the policy's observation. The path's
memory of the last command is the command the policy's action flies. The reward, the terminations and a
teacher's labels stay on the true state (privileged: the env, and ``training.teacher`` inside this wrapper,
see the air data without noise).

In a preset: ``[env] measurement_path = "lp2"`` (``obsHZ``, ``esoHZ``); the run's policies carry the path in
their metadata and ``--controller rl``/``hybrid`` fly them behind it. With ``[env] critic = "privileged"``
the critic sees the true state instead (an asymmetric actor-critic: the env's ``critic_observation``, the
observation the policy would get from perfect sensors without the path, ``harv_jax.ppo.acting``); the
policy, and so what is saved and flown, is the same network either way.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from harv_jax.control.base import Controller
from harv_jax.control.registry import with_measurement_path
from harv_jax.dynamics.disturbed_step import measured
from harv_jax.env.auto_reset import with_auto_reset
from harv_jax.task.measurement_path import MeasurementPath, path_record
from harv_jax.task.spaces import action_to_command, clean_observation, finish_observation
from harv_jax.training.in_loop import InLoopState
from harv_jax.training.wrapped_env import WrappedEnv, wrap

#: Key of the measurement path in a run's env settings (absent: none).
MEASUREMENT_PATH_KEY = "measurement_path"
#: ``info`` key of the estimate the policy saw.
SEEN_KEY = "x_seen"
#: Key of what the critic observes in a run's env settings (absent: the policy's observation).
CRITIC_KEY = "critic"
#: What the critic may observe: the policy's observation, or the true state (asymmetric actor-critic).
CRITICS = ("actor", "privileged")


def _capture() -> Controller:
    """A controller that commands nothing and reports the state it is given (the path's estimate)."""

    def init(params: Any) -> jnp.ndarray:
        return jnp.zeros((3,), params.mass_slug.dtype)

    def apply(state: jnp.ndarray, x_wind: jnp.ndarray, reference_rad: jnp.ndarray, key: jax.Array):
        return jnp.zeros((3,), x_wind.dtype), state, {SEEN_KEY: x_wind}

    return Controller(init, apply)


def plain_state(state: Any) -> Any:
    """The recovery env's own state inside wrapper states (``InLoopState`` nests it under ``env``)."""
    while isinstance(state, InLoopState):
        state = state.env
    return state


def true_observation(state: Any) -> jnp.ndarray:
    """[O] the observation of a wrapper state's true (air-data) state, without noise or path."""
    es = plain_state(state)
    return finish_observation(clean_observation(es.wind, es.target_rad))


def make_measured_env(env: Any, path: MeasurementPath, privileged_critic: bool = False) -> WrappedEnv:
    """Wrap ``env`` (the plain env or a teacher wrapper) so that the policy observes through ``path``; with
    ``privileged_critic`` the env offers the critic the true state's observation ([`true_observation`][])."""
    path_ctrl = with_measurement_path(_capture(), path)
    critic = true_observation if privileged_critic else None

    def observe(pstate: Any, inner: Any, key: jax.Array) -> tuple[jnp.ndarray, Any]:
        es = plain_state(inner)
        y = measured(es.wind, es.disturbance, es.episode.levels)
        _, pstate, info = path_ctrl.apply(pstate, y, es.target_rad, key)
        return finish_observation(clean_observation(info[SEEN_KEY], es.target_rad)), pstate

    def step_no_reset(key: jax.Array, state: InLoopState, action: jnp.ndarray, params: Any):
        es = plain_state(state.env)
        ac = es.episode.aircraft
        cmd = action_to_command(jnp.clip(action, -1.0, 1.0), ac.u_min_rad, ac.u_max_rad)
        _, inner, reward, terminated, truncated, info = env.step_no_reset(key, state.env, action, params)
        pstate = state.ctrl.replace(u_prev_rad=cmd.astype(state.ctrl.u_prev_rad.dtype))
        obs, pstate = observe(pstate, inner, key)
        return obs, InLoopState(env=inner, ctrl=pstate), reward, terminated, truncated, info

    inner_reset, inner_reset_to = env.reset, env.reset_to

    def _start(inner: Any, params: Any, key: jax.Array) -> tuple[jnp.ndarray, InLoopState]:
        es = plain_state(inner)
        pstate = path_ctrl.init(params.aircraft)  # the nominal aircraft, as the Monte Carlo's controllers
        pstate = pstate.replace(u_prev_rad=es.delta_rad.astype(pstate.u_prev_rad.dtype))
        obs, pstate = observe(pstate, inner, key)
        return obs, InLoopState(env=inner, ctrl=pstate)

    def reset(key: jax.Array, params: Any) -> tuple[jnp.ndarray, InLoopState]:
        return _start(inner_reset(key, params)[1], params, key)

    def reset_to(key: jax.Array, x_wind: jnp.ndarray, target_rad: jnp.ndarray, params: Any):
        return _start(inner_reset_to(key, x_wind, target_rad, params)[1], params, key)

    step = with_auto_reset(step_no_reset, reset, critic)

    def batch_step(keys: jax.Array, states: InLoopState, actions: jnp.ndarray, params: Any):
        return jax.vmap(step, in_axes=(0, 0, 0, None))(keys, states, actions, params)

    return wrap(
        env,
        reset,
        step,
        step_no_reset,
        reset_to,
        batch_step,
        measurement_path=path_record(path),
        critic_observation=critic,
    )
