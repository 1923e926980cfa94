"""The CAPS smoothness terms of the PPO loss (temporal and spatial) against hand-worked numbers, their
settings, and the trainer without them left as it was."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from test_train import CFG, TOY_PARAMS, ToyEnv

from harv_jax.errors import UsageError
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo.loss_terms import SpatialSmoothness, TemporalSmoothness, action_change, terms_from_config
from harv_jax.ppo.losses import LossWeights, PPOBatch, PPOLossSettings, ppo_loss
from harv_jax.ppo.networks import gaussian_log_prob, make_ppo_networks
from harv_jax.ppo.train import make_train, seed_keys

N = 6


def _case(seed: int = 0):
    nets = make_ppo_networks(5, 3, (8,), -0.5)
    params = nets.init(jax.random.key(seed))
    rng = np.random.default_rng(seed)
    obs = jnp.asarray(rng.normal(size=(N, 5)), jnp.float32)
    next_obs = obs + jnp.asarray(0.3 * rng.normal(size=(N, 5)), jnp.float32)
    perturbed = obs + jnp.asarray(0.05 * rng.normal(size=(N, 5)), jnp.float32)
    mask = jnp.asarray([1, 1, 0, 1, 1, 0], jnp.float32)
    mean, log_std = nets.policy(params, obs)
    lp = gaussian_log_prob(mean, log_std, mean)
    zeros = jnp.zeros((N,), jnp.float32)
    adv = jnp.arange(N, dtype=jnp.float32)
    batch = PPOBatch(obs, mean, lp, zeros, adv, zeros, ((next_obs, mask), perturbed))
    return nets, params, batch


TERMS = (TemporalSmoothness(1.0), SpatialSmoothness(1.0, 0.05))


def _loss(params, batch, nets, temporal: float, spatial: float, vf_coef: float = 0.0):
    """The PPO loss plus both smoothness terms with these weights (the batch carries both terms' data)."""
    return ppo_loss(
        params, batch, nets, PPOLossSettings(vf_coef=vf_coef), TERMS, LossWeights(None, (temporal, spatial))
    )


def _l1(a, b, w=None):
    d = np.sum(
        np.abs(np.clip(np.asarray(a, np.float64), -1, 1) - np.clip(np.asarray(b, np.float64), -1, 1)), -1
    )
    return float(np.mean(d)) if w is None else float(np.sum(w * d) / np.sum(w))


def test_action_change_is_the_clipped_l1_distance():
    a = jnp.asarray([[0.5, 2.0, -0.2], [0.0, 0.0, 0.0]], jnp.float32)
    b = jnp.asarray([[0.1, 1.5, 0.3], [0.4, -3.0, 0.0]], jnp.float32)
    # row 0: |0.4| + |1 - 1| + |-0.5| = 0.9; row 1: 0.4 + 1 + 0 = 1.4
    np.testing.assert_allclose(float(action_change(a, b)), (0.9 + 1.4) / 2, rtol=1e-6)
    np.testing.assert_allclose(float(action_change(a, b, jnp.asarray([1.0, 0.0]))), 0.9, rtol=1e-6)
    np.testing.assert_allclose(float(action_change(a, b, jnp.asarray([0.0, 0.0]))), 0.0)


def test_smoothness_terms_equal_the_hand_worked_values():
    nets, params, batch = _case()
    mu = nets.policy(params, batch.obs)[0]
    (next_obs, next_mask), perturbed = batch.term_data
    mu_next = nets.policy(params, next_obs)[0]
    mu_pert = nets.policy(params, perturbed)[0]
    temporal = _l1(mu, mu_next, np.asarray(next_mask))
    spatial = _l1(mu, mu_pert)
    total, m = _loss(params, batch, nets, 0.7, 0.3)
    np.testing.assert_allclose(float(m["smooth_temporal_loss"]), temporal, rtol=1e-5)
    np.testing.assert_allclose(float(m["smooth_spatial_loss"]), spatial, rtol=1e-5)
    assert (float(m["smooth_temporal_coef"]), float(m["smooth_spatial_coef"])) == pytest.approx((0.7, 0.3))
    total_plain, m_plain = ppo_loss(params, batch._replace(term_data=()), nets, PPOLossSettings(vf_coef=0.0))
    assert "smooth_temporal_loss" not in m_plain and "smooth_spatial_loss" not in m_plain
    np.testing.assert_allclose(float(total - total_plain), 0.7 * temporal + 0.3 * spatial, rtol=1e-4)


def test_the_temporal_term_ignores_the_step_that_ends_an_episode():
    nets, params, batch = _case(1)
    (next_obs, mask), perturbed = batch.term_data
    far = next_obs.at[2].add(100.0).at[5].add(-100.0)  # rows 2 and 5 are masked
    _, m = _loss(params, batch, nets, 1.0, 0.0, vf_coef=0.5)
    _, m_far = _loss(params, batch._replace(term_data=((far, mask), perturbed)), nets, 1.0, 0.0, vf_coef=0.5)
    np.testing.assert_allclose(
        float(m_far["smooth_temporal_loss"]), float(m["smooth_temporal_loss"]), rtol=1e-6
    )


def test_descending_the_terms_brings_the_actions_together():
    nets, params, batch = _case(2)
    opt = optax.adam(1e-2)
    state = opt.init(params)

    def smooth_only(p):
        _, m = _loss(p, batch, nets, 1.0, 1.0)
        return m["smooth_temporal_loss"] + m["smooth_spatial_loss"]

    @jax.jit
    def step(params, state):
        updates, state = opt.update(jax.grad(smooth_only)(params), state, params)
        return optax.apply_updates(params, updates), state

    start = float(smooth_only(params))
    for _ in range(100):
        params, state = step(params, state)
    assert float(smooth_only(params)) < 0.2 * start


def test_settings_are_checked_and_recorded_only_when_on():
    with pytest.raises(UsageError, match="--smooth-temporal-coef -1.0 must be >= 0"):
        CFG.replace(smooth_temporal_coef=-1.0)
    with pytest.raises(UsageError, match="--smooth-spatial-std 0.0 is outside the allowed"):
        CFG.replace(smooth_spatial_std=0.0)
    with pytest.raises(UsageError, match="--smooth-spatial-coef nan must be a finite number"):
        CFG.replace(smooth_spatial_coef=float("nan"))
    assert "smooth_temporal_coef" not in ppo_config.to_dict(CFG)
    on = ppo_config.to_dict(CFG.replace(smooth_spatial_coef=0.5))
    assert (on["smooth_temporal_coef"], on["smooth_spatial_coef"], on["smooth_spatial_std"]) == (
        0.0,
        0.5,
        0.05,
    )


def _one_period(cfg):
    trainer = make_train(ToyEnv(), cfg, TOY_PARAMS, terms=terms_from_config(cfg))
    state = trainer.init(seed_keys(jax.random.key(3), cfg.num_seeds), TOY_PARAMS)
    return trainer.period(state, TOY_PARAMS)


def test_trainer_without_the_terms_is_unchanged_and_with_them_reports_them():
    base_state, base_metrics = _one_period(CFG)
    # the noise level alone, with both terms off, changes nothing
    off_state, _ = _one_period(dataclasses.replace(CFG, smooth_spatial_std=0.5))
    jax.tree.map(np.testing.assert_array_equal, base_state.params, off_state.params)
    assert "smooth_temporal_loss" not in base_metrics
    assert terms_from_config(CFG) == ()
    on_state, on_metrics = _one_period(CFG.replace(smooth_temporal_coef=0.5, smooth_spatial_coef=0.5))
    for k in ("smooth_temporal_loss", "smooth_spatial_loss"):
        assert np.all(np.isfinite(on_metrics[k])) and np.all(on_metrics[k] > 0), k
    w_base = base_state.params.policy["params"]["mlp"]["out"]["kernel"]
    w_on = on_state.params.policy["params"]["mlp"]["out"]["kernel"]
    assert not np.allclose(w_base, w_on)
