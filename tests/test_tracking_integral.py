"""The tracking-error integral as three more observations: the update by hand, the env, the RL-only and hybrid
controllers, policy files."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_engage_airspeed import _fly_env, _rl_controller_observations

from harv_jax.aircraft import get_aircraft
from harv_jax.control.hybrid import HybridConfig, make_hybrid
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.env import make_env
from harv_jax.env.config import EnvConfig
from harv_jax.policy import export_npz, make_policy
from harv_jax.ppo import normalize
from harv_jax.ppo.networks import make_ppo_networks
from harv_jax.task.spaces import (
    INTEGRAL_OBSERVATION_SIZE,
    OBSERVATION_SIZE,
    ObservationLayout,
    layout_of_size,
    tracking_integral_step,
)

DEG = math.pi / 180.0
N_STEPS = 8
INTEGRAL = ObservationLayout(tracking_integral=True)


def _obs(alpha, beta, mu, gamma, alpha_d=20 * DEG, beta_d=0.0, mu_d=0.0) -> jnp.ndarray:
    return jnp.array([500.0, alpha, beta, 0.0, 0.0, 0.0, mu, gamma, alpha_d, beta_d, mu_d], jnp.float32)


def test_integral_step_by_hand():
    """Errors inside the 5 deg band integrate times dt; outside it, or mu at |gamma| > 45 deg, they do not."""
    z = jnp.zeros(3, jnp.float32)
    got = tracking_integral_step(z, _obs(22 * DEG, -1 * DEG, 3 * DEG, 10 * DEG), 0.01)
    np.testing.assert_allclose(got, [0.02 * DEG, -0.01 * DEG, 0.03 * DEG], rtol=1e-5)
    got = tracking_integral_step(
        z, _obs(26 * DEG, 6 * DEG, 3 * DEG, 50 * DEG), 0.01
    )  # alpha, beta out; mu gated
    np.testing.assert_array_equal(got, [0.0, 0.0, 0.0])
    # mu error wrapped: mu = 179 deg, mu_d = -179 deg is an error of -2 deg
    got = tracking_integral_step(z, _obs(20 * DEG, 0.0, 179 * DEG, 0.0, mu_d=-179 * DEG), 0.5)
    np.testing.assert_allclose(got, [0.0, 0.0, -1.0 * DEG], atol=1e-6)
    # clipped to +-0.5 rad s
    got = tracking_integral_step(jnp.array([0.499, -0.499, 0.0]), _obs(24 * DEG, -4 * DEG, 0.0, 0.0), 1.0)
    np.testing.assert_allclose(got, [0.5, -0.5, 0.0])


def _integrals(obs11: list[np.ndarray], dt_s: float) -> np.ndarray:
    """The integral after each observation, recomputed from the observations in float64."""
    out, acc = [], np.zeros(3)
    for o in obs11:
        d_mu = (o[6] - o[10] + np.pi) % (2 * np.pi) - np.pi
        e = np.array([o[1] - o[8], o[2] - o[9], d_mu], dtype=np.float64)
        active = np.abs(e) < 5 * DEG
        active[2] &= abs(o[7]) <= 45 * DEG
        acc = np.clip(acc + dt_s * np.where(active, e, 0.0), -0.5, 0.5)
        out.append(acc.copy())
    return np.stack(out)


def test_env_appends_the_integral_of_its_observed_error():
    """With the flag the first 11 components are the plain env's (sensor noise on), the last 3 the integral of
    the observed tracking error; a state near the reference makes it move."""
    actions = np.zeros((N_STEPS, 3), np.float32)
    on = EnvConfig(episode_steps=100, observe_tracking_integral=True)
    obs_on, _ = _fly_env(on, actions, 5, 200)
    obs_off, _ = _fly_env(EnvConfig(episode_steps=100), actions, 5, 200)
    assert make_env(on).observation_size == INTEGRAL_OBSERVATION_SIZE
    assert {o.shape for o in obs_on} == {(INTEGRAL_OBSERVATION_SIZE,)}
    for o_on, o_off in zip(obs_on, obs_off, strict=True):
        np.testing.assert_array_equal(o_on[:OBSERVATION_SIZE], o_off)
    want = _integrals(obs_off, on.dt_s)
    np.testing.assert_allclose(np.stack(obs_on)[:, OBSERVATION_SIZE:], want, rtol=0, atol=1e-6)


def test_env_integral_moves_near_the_reference():
    """Started on the reference with a small error, the integral grows as dt * error per step."""
    config = EnvConfig(episode_steps=100, domain_randomization=False, observe_tracking_integral=True)
    env = make_env(config)
    params = env.default_params()
    target = jnp.array([20 * DEG, 0.0, 0.0])
    x0 = jnp.array([600.0, 21 * DEG, 0.5 * DEG, 0.0, 0.0, 0.0, 1 * DEG, 0.0, 0.0, 25000.0])
    obs, state = env.reset_to(jax.random.key(0), x0, target, params)
    np.testing.assert_allclose(obs[OBSERVATION_SIZE:], [0.01 * DEG, 0.005 * DEG, 0.01 * DEG], rtol=1e-4)
    obs, state, *_ = env.step_no_reset(jax.random.key(1), state, jnp.zeros(3), params)
    assert float(obs[OBSERVATION_SIZE]) > 0.015 * DEG  # two steps of ~1 deg


def test_rl_controller_sees_what_the_env_sees():
    """Flown on the env's noise-free states, the controller's 14 observations are the env's, step by step."""
    config = EnvConfig(episode_steps=100, domain_randomization=False, observe_tracking_integral=True)
    actions = np.random.default_rng(2).uniform(-0.2, 0.2, (N_STEPS, 3)).astype(np.float32)
    env_obs, winds = _fly_env(config, actions, 5, 200)
    assert np.any(np.stack(env_obs)[:, OBSERVATION_SIZE:] != 0.0)
    seen = _rl_controller_observations(INTEGRAL, winds, env_obs[0][8:11])
    np.testing.assert_allclose(seen, np.stack(env_obs), rtol=0, atol=1e-6)


