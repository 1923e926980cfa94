"""Objectives the PPO update adds to its clipped-surrogate loss: behaviour cloning, and any term of yours.

The PPO loss ([`ppo_loss`][harv_jax.ppo.losses.ppo_loss]) is ``actor + value`` and the trainer composes
any number of terms after it, as ``optax.chain`` composes gradient transformations:
``loss = actor + value + sum_k coef_k(frac) * value_k``, in the order given (``frac``: the fraction of the
run's updates done). A term declares what it needs and where it comes from:

- ``step_data(info)``: something of each env step's ``info`` it keeps in the rollout (e.g. a teacher's
  labels), ``[T, N, ...]`` after the rollout;
- ``transition_data(ctx)``: per-transition arrays ``[T, N, ...]`` made after the rollout (default: the step
  data); they are shuffled and split into minibatches with the transitions;
- ``inputs()`` and ``samples(...)``: arrays put on the devices once (e.g. demonstrations) and a sample of
  them per minibatch, drawn with the update's key;
- ``value(...)``: the term on one minibatch, from the policy mean at the minibatch's observations (the same
  forward pass the PPO terms use), with its metrics.

Without terms the trainer compiles the plain PPO loss, bit for bit; each term draws its random numbers from
a stream of its own (``fold_in`` of the update's key), so the other draws stay as without it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.ppo.networks import PPONetworks, PPOParams
from harv_jax.ppo.sharding import put_global


class DemoBatch(NamedTuple):
    """Demonstration pairs, leading axes [..., K].

    Attributes:
        obs: [..., K, O] observations (normalised as the policy's input once sampled).
        action: [..., K, A] the demonstrated actions in [-1, 1].
    """

    obs: jax.Array
    action: jax.Array


class TermContext(NamedTuple):
    """What a term may use to make its per-transition data after a rollout.

    Attributes:
        obs: [T, N, O] the rollout's normalised observations.
        termination: [T, N] 1.0 where the episode terminated at t.
        truncation: [T, N] 1.0 where it was truncated at t.
        last_obs: [N, O] the normalised observation after the last step.
        step_data: [T, N, ...] what this term kept of each step's info (``LossTerm.step_data``), or None.
        key: the update's SGD key (draw from ``fold_in(key, i)`` with an ``i`` of the term's own).
    """

    obs: jax.Array
    termination: jax.Array
    truncation: jax.Array
    last_obs: jax.Array
    step_data: Any
    key: jax.Array


class LossTerm:
    """A term ``coef(frac) * value`` added to the PPO loss (see the module docstring); subclasses set
    ``name`` and override what they use."""

    name: str = "term"

    def coef(self, frac: jax.Array) -> float | jax.Array:
        """Weight at ``frac`` (the fraction of the run's updates done, traced float32)."""
        raise NotImplementedError

    def check(self, info_keys: Sequence[str], obs_size: int, act_size: int) -> None:
        """ValueError if the env (its ``info`` keys, observation and action sizes) cannot feed the term."""

    def step_data(self, info: dict[str, Any]) -> Any:
        """What the term keeps of one env step's ``info`` (None: nothing)."""
        return None

    def transition_data(self, ctx: TermContext) -> Any:
        """Per-transition arrays [T, N, ...] (default: the step data)."""
        return ctx.step_data

    def inputs(self) -> Any:
        """Host arrays put on the devices once and passed into the compiled period (None: none)."""
        return None

    def samples(
        self, key: jax.Array, inputs: Any, shape: tuple[int, ...], normalise: Callable[[jax.Array], jax.Array]
    ) -> Any:
        """A sample of ``inputs`` for each of ``shape`` = [epochs, minibatches, size] (None: none)."""
        return None

    def value(
        self, params: PPOParams, networks: PPONetworks, mean: jax.Array, data: Any, sample: Any
    ) -> tuple[jax.Array, dict[str, jax.Array]]:
        """(scalar, metrics) on one minibatch: ``mean`` [M, A] is the policy mean at its observations,
        ``data`` its per-transition data, ``sample`` its sample of the inputs."""
        raise NotImplementedError


def behaviour_cloning(mean: jax.Array, target: jax.Array) -> jax.Array:
    """``mean(sum(|clip(mu, -1, 1) - a|^2 + 0.01 |mu - a|^2))`` over [M, A] policy means ``mu`` and targets
    ``a``, summed over action components (the small unclipped part keeps a gradient where mu is clipped)."""
    err = jnp.clip(mean, -1.0, 1.0) - target
    return jnp.mean(jnp.sum(jnp.square(err) + 0.01 * jnp.square(mean - target), axis=-1))


class BehaviourCloning(LossTerm):
    """Behaviour cloning (DAPG-style) toward action labels the env writes into each step's ``info`` (a
    teacher's) and/or toward demonstration pairs: ``BC = behaviour_cloning(mu(obs), label)`` plus
    ``behaviour_cloning(mu(demo_obs), demo_action)`` on a sample of the demonstrations per minibatch
    (drawn uniformly with replacement from ``fold_in(key, 1)``), weighted linearly from ``coef_start``
    at the first update to ``coef_end`` after the last. Metrics: ``bc_loss``, ``bc_demo_loss``, ``bc_coef``.

    Args:
        coef_start: weight at the start of the run.
        coef_end: weight at its end.
        label_key: the ``info`` key of the labels ([A] in [-1, 1] per step); None: no labels.
        demos: (observations [M, O], actions [M, A] in [-1, 1]), raw as the env observes; None: none.
    """

    name = "bc"

    def __init__(
        self,
        coef_start: float,
        coef_end: float,
        label_key: str | None = None,
        demos: tuple[Any, Any] | None = None,
    ) -> None:
        if label_key is None and demos is None:
            raise ValueError(
                f"behaviour cloning (bc_coef {coef_start:g} -> {coef_end:g}) needs an env that writes a "
                "teacher's action labels, or demos"
            )
        self.coef_start, self.coef_end, self.label_key = coef_start, coef_end, label_key
        self.demos = None if demos is None else DemoBatch(*(np.asarray(x, np.float32) for x in demos))

    def coef(self, frac: jax.Array) -> jax.Array:
        return self.coef_start + (self.coef_end - self.coef_start) * frac

    def check(self, info_keys: Sequence[str], obs_size: int, act_size: int) -> None:
        if self.label_key is not None and self.label_key not in info_keys:
            raise ValueError(
                f"behaviour cloning reads the env's info[{self.label_key!r}], which this env does not write"
            )
        if self.demos is not None:
            obs, action = self.demos
            if obs.ndim != 2 or action.ndim != 2 or obs.shape[0] != action.shape[0] or obs.shape[0] == 0:
                raise ValueError(
                    f"demos: observations {obs.shape} and actions {action.shape} must be [M, O], [M, A]"
                )
            if (obs.shape[1], action.shape[1]) != (obs_size, act_size):
                raise ValueError(
                    f"demos have {obs.shape[1]} observations and {action.shape[1]} actions; the env has "
                    f"{obs_size} and {act_size}"
                )

    def step_data(self, info: dict[str, Any]) -> jax.Array | None:
        return None if self.label_key is None else info[self.label_key].astype(jnp.float32)

    def inputs(self) -> DemoBatch | None:
        return self.demos

    def samples(
        self, key: jax.Array, inputs: Any, shape: tuple[int, ...], normalise: Callable[[jax.Array], jax.Array]
    ) -> DemoBatch | None:
        if inputs is None:
            return None
        return sample_minibatches(key, inputs, shape, normalise)

    def value(
        self, params: PPOParams, networks: PPONetworks, mean: jax.Array, data: Any, sample: Any
    ) -> tuple[jax.Array, dict[str, jax.Array]]:
        parts = {}
        if data is not None:
            parts["bc_loss"] = behaviour_cloning(mean, data)
        if sample is not None:
            parts["bc_demo_loss"] = behaviour_cloning(networks.policy(params, sample.obs)[0], sample.action)
        values = list(parts.values())
        total = values[0] if len(values) == 1 else values[0] + values[1]
        return total, parts


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


def put_inputs(terms: Sequence[LossTerm], placement: jax.sharding.Sharding) -> tuple[Any, ...]:
    """Every term's inputs on the devices (with ``placement``), once: arguments of the compiled period,
    not constants of its program."""
    return tuple(jax.tree.map(lambda x: put_global(x, placement), t.inputs()) for t in terms)


def config_term_names(cfg: Any) -> tuple[str, ...]:
    """The names of the loss terms a PPO config's settings ask for (``bc``), in the order they are added."""
    names = []
    if cfg.bc_coef > 0 or cfg.bc_coef_end > 0:
        names.append(BehaviourCloning.name)
    return tuple(names)


def terms_from_config(
    cfg: Any, label_key: str | None = None, demos: tuple[Any, Any] | None = None
) -> tuple[LossTerm, ...]:
    """The loss terms a [`PPOConfig`][harv_jax.ppo.config.PPOConfig] asks for, in the order they are added:
    behaviour cloning (``bc_coef`` -> ``bc_coef_end``, toward the env's ``info[label_key]`` and/or
    ``demos``). None of them: ``()``, the plain PPO loss.

    Raises:
        ValueError: behaviour cloning without labels or demonstrations, or demonstrations without it.
    """
    names = config_term_names(cfg)
    terms: list[LossTerm] = []
    if BehaviourCloning.name in names:
        terms.append(BehaviourCloning(cfg.bc_coef, cfg.bc_coef_end, label_key, demos))
    elif demos is not None:
        raise ValueError("demos are cloned with weight bc_coef; set bc_coef > 0 or bc_coef_end > 0")
    return tuple(terms)
