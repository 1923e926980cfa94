"""A single-env ``gymnasium.Env`` adapter of the recovery environment (numpy in, numpy out).

Import this module only where gymnasium is installed; the core package does not import it. Importing
it registers ``GYM_ID`` ("harv_jax/HarvRecovery-v0") with gymnasium.

- ``reset(seed=...)`` seeds gymnasium's ``np_random``, which draws the JAX key of the episode; the same
  seed gives the same episode (initial state, target, randomized aircraft, gust and noise streams).
  ``reset(options={"wind_state": x[10], "target_rad": t[3]})`` starts at a given state and target.
- ``step`` returns the gymnasium 5-tuple; ``terminated`` is the envelope exit (reward -1000 - sigma_t),
  ``truncated`` the time limit ``EnvConfig.episode_steps``. The env does not reset itself: after either
  flag, call ``reset``. ``info`` holds every reward term (``reward/<term>``, float), the termination
  causes (``term/<cause>``, bool) and ``episode_step``; ``env_state`` is the core ``EnvState``.
- One jitted JAX call per ``step`` (compiled on first use), with the env state passed as one flat
  vector; observations are float32 in the paper's observation box, actions float32 in [-1, 1]^3.
"""

from __future__ import annotations

import functools
from typing import Any

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from harv_jax.env.config import EnvConfig, EnvParams
from harv_jax.env.recovery import EnvState, make_env
from harv_jax.env.reward import RewardTerms
from harv_jax.env.termination import TerminationFlags
from harv_jax.task.spaces import ACTION_SIZE, OBS_HIGH, OBS_LOW
from harv_jax.task.spec import ALPHA_TARGET_RAD, BETA_TARGET_RAD, MU_TARGET_RAD

_SEED_HIGH = 2**31 - 1
#: Default target of ``reset(options={"wind_state": ...})``: alpha_d = 20 deg (the paper's Monte Carlo
#: target, ``task.spec.ALPHA_TARGET_RAD``), beta_d = mu_d = 0.
DEFAULT_EVAL_TARGET_RAD = (ALPHA_TARGET_RAD, BETA_TARGET_RAD, MU_TARGET_RAD)


