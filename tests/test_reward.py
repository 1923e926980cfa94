"""Reward terms of the recovery env against hand-worked values (paper Section IV-A)."""

from __future__ import annotations

import math

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from absl.testing import parameterized

from harv_jax.env import reward
from harv_jax.env.config import paper_reward_params

W = paper_reward_params()  # w_p1 = 0.3, w_p21 = 0.3, w_p22 = 0.05, k = 10, omega_th = 0.17, Gamma = 0.99


class TermsTest(chex.TestCase):
    @chex.variants(with_jit=True, without_jit=True)
    def test_phase1(self):
        # pqr = [1, 2, -3]: ||w||^2 = 1 + 4 + 9 = 14
        # coupling = |1*2| + |2*-3| + |1*-3| = 2 + 6 + 3 = 11
        # r1 = -14 - 0.3 * 11 = -17.3
        f = self.variant(reward.phase1)
        np.testing.assert_allclose(f(jnp.array([1.0, 2.0, -3.0]), W), -17.3, rtol=1e-6)

    @chex.variants(with_jit=True, without_jit=True)
    def test_phase2(self):
        # e_alpha = 0.1, pqr = [0.2, -0.1, 0.05]
        # ||w||^2 = 0.04 + 0.01 + 0.0025 = 0.0525
        # coupling = |0.2*-0.1| + |-0.1*0.05| + |0.2*0.05| = 0.02 + 0.005 + 0.01 = 0.035
        # r2 = -0.1^2 - 0.3 * 0.1 * (-0.1) - 0.05 * (0.0525 + 0.035)
        #    = -0.01 + 0.003 - 0.004375 = -0.011375
        f = self.variant(reward.phase2)
        np.testing.assert_allclose(f(jnp.array(0.1), jnp.array([0.2, -0.1, 0.05]), W), -0.011375, rtol=1e-5)

    @chex.variants(with_jit=True, without_jit=True)
    def test_blend_values(self):
        f = self.variant(reward.blend)
        # at the threshold: 1 / (1 + exp(0)) = 0.5
        np.testing.assert_allclose(f(jnp.array(0.17), W), 0.5, rtol=1e-6)
        # at rest: 1 / (1 + exp(10 * (0 - 0.17))) = 1 / (1 + exp(-1.7)) = 1 / 1.182684 = 0.845535
        np.testing.assert_allclose(f(jnp.array(0.0), W), 0.8455347, rtol=1e-6)
        # one rad/s above the threshold: 1 / (1 + exp(10)) = 4.53979e-5
        np.testing.assert_allclose(f(jnp.array(1.17), W), 4.539787e-5, rtol=1e-4)

    @chex.variants(with_jit=True, without_jit=True)
    def test_blend_limits(self):
        f = self.variant(reward.blend)
        w = jnp.linspace(0.0, 40.0, 401)
        eps = f(w, W)
        chex.assert_tree_all_finite(eps)
        assert jnp.all(jnp.diff(eps) <= 0), "eps must not increase with the rate norm"
        assert jnp.all((eps >= 0) & (eps <= 1))
        # ||w|| -> large: phase 1 only (no overflow in exp(k * 40))
        assert float(f(jnp.array(40.0), W)) < 1e-30
        # a steep gate (k -> inf) is the paper's hard switch: 1 below omega_th, 0 above
        steep = W.replace(k_blend=jnp.array(1e4))
        assert float(f(jnp.array(0.16), steep)) == pytest.approx(1.0, abs=1e-6)
        assert float(f(jnp.array(0.18), steep)) == pytest.approx(0.0, abs=1e-6)

    @chex.variants(with_jit=True, without_jit=True)
    def test_raw_is_phase1_or_phase2_at_the_blend_limits(self):
        f = self.variant(reward.raw)
        steep = W.replace(k_blend=jnp.array(1e4))
        slow, e_alpha = jnp.array([0.05, -0.02, 0.01]), jnp.array(0.2)
        fast = jnp.array([1.0, 2.0, -3.0])
        np.testing.assert_allclose(f(slow, e_alpha, steep), reward.phase2(e_alpha, slow, steep), rtol=1e-6)
        np.testing.assert_allclose(f(fast, e_alpha, steep), reward.phase1(fast, steep), rtol=1e-6)

    @chex.variants(with_jit=True, without_jit=True)
    def test_bonuses(self):
        f = self.variant(reward.bonuses)
        # |e| < 0.017 rad pays: alpha 0.01 -> +5; beta -0.02 -> 0; mu 0.0169 -> +3
        np.testing.assert_array_equal(f(jnp.array([0.01, -0.02, 0.0169]), W), [5.0, 0.0, 3.0])
        # strict inequality: exactly 0.017 does not pay
        np.testing.assert_array_equal(f(jnp.array([0.017, 0.0, -0.017]), W), [0.0, 3.0, 0.0])

    @chex.variants(with_jit=True, without_jit=True)
    def test_action_penalty(self):
        # -(0.5^2 + 1^2 + 0.2^2) = -(0.25 + 1 + 0.04) = -1.29
        f = self.variant(reward.action_penalty)
        np.testing.assert_allclose(f(jnp.array([0.5, -1.0, 0.2]), W), -1.29, rtol=1e-6)

    @chex.variants(with_jit=True, without_jit=True)
    def test_potential_and_shaping(self):
        # sigma = -0.2^2 - 0.3 * 14 = -0.04 - 4.2 = -4.24
        pot = self.variant(reward.potential)
        np.testing.assert_allclose(pot(jnp.array(0.2), jnp.array([1.0, 2.0, -3.0]), W), -4.24, rtol=1e-6)
        # 0.99 * (-1) - (-2) = 1.01
        sh = self.variant(reward.shaping)
        np.testing.assert_allclose(sh(jnp.array(-1.0), jnp.array(-2.0), W), 1.01, rtol=1e-6)

    def test_mu_error_wraps(self):
        # mu = 3.1, mu_d = -3.1: 6.2 rad is -0.0831853 rad the short way round (6.2 - 2 pi)
        x = jnp.zeros(10).at[6].set(3.1)
        e = reward.tracking_errors(x, jnp.array([0.0, 0.0, -3.1]))
        np.testing.assert_allclose(e[2], 6.2 - 2 * math.pi, atol=1e-5)


