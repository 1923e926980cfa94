"""Our PPO loss equals brax's ``compute_ppo_loss`` on the same batch and parameters (values and gradients)."""

from __future__ import annotations

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.ppo.losses import PPOBatch, PPOLossSettings, ppo_loss
from harv_jax.ppo.networks import gaussian_entropy, gaussian_log_prob, make_ppo_networks

T, B, OBS, ACT = 5, 6, 11, 3


def _make_case(seed: int):
    """Random params (log_std moved off its init) and a random [B, T] batch with truncations/terminations."""
    nets = make_ppo_networks(OBS, ACT, hidden_sizes=(16, 8), init_log_std=-0.5)
    params = nets.init(jax.random.key(seed))
    params = params._replace(
        policy=jax.tree.map(lambda x: x, params.policy)
        | {"params": params.policy["params"] | {"log_std": jnp.asarray([-0.3, -0.6, 0.1], jnp.float32)}}
    )
    rng = np.random.default_rng(seed)
    obs = jnp.asarray(rng.normal(size=(B, T, OBS)), jnp.float32)
    next_obs = jnp.asarray(rng.normal(size=(B, T, OBS)), jnp.float32)
    raw_action = jnp.asarray(rng.normal(size=(B, T, ACT)) * 0.7, jnp.float32)
    # behaviour log-probs: the current policy's, perturbed so that ratios spread across the clip range
    mean, log_std = nets.policy(params, obs)
    behaviour = gaussian_log_prob(mean, log_std, raw_action) + jnp.asarray(rng.normal(size=(B, T)) * 0.3)
    reward = jnp.asarray(rng.normal(size=(B, T)), jnp.float32)
    done = jnp.asarray(rng.random((B, T)) < 0.2, jnp.float32)
    trunc = done * jnp.asarray(rng.random((B, T)) < 0.5, jnp.float32)
    old_value = nets.value(params, obs) + jnp.asarray(rng.normal(size=(B, T)) * 0.2, jnp.float32)
    return nets, params, obs, next_obs, raw_action, behaviour, reward, done, trunc, old_value


def _brax_setup(nets):
    from brax.training import distribution
    from brax.training import networks as brax_networks
    from brax.training.agents.ppo import networks as ppo_networks

    def policy_apply(_normalizer, policy_params, obs):
        mean, log_std = nets.actor.apply(policy_params, obs)
        return (mean, jnp.exp(log_std))  # NormalDistribution.create_dist(*parameters) -> (loc, scale)

    def value_apply(_normalizer, value_params, obs):
        return nets.critic.apply(value_params, obs)

    return ppo_networks.PPONetworks(
        policy_network=brax_networks.FeedForwardNetwork(init=None, apply=policy_apply),
        value_network=brax_networks.FeedForwardNetwork(init=None, apply=value_apply),
        parametric_action_distribution=distribution.NormalDistribution(event_size=ACT),
    )


