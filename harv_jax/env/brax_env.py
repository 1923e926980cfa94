"""A ``brax.envs.base.Env`` adapter of the recovery environment (imports brax; the core does not).

    from brax.envs.wrappers.training import wrap
    env = wrap(HarvBraxEnv(), episode_length=20_000)     # VmapWrapper -> EpisodeWrapper -> AutoReset
    state = jax.jit(env.reset)(jax.random.split(jax.random.PRNGKey(0), 256))

- ``state.pipeline_state`` is the core ``EnvState`` (the aircraft's ``BodyState`` is
  ``pipeline_state.aircraft``; it also holds the per-episode randomized parameters, so that brax's
  ``AutoResetWrapper``, which swaps ``pipeline_state``, swaps them together).
- ``state.metrics`` holds every reward term (``reward/<term>``) and the termination causes
  (``term/<cause>``), updated in place; ``state.info`` holds ``rng`` (this env's PRNG stream, raw
  uint32 key data as brax passes it) and ``truncation``.
- ``done`` is the termination only (envelope exit, reward -1000). Time limits are the
  ``EpisodeWrapper``'s job, as in brax: it sets ``done`` and ``info['truncation']`` at
  ``episode_length`` (use ``EnvConfig.episode_steps``); ``info['truncation']`` is 0 without it.
- Per-episode resampling under ``AutoResetWrapper``: that wrapper resets a done env to the state saved
  in ``info['first_pipeline_state']``/``info['first_obs']`` at ``reset``, i.e. the same initial state and
  aircraft every episode. When those keys are present this env refreshes them at every step with a
  freshly drawn episode, so every episode gets new draws, as in the core env.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from brax.envs.base import Env as BraxEnvBase
from brax.envs.base import State

from harv_jax.env.config import EnvConfig, EnvParams
from harv_jax.env.recovery import make_env
from harv_jax.env.reward import RewardTerms
from harv_jax.env.termination import TerminationFlags
from harv_jax.task.spaces import ACTION_SIZE


class HarvBraxEnv(BraxEnvBase):
    """The recovery env behind brax's ``Env`` interface (single env; vmap it with brax's wrappers)."""

    def __init__(self, config: EnvConfig | None = None, params: EnvParams | None = None):
        """Build the adapter.

        Args:
            config: static env config (default ``EnvConfig()``).
            params: traced env parameters (default ``default_params(config)``), held as constants.
        """
        self._core = make_env(config)
        self._params = params if params is not None else self._core.default_params()

    @property
    def config(self) -> EnvConfig:
        return self._core.config

    @property
    def params(self) -> EnvParams:
        return self._params

    @property
    def observation_size(self) -> int:
        return self._core.observation_size

    @property
    def action_size(self) -> int:
        return ACTION_SIZE

    @property
    def backend(self) -> str:
        return "harv_jax"

    @property
    def dt(self) -> float:
        """Control step, s."""
        return self._core.config.dt_s

    def _metrics(self, terms: dict[str, jnp.ndarray], flags: dict[str, jnp.ndarray]) -> dict[str, Any]:
        m = {f"reward/{k}": v for k, v in terms.items()}
        m.update({f"term/{k}": v.astype(jnp.float32) for k, v in flags.items()})
        return m

    def reset(self, rng: jax.Array) -> State:
        """Start an episode from a raw PRNG key [2] (brax convention)."""
        k_reset, k_stream = jax.random.split(rng)
        obs, es = self._core.reset(k_reset, self._params)
        zero = jnp.zeros((), dtype=obs.dtype)
        zeros_terms = dict.fromkeys(RewardTerms._fields, zero)
        zeros_flags = dict.fromkeys(TerminationFlags._fields, zero)
        return State(
            pipeline_state=es,
            obs=obs,
            reward=zero,
            done=zero,
            metrics=self._metrics(zeros_terms, zeros_flags),
            info={"rng": k_stream, "truncation": zero},
        )

    def step(self, state: State, action: jax.Array) -> State:
        """One control step; metrics and info are updated in place (brax style)."""
        rng, k_step, k_fresh = jax.random.split(state.info["rng"], 3)
        obs, es, reward, terminated, _, info = self._core.step_no_reset(
            k_step, state.pipeline_state, action, self._params
        )
        state.metrics.update(self._metrics(info["reward_terms"], info["termination"]))
        state.info["rng"] = rng
        if "first_pipeline_state" in state.info:
            obs0, es0 = self._core.reset(k_fresh, self._params)
            state.info["first_pipeline_state"] = es0
            state.info["first_obs"] = obs0
        return state.replace(
            pipeline_state=es,
            obs=obs,
            reward=reward.astype(obs.dtype),
            done=terminated.astype(obs.dtype),
        )
