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

import functools
import operator
from typing import NamedTuple

import jax
import jax.numpy as jnp

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
        teacher_action: [M, A] a teacher's action in [-1, 1] at ``obs`` (None: no behaviour cloning).
        next_obs: [M, O] the next observation of the same episode, normalised (None: no temporal smoothness).
        next_mask: [M] 1.0 where ``next_obs`` belongs to the same episode, else 0.0.
        perturbed_obs: [M, O] ``obs`` plus Gaussian noise (None: no spatial smoothness).
    """

    obs: jax.Array
    raw_action: jax.Array
    log_prob: jax.Array
    value: jax.Array
    advantage: jax.Array
    target: jax.Array
    teacher_action: jax.Array | None = None
    next_obs: jax.Array | None = None
    next_mask: jax.Array | None = None
    perturbed_obs: jax.Array | None = None


class DemoBatch(NamedTuple):
    """A minibatch of demonstration pairs, leading axis [K].

    Attributes:
        obs: [K, O] the demonstrations' observations, normalised as the policy's input.
        action: [K, A] the demonstrated actions in [-1, 1].
    """

    obs: jax.Array
    action: jax.Array


def behaviour_cloning(mean: jax.Array, target: jax.Array) -> jax.Array:
    """``mean(sum(|clip(mu, -1, 1) - a|^2 + 0.01 |mu - a|^2))`` over [M, A] policy means ``mu`` and targets
    ``a``, summed over action components (the small unclipped part keeps a gradient where mu is clipped)."""
    err = jnp.clip(mean, -1.0, 1.0) - target
    return jnp.mean(jnp.sum(jnp.square(err) + 0.01 * jnp.square(mean - target), axis=-1))


def action_change(mean: jax.Array, other: jax.Array, weight: jax.Array | None = None) -> jax.Array:
    """``mean(sum(|clip(mu, -1, 1) - clip(mu', -1, 1)|))`` over [M, A] policy means, summed over action
    components, weighted per row by ``weight`` [M] (a weighted mean; None: all rows): the smoothness terms
    of CAPS (Mysore et al. 2021) on the actions that fly, with the L1 distance of the control's total
    variation (its gradient does not vanish as the change gets small, as a squared distance's does)."""
    change = jnp.sum(jnp.abs(jnp.clip(mean, -1.0, 1.0) - jnp.clip(other, -1.0, 1.0)), axis=-1)
    if weight is None:
        return jnp.mean(change)
    return jnp.sum(weight * change) / jnp.maximum(jnp.sum(weight), 1.0)


def ppo_loss(
    params: PPOParams,
    batch: PPOBatch,
    networks: PPONetworks,
    clip_eps: float = 0.2,
    vf_coef: float = 0.5,
    ent_coef: float = 0.0,
    clip_value_eps: float | None = None,
    normalize_advantage: bool = True,
    bc_coef: jax.Array | float = 0.0,
    pg_on: jax.Array | float = 1.0,
    demo: DemoBatch | None = None,
    smooth_temporal_coef: float = 0.0,
    smooth_spatial_coef: float = 0.0,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """Clipped-surrogate PPO loss with value loss and entropy bonus (SB3 / brax form), and optionally a
    behaviour-cloning term toward a teacher (DAPG-style).

    ``loss = -pg_on * mean(min(rho A, clip(rho, 1-eps, 1+eps) A)) + vf_coef * 0.5 * mean((target - V)^2)
    - pg_on * ent_coef * mean(entropy) + bc_coef * BC``; with ``clip_value_eps`` the value error is the max
    of the unclipped and the clipped (``V_old + clip(V - V_old, +-eps)``) squared errors. Advantages are
    standardised over the minibatch when ``normalize_advantage``. ``BC`` is the sum of
    [`behaviour_cloning`][] of the policy mean toward ``batch.teacher_action`` (if given) and of the policy
    mean at ``demo.obs`` toward ``demo.action`` (if given); with neither there is no BC term at all. The
    smoothness terms (CAPS, Mysore et al. 2021) add ``smooth_temporal_coef * action_change(mu(obs),
    mu(next_obs), next_mask) + smooth_spatial_coef * action_change(mu(obs), mu(perturbed_obs))`` when their
    inputs are in the batch; they act on the policy mean, the action that flies at evaluation.

    Args:
        params: actor and critic parameters.
        batch: minibatch of transitions.
        networks: the modules.
        clip_eps: PPO ratio clip.
        vf_coef: value-loss coefficient.
        ent_coef: entropy-bonus coefficient.
        clip_value_eps: value clip range (None: no value clipping).
        normalize_advantage: standardise advantages over the minibatch.
        bc_coef: weight of the behaviour-cloning term (used only with ``batch.teacher_action`` or ``demo``).
        pg_on: factor on the policy-gradient and entropy terms (0: the actor learns from BC alone).
        demo: demonstration pairs cloned besides the rollout's teacher labels (None: none).
        smooth_temporal_coef: weight of the temporal smoothness term (used only with ``batch.next_obs``).
        smooth_spatial_coef: weight of the spatial smoothness term (used only with ``batch.perturbed_obs``).

    Returns:
        (scalar loss, metrics dict of scalars).
    """
    mean, log_std, value = networks.policy_and_value(params, batch.obs)
    log_prob = gaussian_log_prob(mean, log_std, batch.raw_action)
    log_ratio = log_prob - batch.log_prob
    ratio = jnp.exp(log_ratio)

    adv = batch.advantage
    if normalize_advantage:
        adv = (adv - adv.mean()) / (adv.std() + 1e-8)
    surrogate = jnp.minimum(ratio * adv, jnp.clip(ratio, 1.0 - clip_eps, 1.0 + clip_eps) * adv)
    policy_loss = -jnp.mean(surrogate)

    v_err = jnp.square(batch.target - value)
    if clip_value_eps is not None:
        v_clipped = batch.value + jnp.clip(value - batch.value, -clip_value_eps, clip_value_eps)
        v_err = jnp.maximum(v_err, jnp.square(batch.target - v_clipped))
    value_loss = 0.5 * vf_coef * jnp.mean(v_err)

    entropy = jnp.mean(gaussian_entropy(log_std))
    entropy_loss = -ent_coef * entropy
    if isinstance(pg_on, float) and pg_on == 1.0:  # a static 1 leaves the plain PPO loss's graph as it is
        actor_loss = policy_loss + entropy_loss
    else:
        actor_loss = pg_on * (policy_loss + entropy_loss)
    bc_terms = {}
    if batch.teacher_action is not None:
        bc_terms["bc_loss"] = behaviour_cloning(mean, batch.teacher_action)
    if demo is not None:
        bc_terms["bc_demo_loss"] = behaviour_cloning(networks.policy(params, demo.obs)[0], demo.action)
    if not bc_terms:
        total = actor_loss + value_loss
        extra = {}
    else:
        bc = functools.reduce(operator.add, bc_terms.values())
        total = actor_loss + value_loss + bc_coef * bc
        extra = {**bc_terms, "bc_coef": jnp.asarray(bc_coef, jnp.float32)}
    if batch.next_obs is not None:
        smooth = action_change(mean, networks.policy(params, batch.next_obs)[0], batch.next_mask)
        total = total + smooth_temporal_coef * smooth
        extra["smooth_temporal_loss"] = smooth
    if batch.perturbed_obs is not None:
        smooth = action_change(mean, networks.policy(params, batch.perturbed_obs)[0])
        total = total + smooth_spatial_coef * smooth
        extra["smooth_spatial_loss"] = smooth
    metrics = {
        "total_loss": total,
        "policy_loss": policy_loss,
        "value_loss": value_loss,
        "entropy": entropy,
        "approx_kl": jnp.mean((ratio - 1.0) - log_ratio),
        "clip_fraction": jnp.mean((jnp.abs(ratio - 1.0) > clip_eps).astype(jnp.float32)),
        "policy_std": jnp.mean(jnp.exp(log_std)),
        **extra,
    }
    return total, metrics
