"""GAE and the clipped PPO loss. No environment imports.

Conventions (time-major, as brax ``compute_gae``): arrays are ``[T, B]``; ``terminations[t] = 1`` when the
episode ended at step t in a terminal state (no bootstrap), ``truncations[t] = 1`` when it was cut by the
time limit (bootstrap from the value of the final observation). ``next_values[t]`` is the value of the true
successor of step t: ``V(final_obs_t)`` when the episode ended at t, otherwise ``V(obs_{t+1})`` (and the
bootstrap value after the last step).

Advantages are the standard GAE(lambda) of Schulman et al. (as in SB3, the paper's trainer). Brax's
``compute_gae`` differs in two ways, on purpose here: it masks truncated steps out instead of bootstrapping,
and its policy advantage is ``r_t + gamma * vs_{t+1} - V_t`` (a V-trace form) rather than GAE; both agree
with ours when lambda = 1 and nothing is truncated (tested).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from harv_jax.ppo.loss_terms import LossTerm
from harv_jax.ppo.networks import PPONetworks, PPOParams, gaussian_entropy, gaussian_log_prob


def compute_gae(
    rewards: jax.Array,
    values: jax.Array,
    next_values: jax.Array,
    terminations: jax.Array,
    truncations: jax.Array,
    gamma: float,
    gae_lambda: float,
) -> tuple[jax.Array, jax.Array]:
    """Generalised advantage estimation with termination/truncation handling.

    ``delta_t = r_t + gamma * (1 - term_t) * next_values_t - values_t`` and
    ``A_t = delta_t + gamma * lambda * (1 - done_t) * A_{t+1}`` with ``done_t = max(term_t, trunc_t)``:
    a truncated step bootstraps from ``next_values_t = V(final_obs_t)``; a terminated one does not; neither
    lets the next episode's advantages leak back.

    Args:
        rewards: [T, B] (already scaled).
        values: [T, B] V(obs_t) under the behaviour critic.
        next_values: [T, B] value of the true successor state of step t (see module docstring).
        terminations: [T, B] 1.0 where the episode terminated at t.
        truncations: [T, B] 1.0 where the episode was truncated at t.
        gamma: discount.
        gae_lambda: GAE lambda.

    Returns:
        (advantages [T, B], value_targets [T, B] = advantages + values), both without gradient.
    """
    terminations = terminations.astype(rewards.dtype)
    dones = jnp.maximum(terminations, truncations.astype(rewards.dtype))
    deltas = rewards + gamma * (1.0 - terminations) * next_values - values

    def backward(acc: jax.Array, xs: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
        delta, done = xs
        acc = delta + gamma * gae_lambda * (1.0 - done) * acc
        return acc, acc

    _, advantages = jax.lax.scan(backward, jnp.zeros_like(rewards[0]), (deltas, dones), reverse=True)
    targets = advantages + values
    return jax.lax.stop_gradient(advantages), jax.lax.stop_gradient(targets)


def successor_values(
    values: jax.Array,
    last_value: jax.Array,
    final_values: jax.Array,
    terminations: jax.Array,
    truncations: jax.Array,
) -> jax.Array:
    """``next_values`` for [`compute_gae`][] from a rollout with auto-reset.

    Args:
        values: [T, B] V(obs_t).
        last_value: [B] V(obs_T), the observation after the last step.
        final_values: [T, B] V(final_obs_t) (the last observation of an episode that ended at t).
        terminations: [T, B].
        truncations: [T, B].

    Returns:
        [T, B]: ``final_values`` where the episode ended at t (after an auto-reset ``obs_{t+1}`` belongs
        to the next episode), else ``values[t + 1]`` (``last_value`` for t = T - 1).
    """
    following = jnp.concatenate([values[1:], last_value[None]], axis=0)
    ended = jnp.maximum(terminations, truncations) > 0
    return jnp.where(ended, final_values, following)


class PPOBatch(NamedTuple):
    """One minibatch of flattened transitions, leading axis [M].

    Attributes:
        obs: [M, O] network input (already normalised).
        raw_action: [M, A] unclipped Gaussian sample that was taken.
        log_prob: [M] its log-probability under the behaviour policy.
        value: [M] behaviour critic's V(obs) (used by value clipping).
        advantage: [M] GAE advantage.
        target: [M] value target (lambda-return).
        term_data: each loss term's per-transition data [M, ...] (``LossTerm.transition_data``; None: none).
        term_samples: each loss term's sample for this minibatch (``LossTerm.samples``; None: none).
        critic_obs: [M, O] the critic's input (already normalised) where it differs from the policy's
            (an asymmetric actor-critic, ``harv_jax.ppo.acting``), else None.
    """

    obs: jax.Array
    raw_action: jax.Array
    log_prob: jax.Array
    value: jax.Array
    advantage: jax.Array
    target: jax.Array
    term_data: tuple[Any, ...] = ()
    term_samples: tuple[Any, ...] = ()
    critic_obs: Any = None


class PPOLossSettings(NamedTuple):
    """The clipped-surrogate loss's settings (static).

    Attributes:
        clip_eps: PPO ratio clip.
        vf_coef: value-loss coefficient.
        ent_coef: entropy-bonus coefficient.
        clip_value_eps: value clip range (None: no value clipping).
        normalize_advantage: standardise advantages over the minibatch.
    """

    clip_eps: float = 0.2
    vf_coef: float = 0.5
    ent_coef: float = 0.0
    clip_value_eps: float | None = None
    normalize_advantage: bool = True


class LossWeights(NamedTuple):
    """The weights of one update (traced where scheduled).

    Attributes:
        actor: factor on the policy-gradient and entropy terms (None: 1, the plain PPO loss's graph; 0: the
            actor learns from the loss terms alone).
        terms: each loss term's coefficient.
    """

    actor: jax.Array | None = None
    terms: tuple[jax.Array | float, ...] = ()


def ppo_loss(
    params: PPOParams,
    batch: PPOBatch,
    networks: PPONetworks,
    settings: PPOLossSettings = PPOLossSettings(),
    terms: Sequence[LossTerm] = (),
    weights: LossWeights = LossWeights(),
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """Clipped-surrogate PPO loss with value loss and entropy bonus (SB3 / brax form), then the loss terms.

    ``loss = -actor * mean(min(rho A, clip(rho, 1-eps, 1+eps) A)) + vf_coef * 0.5 * mean((target - V)^2)
    - actor * ent_coef * mean(entropy) + sum_k coef_k * term_k``; with ``clip_value_eps`` the value error
    is the max of the unclipped and the clipped (``V_old + clip(V - V_old, +-eps)``) squared errors; ``V``
    is evaluated on ``batch.critic_obs`` where given (an asymmetric actor-critic), else on ``batch.obs``.
    Advantages are standardised over the minibatch when ``normalize_advantage``. Each term
    ([`LossTerm`][harv_jax.ppo.loss_terms.LossTerm]) is evaluated from the policy mean of the same forward
    pass, on its entries of ``batch.term_data`` and ``batch.term_samples``; its metrics join the PPO ones,
    with its coefficient as ``<name>_coef``.

    Args:
        params: actor and critic parameters.
        batch: minibatch of transitions.
        networks: the modules.
        settings: the clipped-surrogate loss's settings.
        terms: the loss terms, added in this order.
        weights: the actor factor and the terms' coefficients.

    Returns:
        (scalar loss, metrics dict of scalars).
    """
    s = settings
    mean, log_std, value = networks.policy_and_value(params, batch.obs, batch.critic_obs)
    log_prob = gaussian_log_prob(mean, log_std, batch.raw_action)
    log_ratio = log_prob - batch.log_prob
    ratio = jnp.exp(log_ratio)

    adv = batch.advantage
    if s.normalize_advantage:
        adv = (adv - adv.mean()) / (adv.std() + 1e-8)
    surrogate = jnp.minimum(ratio * adv, jnp.clip(ratio, 1.0 - s.clip_eps, 1.0 + s.clip_eps) * adv)
    policy_loss = -jnp.mean(surrogate)

    v_err = jnp.square(batch.target - value)
    if s.clip_value_eps is not None:
        v_clipped = batch.value + jnp.clip(value - batch.value, -s.clip_value_eps, s.clip_value_eps)
        v_err = jnp.maximum(v_err, jnp.square(batch.target - v_clipped))
    value_loss = 0.5 * s.vf_coef * jnp.mean(v_err)

    entropy = jnp.mean(gaussian_entropy(log_std))
    entropy_loss = -s.ent_coef * entropy
    actor_loss = policy_loss + entropy_loss
    if weights.actor is not None:
        actor_loss = weights.actor * actor_loss
    total = actor_loss + value_loss
    extra: dict[str, jax.Array] = {}
    data = batch.term_data or (None,) * len(terms)
    samples = batch.term_samples or (None,) * len(terms)
    for term, coef, d, smp in zip(terms, weights.terms, data, samples, strict=True):
        v, m = term.value(params, networks, mean, d, smp)
        total = total + coef * v
        extra.update(m)
        extra[f"{term.name}_coef"] = jnp.asarray(coef, jnp.float32)
    metrics = {
        "total_loss": total,
        "policy_loss": policy_loss,
        "value_loss": value_loss,
        "entropy": entropy,
        "approx_kl": jnp.mean((ratio - 1.0) - log_ratio),
        "clip_fraction": jnp.mean((jnp.abs(ratio - 1.0) > s.clip_eps).astype(jnp.float32)),
        "policy_std": jnp.mean(jnp.exp(log_std)),
        **extra,
    }
    return total, metrics
