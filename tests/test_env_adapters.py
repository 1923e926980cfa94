"""brax and gymnasium adapters of the recovery env (skipped where the framework is not installed)."""

from __future__ import annotations

import subprocess
import sys
import warnings

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.env import EnvConfig, default_params
from harv_jax.task.spaces import OBS_HIGH, OBS_LOW

#: Tests compile with XLA's backend optimizations off: a third of the compile time, same semantics.
COMPILER_OPTIONS = {"xla_backend_optimization_level": 0}
LEVEL = np.array([600.0, 0.089, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25000.0], dtype=np.float32)


# ---------------------------------------------------------------------------------------------- brax


@pytest.fixture(scope="module")
def brax_training():
    pytest.importorskip("brax")
    from brax.envs.wrappers import training

    return training


def test_brax_wrappers_run_100_steps(brax_training):
    from harv_jax.env.brax_env import HarvBraxEnv

    n, episode_length = 16, 30
    # V_max lowered to 1000 ft/s: resets drawn at V0 > 1000 terminate on their first step, so one
    # compiled env shows both terminations and the EpisodeWrapper's truncations
    params = default_params()
    params = params.replace(envelope=params.envelope.replace(v_max_fps=jnp.float32(1000.0)))
    base = HarvBraxEnv(EnvConfig(episode_steps=episode_length), params)
    env = brax_training.wrap(base, episode_length=episode_length)  # Vmap -> Episode -> AutoReset
    assert (env.observation_size, env.action_size) == (11, 3)
    state = jax.jit(env.reset, compiler_options=COMPILER_OPTIONS)(jax.random.split(jax.random.PRNGKey(0), n))
    first_mass = np.asarray(state.pipeline_state.episode.aircraft.mass_slug)

    def body(state, action):
        sigma_prev = state.pipeline_state.potential
        state = env.step(state, action)
        out = {
            "obs": state.obs,
            "reward": state.reward,
            "done": state.done,
            "trunc": state.info["truncation"],
            "steps": state.info["steps"],
            "sigma_prev": sigma_prev,
            "terminated": sum(v for k, v in state.metrics.items() if k.startswith("term/")) > 0,
            "finite": jax.tree.reduce(
                lambda a, b: a & b, jax.tree.map(lambda x: jnp.all(jnp.isfinite(x)), state.pipeline_state)
            ),
        }
        return state, out

    # 100 steps of brax's training stack in one scan (one compile, one host transfer)
    actions = jax.random.uniform(jax.random.PRNGKey(1), (100, n, 3), minval=-1.0, maxval=1.0)
    run = jax.jit(lambda s, a: jax.lax.scan(body, s, a), compiler_options=COMPILER_OPTIONS)
    state, out = run(state, actions)
    out = jax.device_get(out)
    chex.assert_shape(out["obs"], (100, n, 11))
    chex.assert_shape([out["reward"], out["done"], out["trunc"]], (100, n))
    assert np.all(out["finite"]) and np.all(np.isfinite(out["obs"])) and np.all(np.isfinite(out["reward"]))
    assert np.all(out["obs"] >= OBS_LOW) and np.all(out["obs"] <= OBS_HIGH)
    # the EpisodeWrapper's time limit is a truncation, unless the env terminated on that step
    terminated, at_limit = out["terminated"], out["steps"] >= episode_length
    np.testing.assert_array_equal(out["trunc"], (at_limit & ~terminated).astype(np.float32))
    np.testing.assert_array_equal(out["done"], (at_limit | terminated).astype(np.float32))
    # a termination pays -1000 plus the shaping to the absorbing state's zero potential: -sigma_t
    np.testing.assert_allclose(out["reward"][terminated], -1000.0 - out["sigma_prev"][terminated], rtol=1e-6)
    n_term, n_trunc = int(terminated.sum()), int(out["trunc"].sum())
    assert n_term > 0 and n_trunc > 0, (n_term, n_trunc)
    # every reward term is a metric, accumulated per episode by the EpisodeWrapper
    assert {"reward/total", "reward/shaping", "reward/raw", "term/nonfinite"} <= set(state.metrics)
    assert "reward/total" in state.info["episode_metrics"]
    # AutoResetWrapper starts new episodes with fresh draws, not the first episode's aircraft
    # (every slot has finished at least 3 episodes: 100 steps, episodes <= 30 steps)
    assert np.all(np.asarray(state.pipeline_state.episode.aircraft.mass_slug) != first_mass)


