"""Acting in the environment: the env interface the trainer relies on, episode metrics, evaluation.

Environment interface (gymnax style, single env; the trainer vmaps it): ``env.reset(key, params) -> (obs
[O], state)``; ``env.step(key, state, action [A], params) -> (obs, state, reward, done, info)`` with
auto-reset inside ``step``, ``info["truncation"]`` (time limit; the episode is bootstrapped from
``V(info["final_obs"])``) and ``info["final_obs"]`` (last observation of the episode that just ended).

Asymmetric actor-critic: an env may also define ``critic_observation(state) -> [O]``, what the critic sees
in place of the policy's observation (same size and layout, e.g. the true state behind a policy that
observes through sensors and a filter), and then puts ``info["final_critic_obs"]`` beside ``final_obs``.
The trainer evaluates the value function on it (normalised with the policy's statistics); an env without it
(``critic_observation`` absent or None) trains the critic on the policy's observation.

Episode metrics: an ``EpisodeMetricsFn`` maps one env's ``info`` to a dict of scalars; the trainer averages
it over the episodes that end in a period (``episode/<name>``) and [`make_evaluate`][] records it at each
episode's end. The task side provides it (for the HARV env ``harv_jax.env.episode_metrics``); the default,
[`default_episode_metrics`][], takes the top-level scalar ``info`` entries.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

from harv_jax.ppo import normalize as obs_norm
from harv_jax.ppo.networks import PPONetworks, PPOParams, postprocess

#: One env's ``info`` -> dict of scalar episode metrics.
EpisodeMetricsFn = Callable[[dict[str, Any]], dict[str, jax.Array]]
#: info entries that are not per-episode statistics.
_RESERVED_INFO = ("truncation", "final_obs", "final_critic_obs")


def env_sizes(env: Any, env_params: Any) -> tuple[int, int]:
    """(observation_size, action_size) from env attributes, or from a traced reset."""
    obs_size = getattr(env, "observation_size", None)
    act_size = getattr(env, "action_size", None)
    if obs_size is None:
        obs, _ = jax.eval_shape(env.reset, jax.random.key(0), env_params)
        obs_size = obs.shape[-1]
    if act_size is None:
        raise ValueError("env must define action_size")
    return int(obs_size), int(act_size)


def critic_observer(env: Any) -> Callable[[Any], jax.Array] | None:
    """The env's ``critic_observation(state) -> [O]`` (module docstring), or None: the critic sees the
    policy's observation."""
    return getattr(env, "critic_observation", None)


def episode_length(env: Any) -> int:
    """The env's time limit in steps: ``env.episode_steps`` or ``env.config.episode_steps``.

    Used by ``stagger_episodes``, which also needs the env state to count the steps of its episode in a
    ``step`` field (truncation at ``step >= episode_steps``), as the HARV env's ``EnvState`` does.
    """
    n = getattr(env, "episode_steps", None) or getattr(getattr(env, "config", None), "episode_steps", None)
    if n is None:
        raise ValueError("stagger_episodes needs env.episode_steps or env.config.episode_steps")
    return int(n)


def default_episode_metrics(info: dict[str, Any]) -> dict[str, jax.Array]:
    """Per-env scalar entries of ``info`` (top level), as float32; the generic episode metrics."""
    return {
        k: jnp.asarray(v, jnp.float32)
        for k, v in info.items()
        if k not in _RESERVED_INFO and not isinstance(v, dict) and jnp.ndim(v) == 0
    }


def _first_step_keys(env: Any, env_params: Any, of_info: Callable[[Any], Any]) -> tuple[str, ...]:
    """Sorted keys of ``of_info(info)`` for one step's ``info`` (found by tracing, no compute)."""

    def one_step(key: jax.Array) -> Any:
        _, state = env.reset(key, env_params)
        return of_info(env.step(key, state, jnp.zeros((env.action_size,), jnp.float32), env_params)[4])

    return tuple(sorted(jax.eval_shape(one_step, jax.random.key(0))))


def env_info_keys(env: Any, env_params: Any) -> tuple[str, ...]:
    """Top-level keys of one step's ``info`` (found by tracing, no compute)."""
    return _first_step_keys(env, env_params, lambda info: info)


def episode_metric_names(env: Any, env_params: Any, ep_fn: EpisodeMetricsFn) -> tuple[str, ...]:
    """Names returned by ``ep_fn`` on one step's info (found by tracing, no compute)."""
    return _first_step_keys(env, env_params, ep_fn)


def make_evaluate(
    env: Any,
    networks: PPONetworks,
    num_envs: int,
    num_steps: int,
    normalize_obs: bool = True,
    episode_metrics_fn: EpisodeMetricsFn | None = None,
) -> Callable[..., dict[str, jax.Array]]:
    """Deterministic-policy evaluation: ``evaluate(key, params, normalizer, env_params) -> metrics``.

    Runs ``num_envs`` episodes from reset for ``num_steps`` steps with ``clip(mean)`` actions and records each
    env's first episode only. Returns per-episode arrays [num_envs]: ``return`` (unscaled, until the first
    episode end), ``ended`` (1 if it ended within num_steps), ``steps`` (steps of the first episode), the
    ``episode_metrics_fn`` entries at the first episode end (or at the last step if it did not end), and
    ``mean/<name>``: each of those entries averaged over the steps of the first episode (evaluated after
    every step, as if the episode ended there). Not jitted: wrap it in ``jax.jit``.
    """
    ep_fn = episode_metrics_fn or default_episode_metrics

    def evaluate(
        key: jax.Array, params: PPOParams, normalizer: obs_norm.RunningStats, env_params: Any
    ) -> dict:
        key_reset, key_steps = jax.random.split(key)
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key_reset, num_envs), env_params)

        def step(carry: tuple, key: jax.Array) -> tuple[tuple, None]:
            state, obs, ret, alive, last, total, n = carry
            obs_in = obs_norm.normalize(normalizer, obs) if normalize_obs else obs
            mean, _ = networks.policy(params, obs_in)
            next_obs, state, reward, done, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
                jax.random.split(key, num_envs), state, postprocess(mean), env_params
            )
            ended = jnp.maximum(done.astype(jnp.float32), info["truncation"].astype(jnp.float32))
            ret = ret + alive * reward.astype(jnp.float32)
            metrics = jax.vmap(ep_fn)(info)
            last = {k: jnp.where(alive > 0, v, last[k]) for k, v in metrics.items()}
            total = {k: total[k] + alive * v for k, v in metrics.items()}
            n = n + alive
            alive = alive * (1.0 - ended)
            return (state, next_obs.astype(jnp.float32), ret, alive, last, total, n), None

        names = episode_metric_names(env, env_params, ep_fn)
        last0 = {k: jnp.zeros((num_envs,), jnp.float32) for k in names}
        ones = jnp.ones((num_envs,), jnp.float32)
        carry0 = (state, obs.astype(jnp.float32), 0.0 * ones, ones, last0, last0, 0.0 * ones)
        (_, _, ret, alive, last, total, n), _ = jax.lax.scan(
            step, carry0, jax.random.split(key_steps, num_steps)
        )
        means = {f"mean/{k}": v / jnp.maximum(n, 1.0) for k, v in total.items()}
        return {"return": ret, "ended": 1.0 - alive, "steps": n, **last, **means}

    return evaluate
