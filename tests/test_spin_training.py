"""Spin bank, spin resets of the env, evaluation during training (fixed batch, MC criterion), period hook."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.aircraft import harv
from harv_jax.env import EnvConfig, make_env, settings
from harv_jax.env.config import default_randomization_params
from harv_jax.task.spin_bank import make_spin_bank


@pytest.fixture(scope="module")
def bank():
    return make_spin_bank(jax.random.key(3), 16, harv(), default_randomization_params(True), 8.0, 12.0)


def test_spin_bank_states_are_developed_upsets(bank):
    x = np.asarray(bank.x_wind)
    assert x.shape == (16, 10) and np.all(np.isfinite(x))
    # high-alpha post-stall descents: alpha 35-90 deg, steep descent, altitude lost from 25,000 ft
    assert np.all(np.degrees(x[:, 1]) > 35.0) and np.all(np.degrees(x[:, 1]) < 90.0)
    assert np.all(x[:, 7] < -0.5) and np.all(x[:, 9] < 25_000.0)
    # both spin senses: the yaw rate has either sign, the aileron/rudder deflections follow it
    r, d = x[:, 5], np.asarray(bank.delta_rad)
    assert (r > 0).any() and (r < 0).any()
    np.testing.assert_array_equal(np.sign(d[:, 2]), -np.sign(r))
    np.testing.assert_allclose(d[:, 0], -0.436, atol=1e-3)  # full aft stick reached through the actuator
    s = np.asarray(bank.spin_s)
    assert np.all((s >= 8.0 - 1e-3) & (s <= 12.0 + 1e-3))


def test_spin_bank_is_deterministic(bank):
    again = make_spin_bank(jax.random.key(3), 16, harv(), default_randomization_params(True), 8.0, 12.0)
    np.testing.assert_array_equal(np.asarray(again.x_wind), np.asarray(bank.x_wind))


def test_spin_resets_start_from_the_bank(bank):
    env_cfg = EnvConfig(episode_steps=50, domain_randomization=False)
    nested = {"spin": {"reset_prob": 1.0}, "reward": {}, "randomization": {}, "eval": {}}
    params = settings.env_params(env_cfg, nested, bank)
    env = make_env(env_cfg)
    reset = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))  # one compile serves both resets below
    _, states = reset(jax.random.split(jax.random.key(0), 64), params)
    x0, d0 = np.asarray(states.wind), np.asarray(states.delta_rad)
    bank_x, bank_d = np.asarray(bank.x_wind), np.asarray(bank.delta_rad)
    # every start is a bank entry within the perturbation box, with that entry's deflections
    for i in range(64):
        k = int(np.argmin(np.abs(bank_x[:, 9] - x0[i, 9]) + np.abs(bank_x[:, 0] - x0[i, 0]) / 100))
        np.testing.assert_allclose(d0[i], bank_d[k], atol=1e-6)
        assert np.all(np.abs(x0[i, :6] - bank_x[k, :6]) <= np.asarray(params.spin_perturb[:6]) + 1e-4), i
    # with reset_prob 0 no start is a spin
    params0 = params.replace(spin_reset_prob=jnp.asarray(0.0, jnp.float32))
    _, s0 = reset(jax.random.split(jax.random.key(0), 64), params0)
    assert np.all(np.asarray(s0.delta_rad) == 0.0) and np.all(np.asarray(s0.wind)[:, 9] == 25_000.0)


def test_policy_eval_equals_monte_carlo():
    """The training-time evaluation scores runs exactly as the Monte Carlo does (same runs, same policy)."""
    from harv_jax.control.rl import make_rl_controller
    from harv_jax.evaluation.montecarlo.rollout import run_mc
    from harv_jax.evaluation.policy_eval import make_eval_batch, make_policy_eval, summarize_eval

    def act(params, normalizer, obs):  # a fixed linear "policy": pitch and roll damping
        return jnp.tanh(params @ (obs - normalizer))

    w = jnp.zeros((3, 11)).at[0, 4].set(2.0).at[1, 3].set(-1.0).at[2, 5].set(1.0)
    bias = jnp.zeros((11,))
    batch = make_eval_batch(6, 0, harv())
    out = jax.jit(make_policy_eval(act, batch, duration_s=12.0))(w, bias)
    ctrl = make_rl_controller(lambda obs: act(w, bias, obs))
    from harv_jax.evaluation.montecarlo.rollout import MCInputs

    inputs = MCInputs(x0_wind=batch.x0_wind, params=batch.params, keys=jax.random.split(jax.random.key(0), 6))
    mc, _ = run_mc(ctrl, inputs, jnp.asarray([0.349, 0.0, 0.0]), 1200)
    np.testing.assert_array_equal(np.asarray(out["recovered"]), np.asarray(mc.metrics.recovered))
    np.testing.assert_allclose(np.asarray(out["t_recover_s"]), np.asarray(mc.metrics.t_recover_s), atol=1e-6)
    s = summarize_eval({k: np.asarray(v)[None] for k, v in out.items()}, np.zeros(6, bool))
    assert s["eval/recovered"].shape == (1,) and "eval/recovered_spin" not in s


def test_period_hook_adds_metrics_and_stops(tmp_path):
    from test_train import CFG, TOY_PARAMS, ToyEnv

    from harv_jax.ppo import checkpoint
    from harv_jax.ppo.runner import run_training

    calls = []

    def hook(p, state):
        calls.append(p)
        return {"eval/x": np.full(CFG.num_seeds, float(p))}, p == 1

    res = run_training(jax.random.key(0), ToyEnv(), TOY_PARAMS, CFG, run_dir=tmp_path, period_hook=hook)
    assert calls == [0, 1] and len(res.history) == 2
    assert [float(r["eval/x"][0]) for r in res.history] == [0.0, 1.0]
    # the period that stopped training is checkpointed
    assert checkpoint.checkpoint_paths(tmp_path / "checkpoints")[-1].name == "ckpt_000002.msgpack"
