"""Controller in the loop: the recovery env with the hybrid law applied inside its step (residual learning).

The policy's action a in [-1, 1]^3 is the hybrid's u_RL (``control.hybrid.law``): at every step the hybrid
computes u = u_RL + zeta u_fb (its schedule, safety filter and supervisor included) from the true
wind-axis state and the episode's target, and the env flies u (mapped back to a normalized action,
exactly invertible). The policy therefore learns what to add to an SMC that is already there, in the
same compiled graph as the plain env: ``make_in_loop_env(env, "gated")`` returns an object with the
plain env's interface (``reset``/``step``/``batch_step``/``step_no_reset``/``reset_to``), so the
trainer and the evaluators take it unchanged.

The hybrid's model aircraft is the episode's aircraft (as in the Monte Carlo, where the controller is
built on the aircraft it flies); its memory of the last command starts at the episode's initial
deflections (e.g. the pro-spin controls of a spin reset). The reward is the env's, computed on the
command that acts. ``info["loop"]`` adds the hybrid's zeta (mean over channels), whether the policy
acted unmodified and the supervisor's fallback flag.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from harv_jax.control.hybrid.law import HybridConfig, HybridState, make_hybrid
from harv_jax.control.hybrid.settings import ZETA_SCHEDULES, HybridGains
from harv_jax.control.smc import SMCConfig
from harv_jax.env import Env, EnvState
from harv_jax.env.auto_reset import with_auto_reset
from harv_jax.errors import UsageError
from harv_jax.task.spaces import command_to_action
from harv_jax.training.wrapped_env import WrappedEnv, wrap

#: Loops a policy can be trained in: ``none`` (the plain env) or ``hybrid:<schedule>``.
LOOPS: tuple[str, ...] = ("none",) + tuple(f"hybrid:{s}" for s in ZETA_SCHEDULES)
#: Key of the loop in a run's env settings (``config.json`` ``env``, checkpoints): absent = ``none``.
LOOP_KEY = "loop"


def parse_loop(text: str) -> str:
    """Canonical loop name from ``none``, ``hybrid`` (= ``hybrid:gated``) or ``hybrid:<schedule>``.

    Raises:
        UsageError: one line naming the bad value and what is allowed.
    """
    t = str(text).strip().lower()
    if t == "hybrid":
        t = "hybrid:gated"
    if t not in LOOPS:
        raise UsageError(
            f"--in-loop {text!r} is unknown; allowed: {', '.join(LOOPS)} ('hybrid' = 'hybrid:gated')"
        )
    return t


@jax.tree_util.register_pytree_node_class
class InLoopState:
    """The env's state plus the hybrid controller's (one episode in flight); a pytree.

    ``step`` and ``wind`` read the env's, and ``replace(step=...)`` sets the env's episode step (the
    trainer's staggered episode starts), so the trainer sees the interface of ``EnvState``.
    """

    def __init__(self, env: EnvState, ctrl: HybridState) -> None:
        self.env = env
        self.ctrl = ctrl

    def tree_flatten(self) -> tuple[tuple[EnvState, HybridState], None]:
        return (self.env, self.ctrl), None

    @classmethod
    def tree_unflatten(cls, aux: None, children: tuple[EnvState, HybridState]) -> InLoopState:
        del aux
        return cls(*children)

    @property
    def step(self) -> jnp.ndarray:
        return self.env.step

    @property
    def wind(self) -> jnp.ndarray:
        return self.env.wind

    def replace(self, **changes: Any) -> InLoopState:
        env, ctrl = changes.pop("env", self.env), changes.pop("ctrl", self.ctrl)
        if "step" in changes:
            env = env.replace(step=changes.pop("step"))
        if changes:
            raise TypeError(f"InLoopState.replace: unknown fields {sorted(changes)}")
        return InLoopState(env, ctrl)


def controller_at_reset(controller: Any, es: EnvState) -> Any:
    """A controller's state at an episode's start: built on the episode's aircraft, its memory of the last
    command (if it keeps one) at the episode's initial deflections (e.g. a spin reset's pro-spin controls)."""
    ctrl = controller.init(es.episode.aircraft)
    if hasattr(ctrl, "u_prev_rad"):
        ctrl = ctrl.replace(u_prev_rad=es.delta_rad.astype(ctrl.u_prev_rad.dtype))
    return ctrl


def wrapped_env_functions(env: Env, controller: Any, step_no_reset: Any) -> tuple[Any, Any, Any, Any]:
    """(reset, reset_to, step, batch_step) of an env whose states are ``InLoopState`` (``env``'s state plus
    ``controller``'s, started by [`controller_at_reset`][] on the episode's aircraft), given its
    ``step_no_reset``; ``step`` auto-resets as the plain env's does."""

    def _wrap(obs: jnp.ndarray, es: EnvState, params: Any) -> tuple[jnp.ndarray, InLoopState]:
        return obs, InLoopState(env=es, ctrl=controller_at_reset(controller, es))

    def reset(key: jax.Array, params: Any) -> tuple[jnp.ndarray, InLoopState]:
        return _wrap(*env.reset(key, params), params)

    def reset_to(key: jax.Array, x_wind: jnp.ndarray, target_rad: jnp.ndarray, params: Any):
        return _wrap(*env.reset_to(key, x_wind, target_rad, params), params)

    step = with_auto_reset(step_no_reset, reset)

    def batch_step(keys: jax.Array, states: InLoopState, actions: jnp.ndarray, params: Any):
        return jax.vmap(step, in_axes=(0, 0, 0, None))(keys, states, actions, params)

    return reset, reset_to, step, batch_step


def make_in_loop_env(env: Env, schedule: str = "gated", gains: HybridGains | None = None) -> WrappedEnv:
    """Wrap ``env`` so that its actions are the hybrid's u_RL under ``schedule`` (a ``ZETA_SCHEDULES`` name).

    Args:
        env: the plain recovery env (``make_env``).
        schedule: the hybrid's zeta schedule.
        gains: traced hybrid gains (default ``default_hybrid_gains()``).
    """
    cfg = HybridConfig(schedule=schedule, smc=SMCConfig(dt_s=env.config.dt_s))

    def _hybrid(action: jnp.ndarray):
        return make_hybrid(lambda _obs: action, cfg, gains)

    def step_no_reset(key: jax.Array, state: InLoopState, action: jnp.ndarray, params: Any):
        es = state.env
        a_rl = jnp.clip(action, -1.0, 1.0)
        u, ctrl, cinfo = _hybrid(a_rl).apply(state.ctrl, es.wind, es.target_rad, key)
        ac = es.episode.aircraft
        a_flown = jnp.clip(command_to_action(u, ac.u_min_rad, ac.u_max_rad), -1.0, 1.0)
        obs, es_new, reward, terminated, truncated, info = env.step_no_reset(key, es, a_flown, params)
        info["loop"] = {
            "zeta": cinfo["zeta"],
            "policy_unmodified": cinfo["policy_unmodified"],
            "fallback": cinfo["fallback"],
        }
        return obs, InLoopState(env=es_new, ctrl=ctrl), reward, terminated, truncated, info

    # the hybrid's state does not depend on the action its policy returns: any stands in at a reset
    reset, reset_to, step, batch_step = wrapped_env_functions(env, _hybrid(jnp.zeros((3,))), step_no_reset)
    return wrap(env, reset, step, step_no_reset, reset_to, batch_step, loop=f"hybrid:{schedule}")
