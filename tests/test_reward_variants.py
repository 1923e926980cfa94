"""Our reward terms (smooth bands, dense per-channel terms, recovered bonus, action rate, alpha weighting by
speed, excess speed) by hand, the paper's reward kept bit for bit at the defaults, and the preset tables that
set them."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.env import reward, settings
from harv_jax.env.reward_params import paper_reward_params, reward_fields
from harv_jax.errors import UsageError

W = paper_reward_params()


def _paper_total(x, target, action, pot_prev, terminated, w):
    """The paper's reward as written before our terms existed (reference for the bit-for-bit test)."""
    pqr = x[3:6]
    errors = reward.tracking_errors(x, target)
    e_alpha = errors[0]
    eps = reward.blend(jnp.sqrt(reward.omega_norm_sq(pqr)), w)
    r_raw = (1.0 - eps) * reward.phase1(pqr, w) + eps * reward.phase2(e_alpha, pqr, w)
    inside = jnp.abs(errors) < w.bonus_tol_rad
    amounts = jnp.stack([w.bonus_alpha, w.bonus_beta, w.bonus_mu])
    bonus = jnp.where(inside, amounts, jnp.zeros_like(amounts))
    r_action = -w.action_weight * jnp.sum(action * action)
    pot_next = reward.potential(e_alpha, pqr, w)
    r_shaping = w.shaping_weight * (w.discount * jnp.where(terminated, 0.0, pot_next) - pot_prev)
    performance = r_raw + jnp.sum(bonus) + r_action
    return jnp.where(terminated, w.terminal_reward, performance) + r_shaping


def _random_steps(n, seed=0):
    rng = np.random.default_rng(seed)
    x = np.zeros((n, 10), np.float32)
    x[:, 0] = rng.uniform(100, 1500, n)
    x[:, 1] = rng.uniform(-0.2, 1.2, n)
    x[:, 2] = rng.normal(0, 0.05, n)
    x[:, 3:6] = rng.normal(0, 0.5, (n, 3)) * (rng.uniform(size=(n, 1)) < 0.7)
    x[:, 6] = rng.uniform(-np.pi, np.pi, n)
    near = rng.uniform(size=n) < 0.3  # a third of the states inside the bonus bands
    x[near, 1] = 0.349 + rng.uniform(-0.02, 0.02, near.sum())
    x[near, 2] = rng.uniform(-0.02, 0.02, near.sum())
    x[near, 6] = rng.uniform(-0.02, 0.02, near.sum())
    target = np.tile(np.array([0.349, 0.0, 0.0], np.float32), (n, 1))
    a = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
    a_prev = rng.uniform(-1, 1, (n, 3)).astype(np.float32)
    pot = rng.uniform(-3, 0, n).astype(np.float32)
    term = rng.uniform(size=n) < 0.1
    return tuple(map(jnp.asarray, (x, target, a, pot, term, a_prev)))


def test_paper_reward_bit_for_bit():
    """At the paper's parameters the total equals the paper-only formula exactly (float32, jitted)."""
    x, target, a, pot, term, a_prev = _random_steps(4096)
    ours = jax.jit(jax.vmap(lambda *z: reward.reward_terms(*z, W)[0].total))(x, target, a, pot, term)
    ref = jax.jit(jax.vmap(lambda *z: _paper_total(*z, W)))(x, target, a, pot, term)
    assert np.asarray(ours).tobytes() == np.asarray(ref).tobytes()
    for name in ("dense_alpha", "dense_beta", "dense_mu", "recovered"):
        terms = jax.vmap(lambda *z: reward.reward_terms(*z[:5], W)[0])(x, target, a, pot, term)
        assert np.all(np.asarray(getattr(terms, name)) == 0.0), name


def test_terms_raw_is_reward_raw():
    """The step's r_raw is ``reward.raw`` (raw_weight included), bit for bit."""
    w = W.replace(raw_weight=jnp.asarray(0.5, jnp.float32))
    x, target, a, pot, term, _ = _random_steps(512)
    terms, _ = jax.jit(jax.vmap(lambda *z: reward.reward_terms(*z, w)))(x, target, a, pot, term)
    e_alpha = jax.vmap(reward.tracking_errors)(x, target)[:, 0]
    raw = jax.jit(jax.vmap(lambda p, e: reward.raw(p, e, w)))(x[:, 3:6], e_alpha)
    np.testing.assert_array_equal(terms.raw, jnp.where(term, 0.0, raw))


def test_every_reward_field_declares_default_range_meaning():
    """Each field's default lies in its declared range, with the declared length; the presets' ranges are
    these."""
    for f in reward_fields():
        lo, hi = f.metadata["range"]
        default = f.metadata["default"]
        n = len(default) if isinstance(default, tuple) else None
        assert f.metadata["meaning"], f.name
        assert all(lo <= v <= hi for v in np.atleast_1d(default)), f.name
        assert settings.REWARD_RANGES[f.name] == (lo, hi, n)


