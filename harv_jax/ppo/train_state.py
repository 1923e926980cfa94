"""The types of the compiled PPO step: the per-seed training state, one rollout step and the trainer.

[`harv_jax.ppo.train.make_train`][] builds a [`Trainer`][]; its ``period`` maps a
[`TrainingState`][] to the next one and the period's metrics.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
from flax import struct
from jax.sharding import Mesh

from harv_jax.ppo import normalize as obs_norm
from harv_jax.ppo.networks import PPONetworks, PPOParams

Metrics = dict[str, jax.Array]


@struct.dataclass
class TrainingState:
    """Everything that changes during training, for one seed (a leading [S] axis is added by vmap).

    Attributes:
        params: actor and critic parameters.
        opt_state: optax Adam state.
        normalizer: running observation statistics.
        env_state: env state pytree, leading axis [N].
        obs: [N, O] current observations.
        episode_return: [N] undiscounted, unscaled return of the running episodes.
        episode_length: [N] steps of the running episodes.
        key: PRNG key of this learner.
        update_step: [] int32 number of PPO updates done.
    """

    params: PPOParams
    opt_state: Any
    normalizer: obs_norm.RunningStats
    env_state: Any
    obs: jax.Array
    episode_return: jax.Array
    episode_length: jax.Array
    key: jax.Array
    update_step: jax.Array


class Rollout(NamedTuple):
    """One env step of the rollout, [T, N, ...] after the scan."""

    obs: jax.Array  # network input (normalised) [O]
    raw_action: jax.Array  # [A]
    log_prob: jax.Array  # []
    value: jax.Array  # [] V(obs)
    reward: jax.Array  # [] unscaled env reward
    termination: jax.Array  # []
    truncation: jax.Array  # []
    final_value: jax.Array  # [] V(final_obs), used where the episode ended
    raw_obs: jax.Array  # [O] unnormalised observation (for the running statistics)
    term_data: tuple[Any, ...] = ()  # what each loss term keeps of the step's info (``LossTerm.step_data``)
    critic_obs: Any = None  # [O] the critic's input (normalised) where the env has one, else None


class Trainer(NamedTuple):
    """What `make_train` returns.

    Attributes:
        init: ``init(keys [S], env_params) -> TrainingState`` (jitted, sharded).
        period: ``period(state, env_params) -> (state, metrics)`` (jitted once; metrics are [S] arrays).
        networks: the actor/critic modules.
        mesh: the device mesh.
        state_shardings: shardings of the training state (for restoring checkpoints).
        num_traces: number of times ``period`` has been traced (the no-recompile guard).
    """

    init: Callable[[jax.Array, Any], TrainingState]
    period: Callable[[TrainingState, Any], tuple[TrainingState, Metrics]]
    networks: PPONetworks
    mesh: Mesh
    state_shardings: Any
    num_traces: Callable[[], int]