def _state(alpha, beta, pqr, mu):
    return jnp.array([500.0, alpha, beta, pqr[0], pqr[1], pqr[2], mu, 0.0, 0.0, 25000.0])


class RewardTermsTest(chex.TestCase):
    @chex.variants(with_jit=True, without_jit=True)
    def test_total_non_terminal(self):
        # alpha 0.30, target 0.29 -> e_alpha = 0.01; beta 0.01 -> e_beta = 0.01; mu 0.005 -> e_mu = 0.005
        # pqr = [0.05, -0.02, 0.01]: ||w||^2 = 0.0025 + 0.0004 + 0.0001 = 0.003, ||w|| = 0.0547723
        # coupling = 0.001 + 0.0002 + 0.0005 = 0.0017
        # r1 = -0.003 - 0.3 * 0.0017 = -0.00351
        # r2 = -0.0001 - 0.3 * 0.01 * (-0.02) - 0.05 * (0.003 + 0.0017) = -0.0001 + 0.00006 - 0.000235
        #    = -0.000275
        # eps = 1 / (1 + exp(10 * (0.0547723 - 0.17))) = 1 / (1 + exp(-1.152277)) = 0.7599267
        # raw = 0.2400733 * (-0.00351) + 0.7599267 * (-0.000275) = -0.00105164
        # bonuses: all three errors < 0.017 -> 5 + 3 + 3 = 11
        # action [0.1, 0, -0.2] -> -(0.01 + 0.04) = -0.05
        # sigma_next = -0.01^2 - 0.3 * 0.003 = -0.001; sigma_prev = -0.5
        # shaping = 0.99 * (-0.001) + 0.5 = 0.49901
        # total = -0.00105164 + 11 - 0.05 + 0.49901 = 11.44795836
        f = self.variant(reward.reward_terms)
        x = _state(0.30, 0.01, (0.05, -0.02, 0.01), 0.005)
        terms, pot = f(x, jnp.array([0.29, 0.0, 0.0]), jnp.array([0.1, 0.0, -0.2]), jnp.array(-0.5),
                       jnp.array(False), W)  # fmt: skip
        np.testing.assert_allclose(terms.phase1, -0.00351, rtol=1e-4)
        np.testing.assert_allclose(terms.phase2, -0.000275, rtol=1e-3)
        np.testing.assert_allclose(terms.blend, 0.7599267, rtol=1e-5)
        np.testing.assert_allclose(terms.raw, -0.00105164, rtol=1e-3)
        np.testing.assert_array_equal([terms.bonus_alpha, terms.bonus_beta, terms.bonus_mu], [5.0, 3.0, 3.0])
        np.testing.assert_allclose(terms.action, -0.05, rtol=1e-5)
        np.testing.assert_allclose(pot, -0.001, rtol=1e-3)
        np.testing.assert_allclose(terms.shaping, 0.49901, rtol=1e-5)
        assert float(terms.terminal) == 0.0
        np.testing.assert_allclose(terms.total, 11.44795836, rtol=1e-6)

    @chex.variants(with_jit=True, without_jit=True)
    def test_terminal_step(self):
        # terminating step: sigma(absorbing) = 0, so total = -1000 + (0.99 * 0 - sigma_prev)
        # = -1000 + 0.5 = -999.5, whatever the (here non-finite) state; performance terms read 0
        f = self.variant(reward.reward_terms)
        x = jnp.full((10,), jnp.nan)
        terms, _ = f(x, jnp.array([0.29, 0.0, 0.0]), jnp.array([1.0, 1.0, 1.0]), jnp.array(-0.5),
                     jnp.array(True), W)  # fmt: skip
        np.testing.assert_allclose(terms.total, -999.5, rtol=1e-7)
        np.testing.assert_allclose(terms.shaping, 0.5, rtol=1e-7)
        assert float(terms.terminal) == -1000.0
        for name in ("phase1", "phase2", "blend", "raw", "bonus_alpha", "bonus_beta", "bonus_mu", "action"):
            assert float(getattr(terms, name)) == 0.0, name

    def test_shaping_weight_zero_disables_pbrs(self):
        x = _state(0.30, 0.01, (0.05, -0.02, 0.01), 0.005)
        args = (x, jnp.array([0.29, 0.0, 0.0]), jnp.zeros(3), jnp.array(-0.5), jnp.array(False))
        on, _ = reward.reward_terms(*args, W)
        off, _ = reward.reward_terms(*args, W.replace(shaping_weight=jnp.array(0.0)))
        assert float(off.shaping) == 0.0
        np.testing.assert_allclose(off.total, on.total - on.shaping, rtol=1e-6)