def test_paper_presets_have_no_reward_table():
    from harv_jax.training.presets import load_preset

    for name in ("paper-partial", "paper-full"):
        _, env = load_preset(name)
        assert "reward" not in env and "spin" not in env, name


def test_smooth_bonus_by_hand():
    # e = [0.0873, 0, -0.1746] rad with widths 0.0873: exp(-1) = 0.36788, exp(0) = 1, exp(-4) = 0.018316
    # bonuses 5 * 0.36788 = 1.8394, 3 * 1 = 3, 3 * 0.018316 = 0.054947
    w = W.replace(bonus_shape=jnp.asarray(1.0), bonus_width_rad=jnp.full((3,), 0.0873))
    b = reward.bonuses(jnp.asarray([0.0873, 0.0, -0.1746]), w)
    np.testing.assert_allclose(b, [1.8394, 3.0, 0.054947], rtol=1e-4)


def test_dense_tracking_by_hand():
    # w = [2, 1, 3], clip = [0.5, 0.5, pi]; e = [0.25, -1.0, -pi/2]
    # alpha: -2 * 0.25/0.5 = -1; beta: -1 * min(2, 1) = -1; mu: -3 * (pi/2)/pi = -1.5
    w = W.replace(w_track=jnp.asarray([2.0, 1.0, 3.0]), track_clip_rad=jnp.asarray([0.5, 0.5, math.pi]))
    d = reward.dense_tracking(jnp.asarray([0.25, -1.0, -math.pi / 2]), w)
    np.testing.assert_allclose(d, [-1.0, -1.0, -1.5], rtol=1e-6)


def test_recovered_term_by_hand():
    # tolerances 2 deg, 1 deg, 2 deg (0.0349, 0.01745, 0.0349 rad), 0.17 rad/s
    w = W.replace(recovered_bonus=jnp.asarray(4.0))
    # ||(0.1, 0.1, 0.1)|| = sqrt(0.03) = 0.1732 > 0.17: not recovered
    assert float(reward.recovered_term(jnp.asarray([0.03, -0.017, 0.03]), jnp.full((3,), 0.1), w)) == 0.0
    ok = reward.recovered_term(jnp.asarray([0.03, -0.017, 0.03]), jnp.asarray([0.1, 0.1, 0.0]), w)
    assert float(ok) == 4.0  # ||(0.1, 0.1, 0)|| = 0.1414 < 0.17
    assert (
        float(reward.recovered_term(jnp.asarray([0.03, 0.018, 0.03]), jnp.zeros(3), w)) == 0.0
    )  # beta > 1 deg
    assert (
        float(reward.recovered_term(jnp.asarray([0.03, 0.0, 0.0]), jnp.asarray([0.0, 0.0, 0.18]), w)) == 0.0
    )


