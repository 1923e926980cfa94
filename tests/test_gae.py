"""GAE on a hand-worked example with a truncation and a termination; bootstrapping rules; brax parity."""

from __future__ import annotations

import chex
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.ppo.losses import compute_gae, successor_values

# One env (B = 1), T = 4 steps, gamma = 0.5, lambda = 0.5 (so gamma * lambda = 0.25).
# Step 0: ordinary. Step 1: the episode is TRUNCATED (time limit); V(final_obs_1) = 100.
# Step 2: first step of the next episode. Step 3: that episode TERMINATES (left the envelope).
GAMMA, LAM = 0.5, 0.5
REWARDS = [1.0, 2.0, 3.0, 4.0]
VALUES = [10.0, 20.0, 30.0, 40.0]  # V(obs_t); obs_2 is the reset observation of the new episode
TERM = [0.0, 0.0, 0.0, 1.0]
TRUNC = [0.0, 1.0, 0.0, 0.0]
FINAL_V = [-5.0, 100.0, -5.0, 999.0]  # V(final_obs_t); used only where the episode ended
LAST_V = 77.0  # V(obs_4), after the rollout; obs_4 belongs to a third episode (step 3 terminated)

# successor values: t0 -> V(obs_1) = 20; t1 (truncated) -> V(final_obs_1) = 100;
# t2 -> V(obs_3) = 40; t3 (terminated) -> V(final_obs_3) = 999 (multiplied by 1 - term = 0 below).
NEXT_V = [20.0, 100.0, 40.0, 999.0]
# delta_t = r_t + gamma (1 - term_t) next_t - V_t:
#   d0 = 1 + 0.5 * 20 - 10 = 1
#   d1 = 2 + 0.5 * 100 - 20 = 32      (truncation bootstraps from V(final_obs))
#   d2 = 3 + 0.5 * 40 - 30 = -7
#   d3 = 4 + 0 - 40 = -36             (termination: no bootstrap)
# A_t = d_t + gamma lambda (1 - done_t) A_{t+1}, done = term or trunc:
#   A3 = -36
#   A2 = -7 + 0.25 * (-36) = -16
#   A1 = 32                            (done_1: the new episode's advantages do not leak back)
#   A0 = 1 + 0.25 * 32 = 9
# targets = A + V = [19, 52, 14, 4]
EXPECTED_ADV = [9.0, 32.0, -16.0, -36.0]
EXPECTED_TARGET = [19.0, 52.0, 14.0, 4.0]


def _col(x):
    return jnp.asarray(x, jnp.float32)[:, None]  # [T, 1]


def test_successor_values_hand_example():
    nv = successor_values(_col(VALUES), jnp.asarray([LAST_V]), _col(FINAL_V), _col(TERM), _col(TRUNC))
    chex.assert_shape(nv, (4, 1))
    np.testing.assert_allclose(nv[:, 0], NEXT_V)


def test_gae_hand_example():
    adv, target = compute_gae(_col(REWARDS), _col(VALUES), _col(NEXT_V), _col(TERM), _col(TRUNC), GAMMA, LAM)
    chex.assert_shape((adv, target), (4, 1))
    np.testing.assert_allclose(adv[:, 0], EXPECTED_ADV, rtol=1e-6)
    np.testing.assert_allclose(target[:, 0], EXPECTED_TARGET, rtol=1e-6)


def test_truncation_bootstraps_termination_does_not():
    base = compute_gae(_col(REWARDS), _col(VALUES), _col(NEXT_V), _col(TERM), _col(TRUNC), GAMMA, LAM)[0]
    # Changing V(final_obs) of the TRUNCATED step changes A1 by gamma * dV and A0 by gamma^2 lambda dV.
    nv = np.array(NEXT_V)
    nv[1] += 8.0
    adv = compute_gae(_col(REWARDS), _col(VALUES), _col(nv), _col(TERM), _col(TRUNC), GAMMA, LAM)[0]
    np.testing.assert_allclose(adv[:, 0] - base[:, 0], [0.25 * 4.0, 4.0, 0.0, 0.0], rtol=1e-6)
    # Changing the successor value of the TERMINATED step changes nothing.
    nv = np.array(NEXT_V)
    nv[3] = -1e6
    adv = compute_gae(_col(REWARDS), _col(VALUES), _col(nv), _col(TERM), _col(TRUNC), GAMMA, LAM)[0]
    np.testing.assert_allclose(adv, base)


def test_gae_lambda_zero_is_td_error_and_batches_are_independent():
    rng = np.random.default_rng(0)
    t, b = 6, 3
    r, v, nv = (jnp.asarray(rng.normal(size=(t, b)), jnp.float32) for _ in range(3))
    term = jnp.asarray(rng.random((t, b)) < 0.2, jnp.float32)
    trunc = jnp.asarray(rng.random((t, b)) < 0.2, jnp.float32) * (1 - term)
    adv, _ = compute_gae(r, v, nv, term, trunc, 0.9, 0.0)
    np.testing.assert_allclose(adv, r + 0.9 * (1 - term) * nv - v, rtol=1e-5, atol=1e-6)
    adv_all, _ = compute_gae(r, v, nv, term, trunc, 0.9, 0.8)
    adv_one, _ = compute_gae(r[:, 1:2], v[:, 1:2], nv[:, 1:2], term[:, 1:2], trunc[:, 1:2], 0.9, 0.8)
    np.testing.assert_allclose(adv_all[:, 1:2], adv_one, rtol=1e-6)


def test_matches_brax_gae_when_lambda_one_and_no_truncation():
    """Brax's advantage is r + gamma vs_{t+1} - V (V-trace form): equal to GAE at lambda = 1."""
    pytest.importorskip("brax")
    from brax.training.agents.ppo.losses import compute_gae as brax_gae

    rng = np.random.default_rng(1)
    t, b = 8, 4
    r, v = (jnp.asarray(rng.normal(size=(t, b)), jnp.float32) for _ in range(2))
    boot = jnp.asarray(rng.normal(size=(b,)), jnp.float32)
    term = jnp.asarray(rng.random((t, b)) < 0.15, jnp.float32)
    trunc = jnp.zeros((t, b), jnp.float32)
    # without auto-reset bookkeeping brax bootstraps from values[t+1] (and boot at the end)
    nv = jnp.concatenate([v[1:], boot[None]], axis=0)
    adv, target = compute_gae(r, v, nv, term, trunc, 0.97, 1.0)
    vs, adv_brax = brax_gae(trunc, term, r, v, boot, lambda_=1.0, discount=0.97)
    np.testing.assert_allclose(adv, adv_brax, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(target, vs, rtol=1e-5, atol=1e-5)