@pytest.mark.parametrize(("clip_value_eps", "ent_coef"), [(None, 0.0), (0.1, 0.01)])
def test_loss_and_grads_match_brax(clip_value_eps, ent_coef):
    pytest.importorskip("brax")
    from brax.training import types
    from brax.training.agents.ppo import losses as brax_losses

    gamma, lam, clip_eps, vf_coef = 0.97, 0.9, 0.2, 0.5
    nets, params, obs, next_obs, raw_action, behaviour, reward, done, trunc, old_value = _make_case(0)
    brax_nets = _brax_setup(nets)
    mean_b, log_std_b = nets.policy(params, obs)
    data = types.Transition(
        observation=obs,
        action=jnp.clip(raw_action, -1, 1),
        reward=reward,
        discount=1.0 - done,
        next_observation=next_obs,
        extras={
            "state_extras": {"truncation": trunc},
            "policy_extras": {
                "raw_action": raw_action,
                "log_prob": behaviour,
                "value": old_value,
                "distribution_params": (mean_b, jnp.exp(log_std_b)),
            },
        },
    )

    def brax_loss(p):
        bp = brax_losses.PPONetworkParams(policy=p.policy, value=p.value)
        return brax_losses.compute_ppo_loss(
            bp, None, data, jax.random.key(1), brax_nets, entropy_cost=ent_coef, discounting=gamma,
            reward_scaling=1.0, gae_lambda=lam, clipping_epsilon=clip_eps, normalize_advantage=True,
            vf_coefficient=vf_coef, clipping_epsilon_value=clip_value_eps,
        )  # fmt: skip

    def our_loss(p):
        # Same advantages and value targets as brax computes inside its loss (its GAE, its bootstrap).
        tm = lambda x: jnp.swapaxes(x, 0, 1)  # noqa: E731  [B, T] -> [T, B]
        values = nets.value(p, tm(obs))
        bootstrap = nets.value(p, tm(next_obs)[-1])
        termination = tm(done) * (1 - tm(trunc))
        vs, adv = brax_losses.compute_gae(tm(trunc), termination, tm(reward), values, bootstrap, lam, gamma)
        flat = lambda x: tm(x).reshape((T * B,) + x.shape[2:])  # noqa: E731
        batch = PPOBatch(flat(obs), flat(raw_action), flat(behaviour), flat(old_value),
                         adv.reshape(-1), vs.reshape(-1))  # fmt: skip
        settings = PPOLossSettings(clip_eps, vf_coef, ent_coef, clip_value_eps, normalize_advantage=True)
        return ppo_loss(p, batch, nets, settings)

    (l_b, m_b), g_b = jax.jit(jax.value_and_grad(brax_loss, has_aux=True))(params)
    (l_o, m_o), g_o = jax.jit(jax.value_and_grad(our_loss, has_aux=True))(params)
    # the case is not degenerate: some ratios are clipped, the loss is not tiny
    assert 0.05 < float(m_o["clip_fraction"]) < 0.95
    np.testing.assert_allclose(l_o, l_b, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(m_o["policy_loss"], m_b["policy_loss"], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(m_o["value_loss"], m_b["v_loss"], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(-ent_coef * m_o["entropy"], m_b["entropy_loss"], rtol=1e-5, atol=1e-7)
    chex.assert_trees_all_close(g_o, g_b, rtol=1e-4, atol=1e-6)


def test_gaussian_helpers_match_closed_form():
    mean = jnp.asarray([[0.1, -0.2, 0.3]])
    log_std = jnp.asarray([[-0.5, 0.0, 0.2]])
    x = jnp.asarray([[0.4, 0.0, -1.0]])
    std = np.exp(np.asarray(log_std))
    expected = np.sum(
        -0.5 * ((np.asarray(x) - np.asarray(mean)) / std) ** 2 - np.log(std * np.sqrt(2 * np.pi))
    )
    np.testing.assert_allclose(gaussian_log_prob(mean, log_std, x), [expected], rtol=1e-6)
    entropy = np.sum(0.5 + 0.5 * np.log(2 * np.pi) + np.asarray(log_std))
    np.testing.assert_allclose(gaussian_entropy(log_std), [entropy], rtol=1e-6)


@pytest.mark.parametrize("seeds", [None, 2])
def test_feature_major_forward_equals_flax(seeds):
    """``policy_and_value`` (feature-major, hand-written VJP; used by the loss) equals the flax modules'
    ``policy``/``value``: outputs and gradients, at the paper's widths, on 3-d inputs, under vmap."""
    nets = make_ppo_networks(OBS, ACT, hidden_sizes=(256, 128))
    keys = jax.random.split(jax.random.key(3), seeds or 1)
    params = nets.init_seeds(keys)  # = jax.vmap(nets.init)(keys) bit for bit (test_no_batched_lapack)
    obs = jax.random.normal(jax.random.key(4), (seeds or 1, 7, 9, OBS), jnp.float32)
    w = jax.random.normal(jax.random.key(5), (7, 9, 2 * ACT + 1), jnp.float32)

    def flax_path(p, o):
        mean, log_std = nets.policy(p, o)
        return mean, log_std, nets.value(p, o)

    def scalar(fn):
        def f(p, o):
            mean, log_std, value = fn(p, o)
            weighted = jnp.sum(w[..., :ACT] * mean) + jnp.sum(w[..., ACT:-1] * log_std)
            return weighted + jnp.sum(w[..., -1] * value)

        return jax.value_and_grad(f)

    def run(fn):
        if seeds is None:
            take = lambda x: x[0]  # noqa: E731
            return fn(jax.tree.map(take, params), obs[0])
        return jax.vmap(fn)(params, obs)

    jrun = jax.jit(run, static_argnums=0)
    out_fm, out_flax = jrun(nets.policy_and_value), jrun(flax_path)
    chex.assert_trees_all_close(out_fm, out_flax, rtol=1e-5, atol=1e-6)
    (v_fm, g_fm), (v_flax, g_flax) = jrun(scalar(nets.policy_and_value)), jrun(scalar(flax_path))
    np.testing.assert_allclose(v_fm, v_flax, rtol=1e-5)
    chex.assert_trees_all_close(g_fm, g_flax, rtol=1e-4, atol=1e-5)
