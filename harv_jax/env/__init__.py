"""The spin/upset recovery environment (paper Section IV-A): owns the pure gymnax-style core
(``recovery``: reset/step), its static config and traced parameters (``config``, ``settings``), the reward
(``reward``), the terminations (``termination``), the per-episode gust/noise/delay draws (``randomize``)
and the adapters. The task itself (spaces, envelope, criterion, reset bounds) comes from ``harv_jax.task``;
``env`` never imports ``control`` or ``evaluation``.

The core needs only jax/flax. The adapters import their frameworks lazily:
``harv_jax.env.brax_env`` (brax) and ``harv_jax.env.gym_env`` (gymnasium) are not imported here.
"""

from harv_jax.env.config import (
    EnvConfig,
    EnvParams,
    RandomizationParams,
    ResetParams,
    RewardParams,
    default_params,
    default_randomization_params,
)
from harv_jax.env.randomize import EpisodeParams
from harv_jax.env.recovery import Env, EnvState, make_env
from harv_jax.env.reward import RewardTerms
from harv_jax.env.termination import TerminationFlags, termination_flags
from harv_jax.task.spaces import ACTION_SIZE, OBSERVATION_SIZE

observation_size = OBSERVATION_SIZE
action_size = ACTION_SIZE

__all__ = [
    "Env",
    "EnvConfig",
    "EnvParams",
    "EnvState",
    "EpisodeParams",
    "RandomizationParams",
    "ResetParams",
    "RewardParams",
    "RewardTerms",
    "TerminationFlags",
    "action_size",
    "default_params",
    "default_randomization_params",
    "make_env",
    "observation_size",
    "termination_flags",
]
