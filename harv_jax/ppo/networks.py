"""Actor and critic networks (flax linen) and the Gaussian action distribution.

The paper's policy class (Stable-Baselines3 ``MlpPolicy`` with ``net_arch=[256, 128]``, tanh): separate
actor and critic MLPs, a Gaussian policy with a *state-independent* log standard deviation, SB3's orthogonal
initialisation (gain sqrt(2) on hidden layers, 0.01 on the action-mean head, 1 on the value head).

Squash or clip: the policy samples an unbounded Gaussian ``raw_action`` and the environment receives
``clip(raw_action, -1, 1)``. Log-probabilities and entropies are those of the unbounded Gaussian. This is
what SB3 does for a ``Box`` action space with ``squash_output=False`` (the paper's setting) and what the
measured probe in FINDINGS.md used. A tanh squash (brax's ``NormalTanhDistribution``) needs a Jacobian term
in the log-probability, has no closed-form entropy, and shrinks the gradient near the deflection limits,
which the recovery policy visits often (full aft stick, full rudder); clipping keeps the bang-bang corners
reachable at a finite mean. The deterministic action is ``clip(mean, -1, 1)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import flax.linen as nn
import jax
import jax.numpy as jnp

Params = Any

_LOG_2PI = math.log(2.0 * math.pi)


class MLP(nn.Module):
    """Tanh MLP with orthogonal initialisation; the last layer is linear.

    Attributes:
        hidden_sizes: widths of the hidden layers, e.g. ``(256, 128)``.
        out_size: width of the linear output layer.
        out_gain: orthogonal-init gain of the output layer.
    """

    hidden_sizes: Sequence[int]
    out_size: int
    out_gain: float = 1.0

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        for i, width in enumerate(self.hidden_sizes):
            x = nn.Dense(
                width,
                kernel_init=nn.initializers.orthogonal(math.sqrt(2.0)),
                bias_init=nn.initializers.zeros,
                name=f"hidden_{i}",
            )(x)
            x = jnp.tanh(x)
        return nn.Dense(
            self.out_size,
            kernel_init=nn.initializers.orthogonal(self.out_gain),
            bias_init=nn.initializers.zeros,
            name="out",
        )(x)


class Actor(nn.Module):
    """Gaussian policy head: obs -> (mean, log_std), log_std a free parameter (state-independent).

    Attributes:
        hidden_sizes: hidden widths.
        action_size: number of action components.
        init_log_std: initial log standard deviation (same for all components).
    """

    hidden_sizes: Sequence[int]
    action_size: int
    init_log_std: float = -0.5

    @nn.compact
    def __call__(self, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        mean = MLP(self.hidden_sizes, self.action_size, out_gain=0.01, name="mlp")(obs)
        log_std = self.param("log_std", nn.initializers.constant(self.init_log_std), (self.action_size,))
        return mean, jnp.broadcast_to(log_std, mean.shape)


class Critic(nn.Module):
    """State-value head: obs [..., obs_size] -> value [...]."""

    hidden_sizes: Sequence[int]

    @nn.compact
    def __call__(self, obs: jax.Array) -> jax.Array:
        return MLP(self.hidden_sizes, 1, out_gain=1.0, name="mlp")(obs)[..., 0]


class PPOParams(NamedTuple):
    """Learner parameters: ``policy`` (actor) and ``value`` (critic) flax variable dicts."""

    policy: Params
    value: Params


class PPONetworks(NamedTuple):
    """The two modules and the sizes they were built for (static)."""

    actor: Actor
    critic: Critic
    observation_size: int
    action_size: int

    def init(self, key: jax.Array) -> PPOParams:
        """Initialise both networks from one key."""
        key_policy, key_value = jax.random.split(key)
        dummy = jnp.zeros((1, self.observation_size), jnp.float32)
        return PPOParams(self.actor.init(key_policy, dummy), self.critic.init(key_value, dummy))

    def policy(self, params: PPOParams, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        """obs [..., O] (already normalised) -> (mean [..., A], log_std [..., A])."""
        return self.actor.apply(params.policy, obs)

    def value(self, params: PPOParams, obs: jax.Array) -> jax.Array:
        """obs [..., O] (already normalised) -> value [...] (scaled-reward units)."""
        return self.critic.apply(params.value, obs)


def make_ppo_networks(
    observation_size: int,
    action_size: int,
    hidden_sizes: Sequence[int] = (256, 128),
    init_log_std: float = -0.5,
) -> PPONetworks:
    """Build the actor and critic (the paper's [256, 128] tanh by default)."""
    return PPONetworks(
        actor=Actor(tuple(hidden_sizes), action_size, init_log_std),
        critic=Critic(tuple(hidden_sizes)),
        observation_size=observation_size,
        action_size=action_size,
    )


def gaussian_log_prob(mean: jax.Array, log_std: jax.Array, x: jax.Array) -> jax.Array:
    """Log density of a diagonal Gaussian, summed over the last axis: [..., A] -> [...]."""
    z = (x - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * jnp.square(z) - log_std - 0.5 * _LOG_2PI, axis=-1)


def gaussian_entropy(log_std: jax.Array) -> jax.Array:
    """Entropy of a diagonal Gaussian, summed over the last axis: [..., A] -> [...]."""
    return jnp.sum(log_std + 0.5 * (1.0 + _LOG_2PI), axis=-1)


def sample_raw_action(key: jax.Array, mean: jax.Array, log_std: jax.Array) -> jax.Array:
    """Sample the unbounded Gaussian action [..., A]."""
    return mean + jnp.exp(log_std) * jax.random.normal(key, mean.shape, mean.dtype)


def postprocess(raw_action: jax.Array) -> jax.Array:
    """Map a raw Gaussian sample to the env's action box: ``clip(raw, -1, 1)``."""
    return jnp.clip(raw_action, -1.0, 1.0)
