"""The recovery env of a training run and its traced parameters, from its
[`TrainSpec`][harv_jax.training.spec.TrainSpec]."""

from __future__ import annotations

from typing import Any

from harv_jax.control.registry import build_controller
from harv_jax.env import Env, EnvParams, make_env
from harv_jax.ppo.config import PPOConfig
from harv_jax.training.in_loop import make_in_loop_env
from harv_jax.training.measured_env import make_measured_env
from harv_jax.training.spec import TrainSpec
from harv_jax.training.teacher import make_teacher_env
from harv_jax.training.wrapped_env import WrappedEnv


def make_harv_env(
    spec: TrainSpec | dict[str, Any], spin_bank: Any = None
) -> tuple[Env | WrappedEnv, EnvParams]:
    """(env, env_params) of a run: the recovery env of ``spec.env``, with the hybrid law inside its step
    (``spec.loop``: ``harv_jax.training.in_loop``) or a teacher whose action labels every step
    (``spec.teacher``: ``harv_jax.training.teacher``), the policy's observation through its measurement
    path (``spec.measurement_path``: ``harv_jax.training.measured_env``), the critic on the true state with
    ``spec.critic`` ``privileged``. With spin resets on
    (``spin.reset_prob`` > 0) the spin bank is ``spin_bank`` or, if None, made here from the ``[spin]``
    table.

    ``spec`` may also be a preset's env settings (a dict with the nested tables and the wrapper keys),
    checked as a spec with the default PPO config (UsageError naming a bad value).
    """
    if not isinstance(spec, TrainSpec):
        spec = TrainSpec.from_settings("(env settings)", PPOConfig(), spec)
    if spin_bank is None:
        spin_bank = spec.env.spin_bank()
    env = make_env(spec.env.config)
    if spec.loop != "none":
        env = make_in_loop_env(env, spec.loop.removeprefix("hybrid:"))
    if spec.teacher is not None:
        env = make_teacher_env(env, build_controller(spec.teacher), spec.teacher)
    if spec.path is not None:  # the policy observes through its measurement path; the teacher the true state
        env = make_measured_env(env, spec.path, privileged_critic=spec.critic == "privileged")
    return env, spec.env.params(spin_bank)
