"""Demonstration pairs for behaviour cloning inside the PPO update (generic: arrays only, no file format).

``make_train(..., demos=(observations [M, O], actions [M, A]))`` puts the pairs on the devices once; every
SGD step of an update clones a minibatch of them ([`sample_minibatches`][]), drawn uniformly with
replacement from a stream of the update's own key, so that a run is reproducible from its seed.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.ppo.losses import DemoBatch
from harv_jax.ppo.sharding import put_global


def check_demos(demos: tuple[Any, Any], obs_size: int, act_size: int, use_bc: bool) -> DemoBatch:
    """Demonstration pairs as float32 host arrays; ValueError unless they fit the env and BC is on."""
    obs, action = (np.asarray(x, np.float32) for x in demos)
    if obs.ndim != 2 or action.ndim != 2 or obs.shape[0] != action.shape[0] or obs.shape[0] == 0:
        raise ValueError(f"demos: observations {obs.shape} and actions {action.shape} must be [M, O], [M, A]")
    if (obs.shape[1], action.shape[1]) != (obs_size, act_size):
        raise ValueError(
            f"demos have {obs.shape[1]} observations and {action.shape[1]} actions; the env has "
            f"{obs_size} and {act_size}"
        )
    if not use_bc:
        raise ValueError("demos are cloned with weight bc_coef; set bc_coef > 0 or bc_coef_end > 0")
    return DemoBatch(obs, action)


def sample_minibatches(
    key: jax.Array,
    demo: DemoBatch,
    shape: tuple[int, ...],
    normalise: Callable[[jax.Array], jax.Array],
) -> DemoBatch:
    """``shape`` (e.g. [epochs, minibatches, size]) pairs drawn uniformly with replacement from ``demo``
    with ``fold_in(key, 1)`` (a new stream: the draws of ``key`` stay as without demos); observations
    through ``normalise`` (the learner's observation normalizer)."""
    idx = jax.random.randint(jax.random.fold_in(key, 1), shape, 0, demo.obs.shape[0])
    return DemoBatch(normalise(jnp.take(demo.obs, idx, axis=0)), jnp.take(demo.action, idx, axis=0))


def bind_demos(
    period: Callable[..., Any], demo: DemoBatch, placement: jax.sharding.Sharding
) -> Callable[[Any, Any], Any]:
    """``(state, env_params) -> period(state, env_params, demo)`` with ``demo`` put on the devices once
    (with ``placement``): an argument of the compiled period, not a constant of its program."""
    on_devices = jax.tree.map(lambda x: put_global(x, placement), demo)
    return lambda state, env_params: period(state, env_params, on_devices)
