"""The engagement airspeed as a 12th observation: env, RL-only and hybrid controllers, policy files."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.aircraft import get_aircraft
from harv_jax.control.hybrid import HybridConfig, make_hybrid
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.control.rl import make_rl_controller
from harv_jax.env import make_env
from harv_jax.env.config import EnvConfig
from harv_jax.errors import UsageError
from harv_jax.policy import export_npz, make_policy
from harv_jax.ppo import normalize
from harv_jax.ppo.networks import make_ppo_networks
from harv_jax.task.spaces import (
    ENGAGE_OBSERVATION_SIZE,
    OBSERVATION_SIZE,
    ObservationLayout,
    layout_of_size,
    observation,
)

N_STEPS = 6


def _fly_env(
    config: EnvConfig, actions: np.ndarray, reset_key: int = 3, step_key: int = 100
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Observations and wind states of one episode flown with ``actions`` (same keys for every config:
    ``reset_key`` for the reset, ``step_key + i`` for step i)."""
    env = make_env(config)
    params = env.default_params()
    step = jax.jit(env.step_no_reset)
    obs, state = jax.jit(env.reset)(jax.random.key(reset_key), params)
    seen, winds = [np.asarray(obs)], [np.asarray(state.wind)]
    for i, a in enumerate(actions):
        obs, state, *_ = step(jax.random.key(step_key + i), state, jnp.asarray(a), params)
        seen.append(np.asarray(obs))
        winds.append(np.asarray(state.wind))
    return seen, winds


def _rl_controller_observations(
    layout: ObservationLayout, winds: list[np.ndarray], target: np.ndarray
) -> np.ndarray:
    """The observations the RL-only controller of ``layout`` hands its policy, flown on ``winds`` in order."""
    seen = []

    def act(obs):
        seen.append(np.asarray(obs))
        return jnp.zeros(3)

    ctrl = make_rl_controller(act, layout=layout)
    state = ctrl.init(get_aircraft("harv"))
    for x in winds:
        _, state, _ = ctrl.apply(state, jnp.asarray(x), jnp.asarray(target), jax.random.key(0))
    return np.stack(seen)


@pytest.fixture(scope="module")
def flights():
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, (N_STEPS, 3)).astype(np.float32)
    on = EnvConfig(episode_steps=100, observe_engage_airspeed=True)
    off = EnvConfig(episode_steps=100)
    return actions, _fly_env(on, actions), _fly_env(off, actions)


def test_env_appends_the_airspeed_of_the_first_observation(flights):
    """With the flag the first 11 components are the plain env's (sensor noise included: domain
    randomization is on), and the 12th is the first observation's noisy airspeed, held."""
    _, (obs_on, _), (obs_off, _) = flights
    assert make_env(EnvConfig(observe_engage_airspeed=True)).observation_size == ENGAGE_OBSERVATION_SIZE
    assert make_env(EnvConfig()).observation_size == OBSERVATION_SIZE
    v_first = obs_off[0][0]
    assert {o.shape for o in obs_on} == {(ENGAGE_OBSERVATION_SIZE,)}
    for o_on, o_off in zip(obs_on, obs_off, strict=True):
        np.testing.assert_array_equal(o_on[:OBSERVATION_SIZE], o_off)
        assert o_on[-1] == v_first
    assert len({float(o[0]) for o in obs_on}) > 1  # the airspeed moved; its first value is what is held


def test_rl_controller_sees_what_the_env_sees():
    """Flown on the env's (noise-free) states, the controller's observations are the env's, step by step."""
    config = EnvConfig(episode_steps=100, domain_randomization=False, observe_engage_airspeed=True)
    actions = np.random.default_rng(1).uniform(-1.0, 1.0, (N_STEPS, 3)).astype(np.float32)
    env_obs, winds = _fly_env(config, actions)
    seen = _rl_controller_observations(ObservationLayout(engage_airspeed=True), winds, env_obs[0][8:11])
    np.testing.assert_allclose(seen, np.stack(env_obs), rtol=0, atol=1e-6)


def test_hybrid_policy_sees_the_engagement_airspeed():
    seen = []

    def act(obs):
        seen.append(np.asarray(obs))
        return jnp.zeros(3)

    ctrl = make_hybrid(act, HybridConfig(observation=ObservationLayout(engage_airspeed=True)))
    state = ctrl.init(get_aircraft("harv"))
    ref = jnp.array([0.349, 0.0, 0.0])
    x = jnp.array([900.0, 0.3, 0.05, 0.1, -0.2, 0.3, 0.4, -0.1, 0.0, 25000.0])
    for v in (900.0, 640.0, 420.0):
        _, state, _ = ctrl.apply(state, x.at[0].set(v), ref, jax.random.key(0))
    assert [o.shape for o in seen] == [(ENGAGE_OBSERVATION_SIZE,)] * 3
    assert [float(o[0]) for o in seen] == [900.0, 640.0, 420.0]
    assert [float(o[-1]) for o in seen] == [900.0] * 3
    np.testing.assert_array_equal(seen[1][:OBSERVATION_SIZE], observation(x.at[0].set(640.0), ref))


def _write_policy(path, obs_size: int):
    networks = make_ppo_networks(obs_size, 3, (8,))
    params = networks.init(jax.random.key(0))
    pol = make_policy(params, normalize.init_stats(obs_size), networks, meta={"source": "test"})
    return export_npz(path, pol)


def test_a_policy_file_of_12_observations_flies_with_the_engagement_airspeed(tmp_path):
    path = _write_policy(tmp_path / "engage.npz", ENGAGE_OBSERVATION_SIZE)
    params = get_aircraft("harv")
    x = jnp.array([700.0, 0.3, 0.05, 0.1, -0.2, 0.3, 0.4, -0.1, 0.0, 25000.0])
    ref = jnp.array([0.349, 0.0, 0.0])
    for name in ("rl", "hybrid"):
        ctrl = build_controller(name, ControllerOptions(policy=str(path)))
        state = ctrl.init(params)
        u, state, _ = ctrl.apply(state, x, ref, jax.random.key(0))
        assert bool(jnp.all(jnp.isfinite(u)))
        assert float(state.obs_memory.v_engage_fps) == 700.0 and bool(state.obs_memory.engaged)


def test_a_policy_of_another_size_is_refused_in_one_line(tmp_path):
    path = _write_policy(tmp_path / "thirteen.npz", 13)
    with pytest.raises(UsageError) as e:
        build_controller("rl", ControllerOptions(policy=str(path)))
    assert "13 observations" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(ValueError, match="13 observations"):
        layout_of_size(13)
    assert layout_of_size(11) == ObservationLayout()
    assert layout_of_size(12) == ObservationLayout(engage_airspeed=True)
