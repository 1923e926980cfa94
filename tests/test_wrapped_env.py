"""The record of a wrapped env: what each wrapper adds is carried outward by the wrappers around it."""

from __future__ import annotations

import pytest

from harv_jax.training.environment import make_harv_env
from harv_jax.training.wrapped_env import ADDED_FIELDS, WrappedEnv, wrap


def test_the_outer_wrapper_carries_the_teacher_and_adds_its_path():
    env, _ = make_harv_env(
        {"episode_steps": 50, "teacher": "smc-brake", "measurement_path": "lp2", "critic": "privileged"}
    )
    assert isinstance(env, WrappedEnv)
    assert env.teacher == "smc-brake" and env.loop == "none"
    assert env.measurement_path == {"kind": "lp", "bandwidth_hz": 2.0}
    assert env.critic_observation is not None


def test_a_plain_env_wrapped_gets_the_defaults_and_unknown_fields_are_refused():
    env, _ = make_harv_env({"episode_steps": 50})
    assert not isinstance(env, WrappedEnv)
    rec = wrap(env, env.reset, env.step, env.step_no_reset, env.reset_to, env.batch_step, loop="hybrid:gated")
    added = (rec.loop, rec.teacher, rec.measurement_path, rec.critic_observation)
    assert added == ("hybrid:gated", None, None, None)
    assert rec.observation_size == env.observation_size and rec.config is env.config
    assert set(ADDED_FIELDS) <= set(WrappedEnv._fields)
    with pytest.raises(ValueError, match="wrapper fields \\['teachr'\\]; allowed: loop, teacher"):
        wrap(env, env.reset, env.step, env.step_no_reset, env.reset_to, env.batch_step, teachr="smc")
