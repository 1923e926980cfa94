"""Spin/upset recovery environment (paper Section IV-A): pure functional core plus adapters.

The core (``recovery``) needs only jax/flax. The adapters import their frameworks lazily:
``harv_jax.env.brax_env`` (brax) and ``harv_jax.env.gym_env`` (gymnasium) are not imported here.
"""

from harv_jax.env.config import (
    ACTION_SIZE,
    OBS_HIGH,
    OBS_LOW,
    OBS_NAMES,
    OBSERVATION_SIZE,
    EnvConfig,
    EnvelopeParams,
    EnvParams,
    RandomizationParams,
    ResetParams,
    RewardParams,
    default_params,
    default_randomization_params,
)
from harv_jax.env.randomize import EpisodeParams
from harv_jax.env.recovery import Env, EnvState, TerminationFlags, make_env, termination_flags
from harv_jax.env.reward import RewardTerms

observation_size = OBSERVATION_SIZE
action_size = ACTION_SIZE

__all__ = [
    "ACTION_SIZE",
    "OBSERVATION_SIZE",
    "OBS_HIGH",
    "OBS_LOW",
    "OBS_NAMES",
    "Env",
    "EnvConfig",
    "EnvParams",
    "EnvState",
    "EnvelopeParams",
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