def test_hybrid_policy_sees_the_integral():
    seen = []

    def act(obs):
        seen.append(np.asarray(obs))
        return jnp.zeros(3)

    ctrl = make_hybrid(act, HybridConfig(observation=INTEGRAL))
    state = ctrl.init(get_aircraft("harv"))
    ref = jnp.array([20 * DEG, 0.0, 0.0])
    x = jnp.array([600.0, 22 * DEG, 1 * DEG, 0.0, 0.0, 0.0, -1 * DEG, 0.0, 0.0, 25000.0])
    for _ in range(3):
        _, state, _ = ctrl.apply(state, x, ref, jax.random.key(0))
    assert [o.shape for o in seen] == [(INTEGRAL_OBSERVATION_SIZE,)] * 3
    np.testing.assert_allclose(seen[2][OBSERVATION_SIZE:], [0.06 * DEG, 0.03 * DEG, -0.03 * DEG], rtol=1e-4)


def test_a_policy_file_of_14_observations_flies_with_the_integral(tmp_path):
    networks = make_ppo_networks(INTEGRAL_OBSERVATION_SIZE, 3, (8,))
    pol = make_policy(
        networks.init(jax.random.key(0)), normalize.init_stats(INTEGRAL_OBSERVATION_SIZE), networks, meta={}
    )
    path = export_npz(tmp_path / "integral.npz", pol)
    assert layout_of_size(INTEGRAL_OBSERVATION_SIZE) == INTEGRAL
    x = jnp.array([600.0, 21 * DEG, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25000.0])
    ref = jnp.array([20 * DEG, 0.0, 0.0])
    for name in ("rl", "hybrid"):
        ctrl = build_controller(name, ControllerOptions(policy=str(path)))
        state = ctrl.init(get_aircraft("harv"))
        u, state, _ = ctrl.apply(state, x, ref, jax.random.key(0))
        assert bool(jnp.all(jnp.isfinite(u)))
        np.testing.assert_allclose(state.obs_memory.integral_rad_s, [0.01 * DEG, 0.0, 0.0], rtol=1e-4)


def test_both_extensions_at_once_are_refused():
    with pytest.raises(ValueError, match="allowed: one of them or neither"):
        EnvConfig(observe_engage_airspeed=True, observe_tracking_integral=True)