# ----------------------------------------------------------------------------------------- gymnasium


@pytest.fixture(scope="module")
def gym_env():
    pytest.importorskip("gymnasium")
    from harv_jax.env.gym_env import HarvRecoveryEnv

    return HarvRecoveryEnv(EnvConfig(episode_steps=5), compiler_options=COMPILER_OPTIONS)


def test_gymnasium_check_env_passes(gym_env):
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(gym_env, skip_render_check=True)
    assert not [w for w in caught if "gymnasium" in str(w.filename) or "WARN" in str(w.message)], [
        str(w.message) for w in caught
    ]


def test_gymnasium_seeding_and_spaces(gym_env):
    obs_a, _ = gym_env.reset(seed=7)
    obs_b, _ = gym_env.reset(seed=7)
    obs_c, _ = gym_env.reset(seed=8)
    np.testing.assert_array_equal(obs_a, obs_b)
    assert not np.array_equal(obs_a, obs_c)
    assert obs_a.dtype == np.float32 and gym_env.observation_space.contains(obs_a)
    obs_d, _ = gym_env.reset()  # unseeded resets continue the stream: a new episode
    assert not np.array_equal(obs_c, obs_d)


def test_gymnasium_truncation_and_termination(gym_env):
    # from level flight the 5-step time limit truncates (not terminates)
    obs, _ = gym_env.reset(seed=0, options={"wind_state": LEVEL})
    assert abs(obs[0] - 600.0) < 3.0 and abs(obs[1] - 0.089) < 0.02 and obs[9] == 0.0  # sensor noise on
    np.testing.assert_allclose(obs[8], 0.349, rtol=1e-6)  # default target alpha_d = 20 deg
    flags = []
    for _ in range(5):
        obs, rew, terminated, truncated, info = gym_env.step(np.zeros(3, dtype=np.float32))
        assert isinstance(rew, float) and np.isfinite(rew)
        flags.append((terminated, truncated))
    assert flags == [(False, False)] * 4 + [(False, True)]
    assert info["episode_step"] == 5 and info["reward/terminal"] == 0.0
    # alpha 1.65 rad > 1.571: the first step terminates, reward -1000 - sigma_0
    x = LEVEL.copy()
    x[:2] = [300.0, 1.65]
    gym_env.reset(seed=0, options={"wind_state": x, "target_rad": [0.2, 0.0, 0.0]})
    sigma0 = float(gym_env.env_state.potential)
    np.testing.assert_allclose(sigma0, -((1.65 - 0.2) ** 2), rtol=1e-5)  # rates 0
    obs, rew, terminated, truncated, info = gym_env.step(np.zeros(3, dtype=np.float32))
    assert terminated and not truncated and info["term/alpha"]
    np.testing.assert_allclose(rew, -1000.0 - sigma0, rtol=1e-6)
    assert np.all(np.isfinite(obs)) and gym_env.observation_space.contains(obs)
    with pytest.raises(ValueError, match="unknown reset options"):
        gym_env.reset(options={"state": LEVEL})


def test_gymnasium_make():
    gym = pytest.importorskip("gymnasium")
    from harv_jax.env import gym_env as module

    env = gym.make(module.GYM_ID, config=EnvConfig(episode_steps=5))
    assert isinstance(env.unwrapped, module.HarvRecoveryEnv)
    env.close()


def test_core_env_needs_neither_brax_nor_gymnasium():
    """The core imports and builds with brax and gymnasium made unimportable (fresh interpreter)."""
    code = (
        "import sys\n"
        "sys.modules['brax'] = None; sys.modules['gymnasium'] = None\n"
        "import harv_jax.env as e\n"
        "env = e.make_env(e.EnvConfig()); p = env.default_params()\n"
        "assert env.observation_size == 11 and env.action_size == 3\n"
        "try:\n"
        "    import harv_jax.env.brax_env\n"
        "except ImportError:\n"
        "    print('brax adapter: ImportError')\n"
        "try:\n"
        "    import harv_jax.env.gym_env\n"
        "except ImportError:\n"
        "    print('gym adapter: ImportError')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "brax adapter: ImportError" in out.stdout and "gym adapter: ImportError" in out.stdout
