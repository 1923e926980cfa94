"""Running observation normalisation in the learner (Welford / Chan parallel update).

The statistics live in the training state (a pytree), are updated from each rollout's observations after the
PPO update (so the behaviour and target log-probabilities of one update use the same normalisation), are saved
in checkpoints and are baked into exported policies.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

#: Added to the variance before the square root (as SB3 ``VecNormalize``); keeps constant features finite.
VAR_EPS = 1e-8
#: Normalised observations are clipped to +-CLIP_OBS (SB3 ``VecNormalize`` default).
CLIP_OBS = 10.0


@struct.dataclass
class RunningStats:
    """Count, mean and sum of squared deviations of the observations seen so far.

    Attributes:
        count: [] number of observations (float32; relative precision ~1e-7 is enough for the weights).
        mean: [O] running mean.
        m2: [O] running sum of squared deviations from the mean (variance = m2 / count).
    """

    count: jax.Array
    mean: jax.Array
    m2: jax.Array

    @property
    def std(self) -> jax.Array:
        """[O] standard deviation (1 before any update)."""
        var = jnp.where(self.count > 0, self.m2 / jnp.maximum(self.count, 1.0), 1.0)
        return jnp.sqrt(var + VAR_EPS)


def init_stats(observation_size: int) -> RunningStats:
    """Empty statistics (normalisation is the identity until the first update)."""
    return RunningStats(
        count=jnp.zeros((), jnp.float32),
        mean=jnp.zeros((observation_size,), jnp.float32),
        m2=jnp.zeros((observation_size,), jnp.float32),
    )


def update_stats(stats: RunningStats, obs: jax.Array) -> RunningStats:
    """Merge a batch of observations [..., O] into the statistics (Chan et al. parallel Welford).

    Args:
        stats: current statistics.
        obs: [..., O] observations; all leading axes are batch axes.

    Returns:
        Statistics of the union of the old data and the batch.
    """
    x = obs.reshape(-1, obs.shape[-1]).astype(jnp.float32)
    n_b = jnp.asarray(x.shape[0], jnp.float32)
    mean_b = jnp.mean(x, axis=0)
    m2_b = jnp.sum(jnp.square(x - mean_b[None, :]), axis=0)
    n = stats.count + n_b
    delta = mean_b - stats.mean
    mean = stats.mean + delta * (n_b / n)
    m2 = stats.m2 + m2_b + jnp.square(delta) * (stats.count * n_b / n)
    return RunningStats(count=n, mean=mean, m2=m2)


def normalize(stats: RunningStats, obs: jax.Array, clip: float = CLIP_OBS) -> jax.Array:
    """(obs - mean) / std, clipped to +-clip: [..., O] -> [..., O]."""
    mean = jnp.broadcast_to(stats.mean, obs.shape)
    std = jnp.broadcast_to(stats.std, obs.shape)
    return jnp.clip((obs - mean) / std, -clip, clip)
