"""The asymmetric actor-critic: the critic on the true state, the policy behind its measurement path."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cli_util import assert_train_preset_refused

from harv_jax.errors import UsageError
from harv_jax.ppo.config import PPOConfig
from harv_jax.ppo.losses import PPOBatch, PPOLossSettings, ppo_loss
from harv_jax.ppo.networks import gaussian_log_prob, make_ppo_networks
from harv_jax.ppo.train import make_train, seed_keys
from harv_jax.training.environment import make_harv_env
from harv_jax.training.measured_env import true_observation
from harv_jax.training.spec import TrainSpec

M, OBS, ACT = 12, 11, 3
TABLE = {"episode_steps": 40, "domain_randomization": True, "measurement_path": "lp2"}


def test_the_loss_evaluates_the_critic_on_its_own_observation():
    """By hand: the value loss is 0.5 vf (target - V(critic_obs))^2; the policy terms are those of the
    symmetric loss (they see ``obs`` only), and the critic's gradient follows ``critic_obs``."""
    nets = make_ppo_networks(OBS, ACT, hidden_sizes=(8,))
    params = nets.init(jax.random.key(0))
    rng = np.random.default_rng(0)
    obs, critic_obs = (jnp.asarray(rng.normal(size=(M, OBS)), jnp.float32) for _ in range(2))
    raw = jnp.asarray(rng.normal(size=(M, ACT)), jnp.float32)
    mean, log_std = nets.policy(params, obs)
    target = jnp.asarray(rng.normal(size=(M,)), jnp.float32)
    batch = PPOBatch(
        obs, raw, gaussian_log_prob(mean, log_std, raw), target * 0, target, target, critic_obs=critic_obs
    )
    settings = PPOLossSettings(vf_coef=0.7)
    _, m_asym = ppo_loss(params, batch, nets, settings)
    _, m_sym = ppo_loss(params, batch._replace(critic_obs=None), nets, settings)
    by_hand = 0.5 * 0.7 * np.mean((np.asarray(target) - np.asarray(nets.value(params, critic_obs))) ** 2)
    np.testing.assert_allclose(float(m_asym["value_loss"]), by_hand, rtol=1e-5)
    assert abs(float(m_sym["value_loss"]) - by_hand) > 1e-3  # the symmetric loss sees obs instead
    np.testing.assert_allclose(float(m_asym["policy_loss"]), float(m_sym["policy_loss"]), rtol=1e-6)
    g_asym = jax.grad(lambda p: ppo_loss(p, batch, nets, settings)[0])(params)
    g_hand = jax.grad(lambda p: 0.5 * 0.7 * jnp.mean((target - nets.value(p, critic_obs)) ** 2))(params)
    for a, b in zip(jax.tree.leaves(g_asym.value), jax.tree.leaves(g_hand.value), strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-4, atol=1e-7)


def test_the_privileged_critic_sees_the_true_state():
    """The measured env offers the critic the noise-free observation of the true state (the policy sees the
    sensors through the path) and records it for the episode that just ended."""
    env, params = make_harv_env(TABLE | {"critic": "privileged"})
    symmetric, _ = make_harv_env(TABLE)
    assert symmetric.critic_observation is None
    n = 8

    def run(st, k):
        obs, st, _, done, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
            jax.random.split(k, n), st, jnp.zeros((n, 3)), params
        )
        return st, (obs, jax.vmap(env.critic_observation)(st), done, info["final_critic_obs"])

    @jax.jit
    def fly():
        _, st = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(jax.random.key(3), n), params)
        first = (jax.vmap(env.critic_observation)(st), jax.vmap(true_observation)(st))
        return first, jax.lax.scan(run, st, jax.random.split(jax.random.key(4), 45))[1]

    (first_critic, first_true), (obs, critic, done, final) = fly()
    np.testing.assert_array_equal(np.asarray(first_critic), np.asarray(first_true))
    obs, critic, done, final = map(np.asarray, (obs, critic, done, final))
    assert obs.shape == critic.shape and np.isfinite(critic).all()
    # the sensors' noise and the filter separate what the two see; the targets (last 3) are shared
    assert np.abs(obs[..., 3:6] - critic[..., 3:6]).mean() > 1e-3
    np.testing.assert_array_equal(obs[..., -3:], critic[..., -3:])
    assert done.any()  # the 40-step episodes end inside the scan (an auto-reset)
    t, i = np.argwhere(done)[0]
    # where an episode ended, the critic's final observation is the finished episode's, not the new one's
    assert not np.allclose(final[t, i], critic[t, i])
    running = ~done
    np.testing.assert_allclose(final[running], critic[running], rtol=1e-6, atol=1e-6)


@pytest.mark.slow  # ~1 min: two compiled periods
def test_a_period_trains_the_critic_on_the_true_state():
    """A compiled period with the privileged critic: same policy draws as the symmetric run (the rollout's
    actions do not depend on the critic), a different value function."""
    cfg = PPOConfig(total_steps=2048, num_envs=16, unroll=16, minibatches=2, epochs=1, hidden_sizes=(16,))
    out = {}
    for critic in ("actor", "privileged"):
        spec = TrainSpec.from_settings("t", cfg, TABLE | {"critic": critic})
        env, params = make_harv_env(spec)
        trainer = make_train(env, cfg, params)
        state = trainer.init(seed_keys(jax.random.key(0), cfg.num_seeds), params)
        state, metrics = trainer.period(state, params)
        out[critic] = (state, metrics)
    (_, m_a), (_, m_p) = out["actor"], out["privileged"]
    losses = ("total_loss", "policy_loss", "value_loss", "grad_norm")  # no episode ends in this period
    assert all(np.isfinite(np.asarray(m_p[k])).all() for k in losses)
    np.testing.assert_array_equal(np.asarray(m_a["reward_mean"]), np.asarray(m_p["reward_mean"]))
    assert not np.allclose(np.asarray(m_a["value_loss"]), np.asarray(m_p["value_loss"]))


def test_the_critic_setting_is_checked(tmp_path, monkeypatch, capsys):
    with pytest.raises(UsageError, match="allowed: actor, privileged"):
        TrainSpec.from_settings("t", PPOConfig(), TABLE | {"critic": "oracle"})
    spec = TrainSpec.from_settings("t", PPOConfig(), TABLE | {"critic": "privileged"})
    assert spec.env_settings()["critic"] == "privileged"
    assert "critic" not in TrainSpec.from_settings("t", PPOConfig(), TABLE).env_settings()
    for env, message in (
        ('critic = "privileged"', '[env] critic "privileged" sees the true state behind a measurement path'),
        ('measurement_path = "lp2"\ncritic = true', "[env] critic True; allowed: actor, privileged"),
    ):
        assert_train_preset_refused(tmp_path, monkeypatch, capsys, env, message)