def test_total_adds_our_terms():
    x, target, a, pot, term, a_prev = _random_steps(512, seed=1)
    w = W.replace(bonus_shape=jnp.asarray(1.0), bonus_width_rad=jnp.full((3,), 0.0873),
                  w_track=jnp.asarray([1.0, 2.0, 3.0]), recovered_bonus=jnp.asarray(5.0),
                  alpha_v_lo_fps=jnp.asarray(450.0), alpha_v_hi_fps=jnp.asarray(600.0))  # fmt: skip
    t = jax.vmap(lambda *z: reward.reward_terms(*z, w)[0])(x, target, a, pot, term)
    perf = (t.raw + t.bonus_alpha + t.bonus_beta + t.bonus_mu + t.action + t.dense_alpha + t.dense_beta
            + t.dense_mu + t.recovered)  # fmt: skip
    expect = np.where(np.asarray(term), np.asarray(t.terminal), np.asarray(perf)) + np.asarray(t.shaping)
    np.testing.assert_allclose(t.total, expect, rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize(
    "table, message",
    [
        ({"reward": {"w_track": [1.0, 2.0]}}, "reward.w_track"),
        ({"reward": {"w_track": [1.0, -2.0, 0.0]}}, "reward.w_track[1] = -2.0 is outside"),
        ({"reward": {"bonus_shape": 2}}, "reward.bonus_shape = 2 is outside the allowed range [0, 1]"),
        ({"reward": {"recovered_bonus": float("nan")}}, "reward.recovered_bonus"),
        ({"reward": {"bogus": 1}}, "unknown [reward] setting 'bogus'"),
        (
            {"reward": {"alpha_brake_rad": 2.0}},
            "reward.alpha_brake_rad = 2.0 is outside the allowed range [-0.5, 1.5]",
        ),
        ({"reward": {"alpha_v_hi_fps": 2e6}}, "reward.alpha_v_hi_fps = 2000000.0 is outside"),
        ({"spin": {"reset_prob": 1.5}}, "spin.reset_prob = 1.5 is outside the allowed range [0, 1]"),
        ({"spin": {"bank_size": 0}}, "spin.bank_size = 0 is outside"),
        ({"spin": {"spin_s_min": 20.0, "spin_s_max": 10.0}}, "spin.spin_s_max = 10.0 is outside"),
        ({"spin": {"mix": 0.2}}, "unknown [spin] setting 'mix'"),
        ({"randomization": {"gust_on": 1}}, "randomization.gust_on = 1 must be true or false"),
        ({"randomization": {"mass_frac": 0.9}}, "randomization.mass_frac = 0.9 is outside"),
        ({"eval": {"every": -1}}, "eval.every = -1 must be a non-negative integer"),
    ],
)
def test_bad_tables_one_line(table, message):
    from harv_jax.training.environment import make_harv_env

    with pytest.raises(UsageError) as e:
        make_harv_env({"episode_steps": 100, "domain_randomization": False, **table})
    assert message in str(e.value)
    assert "\n" not in str(e.value)


def test_tables_set_traced_params():
    env_table = {"episode_steps": 100, "domain_randomization": True,
                 "reward": {"w_track": [1.0, 2.0, 3.0], "recovered_bonus": 5.0},
                 "randomization": {"gust_on": False, "mass_frac": 0.2}}  # fmt: skip
    flat, nested = settings.split_tables(env_table)
    p = settings.env_params(settings.env_config(flat), nested)
    np.testing.assert_array_equal(p.reward.w_track, [1.0, 2.0, 3.0])
    assert float(p.reward.recovered_bonus) == 5.0
    assert not bool(p.randomization.gust_on) and bool(p.randomization.mass_on)
    np.testing.assert_allclose(p.randomization.mass_frac, 0.2)
    assert p.reward.w_track.dtype == jnp.float32 and not p.reward.w_track.weak_type


def test_mu_weight_by_hand():
    # lo = 45 deg, hi = 60 deg: |gamma| = 30 deg -> 1; 75 deg -> 0; 52.5 deg (t = 0.5) -> 1 - 0.5 = 0.5;
    # 48.75 deg (t = 0.25): smoothstep = 3(0.0625) - 2(0.015625) = 0.15625 -> 0.84375
    w = W.replace(
        mu_gamma_lo_rad=jnp.asarray(math.radians(45.0)), mu_gamma_hi_rad=jnp.asarray(math.radians(60.0))
    )
    got = [float(reward.mu_weight(jnp.asarray(math.radians(g)), w)) for g in (30.0, -75.0, 52.5, -48.75)]
    np.testing.assert_allclose(got, [1.0, 0.0, 0.5, 0.84375], rtol=1e-5, atol=1e-6)
    assert float(reward.mu_weight(jnp.asarray(1.5), W)) == 1.0  # the paper's settings: no weighting


def test_alpha_weight_by_hand():
    # lo = 450, hi = 600 ft/s: V = 300 -> 1; 700 -> 0; 525 (t = 0.5) -> 0.5; 487.5 (t = 0.25) -> 0.84375
    w = W.replace(alpha_v_lo_fps=jnp.asarray(450.0), alpha_v_hi_fps=jnp.asarray(600.0))
    got = [float(reward.alpha_weight(jnp.asarray(v), w)) for v in (300.0, 700.0, 525.0, 487.5)]
    np.testing.assert_allclose(got, [1.0, 0.0, 0.5, 0.84375], rtol=1e-5, atol=1e-6)
    assert float(reward.alpha_weight(jnp.asarray(1500.0), W)) == 1.0  # the paper's settings: no weighting


def test_alpha_terms_weighted_out_when_fast():
    """At V = 700 ft/s with alpha_v_hi 600 the alpha bonus and dense term are 0; at 300 ft/s they are paid."""
    w = W.replace(bonus_shape=jnp.asarray(1.0), bonus_width_rad=jnp.full((3,), 0.0873),
                  w_track=jnp.asarray([4.0, 3.0, 3.0]), alpha_v_lo_fps=jnp.asarray(450.0),
                  alpha_v_hi_fps=jnp.asarray(600.0))  # fmt: skip
    target = jnp.asarray([0.349, 0.0, 0.0])
    a = jnp.zeros(3)
    for v, paid in ((700.0, False), (300.0, True)):
        x = jnp.zeros(10).at[0].set(v).at[1].set(0.349 + 0.25)  # e_alpha = 0.25 rad
        t = reward.reward_terms(x, target, a, jnp.asarray(0.0), jnp.asarray(False), w)[0]
        # dense_alpha = -4 * 0.25/0.5 = -2; bonus_alpha = 5 exp(-(0.25/0.0873)^2) = 5 * 2.74e-4 = 1.37e-3
        np.testing.assert_allclose(float(t.dense_alpha), -2.0 if paid else 0.0, rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(float(t.bonus_alpha), 1.37e-3 if paid else 0.0, rtol=1e-2, atol=1e-7)


def test_alpha_brake_target_by_hand():
    """alpha_brake_on: the alpha terms track w alpha_d + (1 - w) alpha_brake, w the speed weight; the
    recovered term still uses the true alpha_d."""
    w = W.replace(w_track=jnp.asarray([4.0, 3.0, 3.0]), alpha_v_lo_fps=jnp.asarray(450.0),
                  alpha_v_hi_fps=jnp.asarray(600.0), alpha_brake_on=jnp.asarray(1.0),
                  alpha_brake_rad=jnp.asarray(1.0), recovered_bonus=jnp.asarray(5.0))  # fmt: skip
    target = jnp.asarray([0.349, 0.0, 0.0])
    a = jnp.zeros(3)

    def step(v, alpha):
        x = jnp.zeros(10).at[0].set(v).at[1].set(alpha)
        return reward.reward_terms(x, target, a, jnp.asarray(0.0), jnp.asarray(False), w)[0]

    # V = 700 (w = 0): ref 1.0 rad; alpha 0.75 -> -4 * 0.25/0.5 = -2; alpha 1.0 -> 0 and bonus 5
    np.testing.assert_allclose(float(step(700.0, 0.75).dense_alpha), -2.0, rtol=1e-5)
    np.testing.assert_allclose(float(step(700.0, 1.0).dense_alpha), 0.0, atol=1e-6)
    assert float(step(700.0, 1.0).bonus_alpha) == 5.0  # the paper's indicator: 5 [|e| < 0.017]
    # V = 525 (w = 0.5): ref 0.5 * 0.349 + 0.5 * 1.0 = 0.6745; alpha 0.4245 -> -4 * 0.25/0.5 = -2
    np.testing.assert_allclose(float(step(525.0, 0.4245).dense_alpha), -2.0, rtol=1e-4)
    # V = 300 (w = 1): ref alpha_d; at alpha_d the recovered term is paid (omega 0, beta = mu = 0)
    t = step(300.0, 0.349)
    np.testing.assert_allclose(float(t.dense_alpha), 0.0, atol=1e-6)
    assert float(t.recovered) == 5.0
    assert float(step(700.0, 1.0).recovered) == 0.0  # on the braking ref but 37 deg off alpha_d


def test_cli_bad_reward_table_exit_2(monkeypatch, capsys, tmp_path):
    """A [spin] mix out of range in a preset: one line naming the key and the range, exit 2, no run folder."""
    from cli_util import cli_run

    from harv_jax.training.presets import preset_path

    text = preset_path("smoke").read_text() + "\n[spin]\nreset_prob = 1.5\n"
    preset = tmp_path / "bad.toml"
    preset.write_text(text)
    code, _, err = cli_run(monkeypatch, capsys, "train", "--preset", preset, "--out", tmp_path / "run")
    assert code == 2
    expected = "preset bad.toml: spin.reset_prob = 1.5 is outside the allowed range [0, 1]"
    assert err.strip() == f"harv-jax: error: {expected}"
    assert not (tmp_path / "run").exists()


def test_fast_preset_is_recovery_plus_braking():
    """The fast preset is the recovery preset with energy braking in the reward and nothing else (so the
    experiments/fast_policy ablation is a reward ablation); its tables build valid traced params."""
    from harv_jax.training.presets import load_preset

    ppo_f, env_f = load_preset("fast")
    ppo_r, env_r = load_preset("recovery")
    assert ppo_f == ppo_r
    assert {k: v for k, v in env_f.items() if k != "reward"} == {
        k: v for k, v in env_r.items() if k != "reward"
    }
    changed = {
        k for k in env_f["reward"] | env_r["reward"] if env_f["reward"].get(k) != env_r["reward"].get(k)
    }
    assert changed == {
        "track_clip_rad",
        "alpha_brake_on",
        "alpha_brake_rad",
        "alpha_v_lo_fps",
        "alpha_v_hi_fps",
    }
    flat, nested = settings.split_tables(env_f)
    p = settings.env_params(settings.env_config(flat), {**nested, "spin": {}})
    assert float(p.reward.alpha_brake_on) == 1.0 and float(p.reward.alpha_v_hi_fps) == 550.0
