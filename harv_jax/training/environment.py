"""The recovery env and its traced parameters from a preset's env settings."""

from __future__ import annotations

from typing import Any

from harv_jax.env import Env, EnvParams, make_env, settings
from harv_jax.training.in_loop import InLoopEnv, make_in_loop_env, split_loop


def make_harv_env(env_table: dict[str, Any], spin_bank: Any = None) -> tuple[Env | InLoopEnv, EnvParams]:
    """(env, env_params) of the recovery env from a preset's env settings; UsageError if a key is bad.

    ``env_table`` holds the ``[env]`` fields and the nested ``reward``/``randomization``/``spin``/``eval``
    tables (``harv_jax.env.settings``), and optionally ``loop`` (``harv_jax.training.in_loop``: with
    ``hybrid:<schedule>`` the env applies the hybrid law inside its step). With spin resets on
    (``spin.reset_prob`` > 0) the spin bank is ``spin_bank`` or, if None, made here from the ``[spin]`` table.
    """
    loop, env_table = split_loop(env_table)
    flat, nested = settings.split_tables(env_table)
    env_config = settings.env_config(flat)
    settings.spin_settings(nested["spin"])
    settings.eval_settings(nested["eval"])
    if spin_bank is None:
        spin_bank = settings.build_spin_bank(env_config, nested)
    env = make_env(env_config)
    if loop != "none":
        env = make_in_loop_env(env, loop.removeprefix("hybrid:"))
    return env, settings.env_params(env_config, nested, spin_bank)