def test_pbrs_telescopes(x64):
    """sum_t Gamma^t (Gamma sigma_{t+1} - sigma_t) = Gamma^T sigma_T - sigma_0 for any sequence."""
    rng = np.random.default_rng(0)
    sig = jnp.asarray(rng.uniform(-5.0, 0.0, size=101))
    w = paper_reward_params(dtype=jnp.float64)
    shaped = jax.vmap(reward.shaping, in_axes=(0, 0, None))(sig[1:], sig[:-1], w)
    disc = w.discount ** jnp.arange(100)
    np.testing.assert_allclose(jnp.sum(disc * shaped), w.discount**100 * sig[100] - sig[0], rtol=1e-12)


@pytest.mark.parametrize("gamma", [0.9, 0.99, 1.0])
def test_pbrs_telescopes_to_minus_sigma0_on_termination(x64, gamma):
    """With sigma(absorbing) = 0 the discounted shaping of a terminated episode sums to -sigma_0."""
    w = paper_reward_params(discount=gamma, dtype=jnp.float64)
    rng = np.random.default_rng(1)
    sig = rng.uniform(-5.0, 0.0, size=11)  # sigma_0..sigma_10; the step from sigma_9 terminates
    total = 0.0
    for t in range(10):
        x = jnp.zeros(10).at[1].set(jnp.sqrt(-sig[t + 1]))  # e_alpha^2 = -sigma_{t+1}, rates 0
        terms, _ = reward.reward_terms(
            x, jnp.zeros(3), jnp.zeros(3), jnp.asarray(sig[t]), jnp.asarray(t == 9), w
        )
        total += gamma**t * float(terms.shaping)
    assert total == pytest.approx(-sig[0], rel=1e-10)


class VmapTest(parameterized.TestCase):
    def test_reward_terms_vmap(self):
        xs = jnp.stack([_state(0.3, 0.0, (0.1, 0.0, 0.0), 0.0), _state(0.5, 0.1, (1.0, 2.0, 3.0), 1.0)])
        f = jax.vmap(reward.reward_terms, in_axes=(0, None, None, None, None, None))
        terms, pot = f(xs, jnp.zeros(3), jnp.zeros(3), jnp.array(-1.0), jnp.array(False), W)
        chex.assert_shape([terms.total, pot], (2,))
        chex.assert_tree_all_finite(terms)
