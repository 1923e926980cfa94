"""A teacher in the env: a controller flown alongside the policy, whose command labels every state.

``make_teacher_env(env, teacher)`` returns an env with the plain env's interface whose step adds
``info["teacher_action"]``: the normalized action in [-1, 1]^3 the teacher controller (a registry controller,
e.g. the braking SMC ``smc-brake``) commands at the state the policy acts in. The policy's action is what
flies; the teacher only labels, on the states the learner visits (DAgger, Ross et al. 2011). The trainer
turns the labels into a behaviour-cloning term of the PPO loss (``PPOConfig.bc_coef``, DAPG, Rajeswaran et
al. 2017). The teacher's own state (e.g. the SMC's integral and its memory of the last command) runs on the
flown trajectory and starts at the episode's initial deflections; its model aircraft is the episode's (a
privileged teacher: it knows the randomized aircraft the policy does not observe).

In a preset: ``[env] teacher = "smc-brake"``.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from harv_jax.control.base import Controller
from harv_jax.env import Env
from harv_jax.task.spaces import command_to_action
from harv_jax.training.in_loop import InLoopState, wrapped_env_functions
from harv_jax.training.wrapped_env import WrappedEnv, wrap

#: Key of the teacher's controller name in a run's env settings (absent: no teacher).
TEACHER_KEY = "teacher"
#: The key of each step's ``info`` that holds the teacher's normalized action [3] (the labels the behaviour
#: cloning term of ``harv_jax.ppo.loss_terms`` reads).
TEACHER_ACTION_KEY = "teacher_action"


def make_teacher_env(env: Env, teacher: Controller, name: str) -> WrappedEnv:
    """Wrap ``env`` so that every step's info carries ``teacher``'s normalized action (``teacher_action``).

    Args:
        env: the plain recovery env.
        teacher: the teacher controller (``Controller(init, apply)``).
        name: its registry name (recorded as ``WrappedEnv.teacher``).
    """

    def step_no_reset(key: jax.Array, state: InLoopState, action: jnp.ndarray, params: Any):
        es = state.env
        u_teacher, ctrl, _ = teacher.apply(state.ctrl, es.wind, es.target_rad, key)
        ac = es.episode.aircraft
        a_teacher = jnp.clip(command_to_action(u_teacher, ac.u_min_rad, ac.u_max_rad), -1.0, 1.0)
        a_teacher = jnp.where(jnp.isfinite(a_teacher), a_teacher, 0.0)
        obs, es_new, reward, terminated, truncated, info = env.step_no_reset(key, es, action, params)
        info[TEACHER_ACTION_KEY] = a_teacher.astype(jnp.float32)
        return obs, InLoopState(env=es_new, ctrl=ctrl), reward, terminated, truncated, info

    reset, reset_to, step, batch_step = wrapped_env_functions(env, teacher, step_no_reset)
    return wrap(env, reset, step, step_no_reset, reset_to, batch_step, teacher=name)
