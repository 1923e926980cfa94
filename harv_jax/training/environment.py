"""The recovery env and its traced parameters from a preset's env settings."""

from __future__ import annotations

from typing import Any

from harv_jax.env import Env, EnvParams, make_env, settings
from harv_jax.errors import UsageError
from harv_jax.training.in_loop import InLoopEnv, make_in_loop_env, split_loop
from harv_jax.training.teacher import (
    TEACHER_KEY,
    TEACHER_MODEL_KEY,
    TEACHER_MODELS,
    TeacherEnv,
    make_teacher_env,
)
from harv_jax.training.time_to_go import make_progress_env, progress_settings


def make_harv_env(
    env_table: dict[str, Any], spin_bank: Any = None
) -> tuple[Env | InLoopEnv | TeacherEnv, EnvParams]:
    """(env, env_params) of the recovery env from a preset's env settings; UsageError if a key is bad.

    ``env_table`` holds the ``[env]`` fields and the nested ``reward``/``randomization``/``spin``/``eval``
    tables (``harv_jax.env.settings``), and optionally ``loop`` (``harv_jax.training.in_loop``: with
    ``hybrid:<schedule>`` the env applies the hybrid law inside its step) or ``teacher`` (a registry
    controller whose action labels every step: ``harv_jax.training.teacher``), and ``time_to_go`` (a progress
    reward: ``harv_jax.training.time_to_go``). With spin resets on
    (``spin.reset_prob`` > 0) the spin bank is ``spin_bank`` or, if None, made here from the ``[spin]`` table.
    """
    teacher = teacher_name(env_table)
    model = teacher_model(env_table)
    progress = progress_settings(env_table)
    loop, env_table = split_loop(env_table)
    settings.check_env_settings(env_table)  # every table, before the spin bank is made
    flat, nested = settings.split_tables(env_table)
    env_config = settings.env_config(flat)
    if spin_bank is None:
        spin_bank = settings.build_spin_bank(env_config, nested)
    env = make_env(env_config)
    if progress is not None:
        env = make_progress_env(env, *progress)
    if loop != "none":
        env = make_in_loop_env(env, loop.removeprefix("hybrid:"))
    if teacher is not None:
        from harv_jax.control.registry import build_controller

        env = make_teacher_env(env, build_controller(teacher), teacher, model)
    return env, settings.env_params(env_config, nested, spin_bank)


def teacher_model(env_table: dict[str, Any]) -> str:
    """The teacher's model aircraft of a run's env settings (``[env] teacher_model``, default ``"episode"``);
    UsageError naming a value that is not allowed, or a model without a teacher."""
    model = env_table.get(TEACHER_MODEL_KEY, "episode")
    if model not in TEACHER_MODELS:
        raise UsageError(f"[env] teacher_model {model!r}; allowed: {', '.join(TEACHER_MODELS)}")
    if TEACHER_MODEL_KEY in env_table and env_table.get(TEACHER_KEY) is None:
        raise UsageError(f"[env] teacher_model {model!r} given without a teacher; set [env] teacher too")
    return model


def teacher_name(env_table: dict[str, Any]) -> str | None:
    """The teacher controller of a run's env settings (``[env] teacher``), or None; UsageError naming a
    value that is not a registry controller, or a teacher combined with a controller in the loop."""
    from harv_jax.control.registry import controller_names, uses_option

    name = env_table.get(TEACHER_KEY)
    if name is None:
        return None
    teachers = [n for n in controller_names() if not uses_option([n], "policy")]  # model-based ones
    if not isinstance(name, str) or name not in teachers:
        allowed = ", ".join(teachers)
        raise UsageError(f"[env] teacher {name!r} is not a controller that can teach; allowed: {allowed}")
    if split_loop(env_table)[0] != "none":
        raise UsageError(f"[env] teacher {name!r} cannot be combined with --in-loop; drop one of them")
    return name