class HarvRecoveryEnv(gym.Env):
    """F-18/HARV spin/upset recovery (paper Section IV-A) as a gymnasium environment."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        config: EnvConfig | None = None,
        params: EnvParams | None = None,
        compiler_options: dict[str, Any] | None = None,
    ):
        """Build the adapter.

        Args:
            config: static env config (default ``EnvConfig()``).
            params: traced env parameters (default ``default_params(config)``).
            compiler_options: optional XLA options for the adapter's jitted functions (e.g.
                ``{"xla_backend_optimization_level": 0}`` compiles faster and runs slower).
        """
        super().__init__()
        core = make_env(config)
        self._config = core.config
        self._params = params if params is not None else core.default_params()
        low, high = OBS_LOW, OBS_HIGH
        self._n_obs = core.observation_size
        self.observation_space = gym.spaces.Box(low=low, high=high, dtype=np.float32)
        self.action_space = gym.spaces.Box(low=-1.0, high=1.0, shape=(ACTION_SIZE,), dtype=np.float32)
        self._state = None
        self._key = None

        # The jitted functions take and return the env state as one flat vector and the PRNG key as raw
        # key data: a few arrays per call instead of ~30 pytree leaves (dispatch cost dominates here).
        template = jax.eval_shape(core.reset, jax.random.key(0), self._params)[1]
        _, unravel = ravel_pytree(jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), template))

        def _reset(key_data):
            k_reset, k_stream = jax.random.split(jax.random.wrap_key_data(key_data))
            obs, state = core.reset(k_reset, self._params)
            return jax.random.key_data(k_stream), obs, ravel_pytree(state)[0]

        def _reset_to(key_data, x_wind, target_rad):
            k_reset, k_stream = jax.random.split(jax.random.wrap_key_data(key_data))
            obs, state = core.reset_to(k_reset, x_wind, target_rad, self._params)
            return jax.random.key_data(k_stream), obs, ravel_pytree(state)[0]

        def _step(key_data, flat_state, action):
            key, k_step = jax.random.split(jax.random.wrap_key_data(key_data))
            obs, state, reward, terminated, truncated, info = core.step_no_reset(
                k_step, unravel(flat_state), action, self._params
            )
            scalars = [reward, terminated, truncated, info["episode_step"]]
            scalars += list(info["reward_terms"].values()) + list(info["termination"].values())
            # one packed host transfer per step instead of one per value
            packed = jnp.concatenate([obs, jnp.stack([jnp.asarray(v, obs.dtype) for v in scalars])])
            return jax.random.key_data(key), ravel_pytree(state)[0], packed

        self._info_names = tuple(f"reward/{k}" for k in RewardTerms._fields) + tuple(
            f"term/{k}" for k in TerminationFlags._fields
        )
        self._unravel = unravel
        jit = functools.partial(jax.jit, compiler_options=compiler_options)
        self._reset_fn = jit(_reset)
        self._reset_to_fn = jit(_reset_to)
        self._step_fn = jit(_step)

    @property
    def config(self) -> EnvConfig:
        return self._config

    @property
    def params(self) -> EnvParams:
        return self._params

    @property
    def env_state(self) -> EnvState | None:
        """The current core ``EnvState`` (None before the first reset)."""
        return None if self._state is None else self._unravel(self._state)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode: (obs float32 [11], info {}).

        Args:
            seed: seeds ``np_random``, which draws the episode's JAX key.
            options: optional ``{"wind_state": [10], "target_rad": [3]}`` to start at a given
                wind-axis state [V, alpha, beta, p, q, r, mu, gamma, chi, h] (ft/s, rad, rad/s, ft) and
                target [alpha_d, beta_d, mu_d] (default ``DEFAULT_EVAL_TARGET_RAD``, the paper's 20 deg);
                without it the state and target are drawn from the reset bounds.
        """
        super().reset(seed=seed)
        key_data = jax.random.key_data(jax.random.key(int(self.np_random.integers(0, _SEED_HIGH))))
        options = options or {}
        unknown = set(options) - {"wind_state", "target_rad"}
        if unknown:
            raise ValueError(f"unknown reset options {sorted(unknown)}; allowed: wind_state, target_rad")
        if "wind_state" in options:
            x = np.asarray(options["wind_state"], dtype=np.float32).reshape(10)
            target = np.asarray(options.get("target_rad", DEFAULT_EVAL_TARGET_RAD), dtype=np.float32).reshape(
                3
            )
            self._key, obs, self._state = self._reset_to_fn(key_data, x, target)
        elif "target_rad" in options:
            raise ValueError("reset option target_rad needs wind_state as well")
        else:
            self._key, obs, self._state = self._reset_fn(key_data)
        return np.array(obs, dtype=np.float32), {}

    def step(self, action):
        """Advance one control step (dt = ``config.dt_s``)."""
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(action, dtype=np.float32).reshape(ACTION_SIZE)
        self._key, self._state, packed = self._step_fn(self._key, self._state, a)
        packed = np.asarray(packed, dtype=np.float64)
        n = self._n_obs
        obs = packed[:n].astype(np.float32)
        reward, terminated, truncated, episode_step = packed[n : n + 4]
        values = packed[n + 4 :]
        info: dict[str, Any] = dict(zip(self._info_names, values, strict=True))
        for k in self._info_names:
            if k.startswith("term/"):
                info[k] = bool(info[k])
            else:
                info[k] = float(info[k])
        info["episode_step"] = int(episode_step)
        return obs, float(reward), bool(terminated), bool(truncated), info


#: gymnasium id: ``gymnasium.make(GYM_ID, config=EnvConfig(...), params=...)`` after importing this module.
GYM_ID = "harv_jax/HarvRecovery-v0"
if GYM_ID not in gym.registry:
    gym.register(id=GYM_ID, entry_point=HarvRecoveryEnv, disable_env_checker=True)
