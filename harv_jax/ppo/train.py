"""The compiled PPO training step (brax style), multi-seed by vmap, multi-device by ``jax.sharding``.

``make_train(env, cfg)`` returns a [`Trainer`][] whose ``period(state, env_params)`` is jitted once and
runs ``updates_per_period(cfg)`` PPO updates inside a ``lax.scan``; each update is a rollout of ``num_envs``
vmapped envs for ``unroll`` steps (``lax.scan``), GAE, then ``epochs`` x ``minibatches`` Adam steps
(``lax.scan``). All of this is vmapped over ``num_seeds`` independent learners. The host loop that calls it
once per period (fetch metrics, report progress, checkpoint) is [`harv_jax.ppo.runner.run_training`][];
the env interface and the episode-metrics hook are described in [`harv_jax.ppo.acting`][], the device
layout in `harv_jax.ppo.sharding`.

Staggered episodes (``cfg.stagger_episodes``): all envs reset together at init, so without it their episodes
stay in step; every update then sees one phase of the episode only (all envs in the initial transient, or
all settled), and the time-limit truncations of all envs fall into the same update. With it, ``init`` sets
each env's episode step counter (``env_state.step``) to a uniform draw in ``[0, episode_steps)``, so the first
episodes are truncated at spread times and episode phases stay mixed from then on (legged_gym's random
episode start). It needs the env's time limit (``env.episode_steps`` or ``env.config.episode_steps``) and a
``step`` field in the env state.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import optax

from harv_jax.ppo import config as ppo_config
from harv_jax.ppo import normalize as obs_norm
from harv_jax.ppo import sharding, shuffle
from harv_jax.ppo.acting import (
    EpisodeMetricsFn,
    critic_observer,
    default_episode_metrics,
    env_info_keys,
    env_sizes,
    episode_length,
    episode_metric_names,
)
from harv_jax.ppo.config import PPOConfig
from harv_jax.ppo.loss_terms import LossTerm, TermContext, config_term_names, put_inputs
from harv_jax.ppo.losses import (
    LossWeights,
    PPOBatch,
    PPOLossSettings,
    compute_gae,
    ppo_loss,
    successor_values,
)
from harv_jax.ppo.networks import (
    PPOParams,
    gaussian_log_prob,
    make_ppo_networks,
    postprocess,
    sample_raw_action,
)
from harv_jax.ppo.train_state import Metrics, Rollout, Trainer, TrainingState

__all__ = ["BoundPeriod", "make_optimizer", "make_train", "seed_keys"]


def make_optimizer(cfg: PPOConfig) -> optax.GradientTransformation:
    """Adam (eps 1e-5, as SB3) after global-norm clipping; constant or linearly decaying learning rate."""
    if cfg.lr_schedule == "linear":
        n_steps = ppo_config.total_updates(cfg) * cfg.epochs * cfg.minibatches
        lr: float | optax.Schedule = optax.linear_schedule(cfg.lr, 0.0, n_steps)
    else:
        lr = cfg.lr
    return optax.chain(optax.clip_by_global_norm(cfg.max_grad_norm), optax.adam(lr, eps=1e-5))


def make_train(
    env: Any,
    cfg: PPOConfig,
    env_params: Any,
    devices: Sequence[jax.Device] | None = None,
    episode_metrics_fn: EpisodeMetricsFn | None = None,
    terms: Sequence[LossTerm] = (),
) -> Trainer:
    """Build the jitted init and period functions for ``env`` and ``cfg``.

    Args:
        env: gymnax-style environment (see [`harv_jax.ppo.acting`][]).
        cfg: validated PPO config; its shapes and loop lengths are closed over (static).
        env_params: an example of the env parameter pytree (used for shapes only; the real one is an argument
            of ``init``/``period`` so that it can change without recompiling).
        devices: devices to shard the envs over (default `default_devices`:
            all accelerators, or one CPU device).
        episode_metrics_fn: one env's ``info`` -> dict of scalars, averaged over the episodes that end in a
            period and reported as ``episode/<name>`` (default [`default_episode_metrics`][]).
        terms: loss terms added to the PPO loss, in this order ([`harv_jax.ppo.loss_terms`][]); their
            inputs are put on the devices once and passed into the compiled period. None: the plain PPO
            loss.

    Returns:
        A [`Trainer`][].
    """
    devices = list(sharding.default_devices() if devices is None else devices)
    ppo_config.check_devices(cfg, len(devices))
    episode_steps = episode_length(env) if cfg.stagger_episodes else 0
    mesh = sharding.env_mesh(devices)
    obs_size, act_size = env_sizes(env, env_params)
    networks = make_ppo_networks(obs_size, act_size, cfg.hidden_sizes, cfg.init_log_std)
    optimizer = make_optimizer(cfg)
    ep_fn = episode_metrics_fn or default_episode_metrics
    info_keys = episode_metric_names(env, env_params, ep_fn)
    n_envs, unroll = cfg.num_envs, cfg.unroll
    n_batch = ppo_config.batch_size(cfg)
    mb_size = ppo_config.minibatch_size(cfg)
    clip_value = cfg.clip_value_eps if cfg.clip_value_eps > 0 else None
    batch_sharding = sharding.batch_sharding(mesh)
    critic_fn = critic_observer(env)  # None: the critic sees the policy's observation

    terms = tuple(terms)
    missing = [n for n in config_term_names(cfg) if n not in [t.name for t in terms]]
    if missing:  # e.g. bc_coef > 0 without a behaviour-cloning term: it would silently not clone
        raise ValueError(
            f"the config asks for the loss terms {missing}; pass them: make_train(..., "
            "terms=harv_jax.ppo.loss_terms.terms_from_config(cfg, ...))"
        )
    for term in terms:
        term.check(env_info_keys(env, env_params), obs_size, act_size)
    n_updates = ppo_config.total_updates(cfg)
    settings = PPOLossSettings(cfg.clip_eps, cfg.vf_coef, cfg.ent_coef, clip_value, cfg.normalize_advantage)

    def loss_weights(update_step: jax.Array) -> LossWeights:
        """The actor factor (0 before ``pg_start`` of the run, 1 after) and each term's coefficient."""
        frac = update_step.astype(jnp.float32) / n_updates
        actor = (frac >= cfg.pg_start).astype(jnp.float32) if cfg.pg_start > 0 else None
        return LossWeights(actor, tuple(t.coef(frac) for t in terms))

    def normalise(normalizer: obs_norm.RunningStats, obs: jax.Array) -> jax.Array:
        return obs_norm.normalize(normalizer, obs) if cfg.normalize_observations else obs

    def critic_input(normalizer: obs_norm.RunningStats, env_state: Any, obs_in: jax.Array) -> jax.Array:
        """The critic's (normalised) input for the envs' states: the policy's ``obs_in`` or the env's own."""
        if critic_fn is None:
            return obs_in
        return normalise(normalizer, jax.vmap(critic_fn)(env_state).astype(jnp.float32))

    def init_one(key: jax.Array, params: PPOParams, env_params: Any) -> TrainingState:
        _, key_env, key_train = jax.random.split(key, 3)
        key_stagger = jax.random.fold_in(key_env, 1)  # a new stream: the other draws stay as without stagger
        obs, env_state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(key_env, n_envs), env_params)
        obs = obs.astype(jnp.float32)
        if cfg.stagger_episodes:  # first episodes end at uniformly spread times (legged_gym's random start)
            offsets = jax.random.randint(key_stagger, (n_envs,), 0, episode_steps, env_state.step.dtype)
            env_state = env_state.replace(step=offsets)
        normalizer = obs_norm.init_stats(obs_size)
        if cfg.normalize_observations:  # start from the reset distribution, not the identity
            normalizer = obs_norm.update_stats(normalizer, obs)
        return TrainingState(
            params=params,
            opt_state=optimizer.init(params),
            normalizer=normalizer,
            env_state=env_state,
            obs=obs,
            episode_return=jnp.zeros((n_envs,), jnp.float32),
            episode_length=jnp.zeros((n_envs,), jnp.int32),
            key=key_train,
            update_step=jnp.zeros((), jnp.int32),
        )

    def rollout(
        state: TrainingState, key: jax.Array, env_params: Any
    ) -> tuple[TrainingState, Rollout, Metrics]:
        params, normalizer = state.params, state.normalizer
        zeros = {k: jnp.zeros((), jnp.float32) for k in info_keys}
        ep0 = {
            "episodes": jnp.zeros((), jnp.float32),
            "return_sum": jnp.zeros((), jnp.float32),
            "length_sum": jnp.zeros((), jnp.float32),
        }
        ep0.update({f"info_{k}": v for k, v in zeros.items()})

        def step(carry: tuple, key: jax.Array) -> tuple[tuple, Rollout]:
            env_state, obs, ep_ret, ep_len, ep = carry
            key_act, key_env = jax.random.split(key)
            obs_in = normalise(normalizer, obs)
            mean, log_std = networks.policy(params, obs_in)
            raw = sample_raw_action(key_act, mean, log_std)
            log_prob = gaussian_log_prob(mean, log_std, raw)
            critic_in = critic_input(normalizer, env_state, obs_in)
            value = networks.value(params, critic_in)
            next_obs, env_state, reward, done, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
                jax.random.split(key_env, n_envs), env_state, postprocess(raw), env_params
            )
            reward = reward.astype(jnp.float32)
            trunc = info["truncation"].astype(jnp.float32)
            ended = jnp.maximum(done.astype(jnp.float32), trunc)
            term = ended * (1.0 - trunc)
            final_key = "final_obs" if critic_fn is None else "final_critic_obs"
            final_value = networks.value(params, normalise(normalizer, info[final_key].astype(jnp.float32)))
            ep_ret = ep_ret + reward
            ep_len = ep_len + 1
            ep = dict(ep)
            ep["episodes"] += jnp.sum(ended)
            ep["return_sum"] += jnp.sum(ended * ep_ret)
            ep["length_sum"] += jnp.sum(ended * ep_len.astype(jnp.float32))
            ep_metrics = jax.vmap(ep_fn)(info)
            for k in info_keys:
                ep[f"info_{k}"] += jnp.sum(ended * ep_metrics[k])
            ep_ret = ep_ret * (1.0 - ended)
            ep_len = jnp.where(ended > 0, 0, ep_len)
            kept = tuple(t.step_data(info) for t in terms)
            transition = Rollout(
                obs_in,
                raw,
                log_prob,
                value,
                reward,
                term,
                trunc,
                final_value,
                obs,
                kept,
                None if critic_fn is None else critic_in,
            )
            return (env_state, next_obs.astype(jnp.float32), ep_ret, ep_len, ep), transition

        carry0 = (state.env_state, state.obs, state.episode_return, state.episode_length, ep0)
        (env_state, obs, ep_ret, ep_len, ep), traj = jax.lax.scan(step, carry0, jax.random.split(key, unroll))
        state = state.replace(env_state=env_state, obs=obs, episode_return=ep_ret, episode_length=ep_len)
        return state, traj, ep

    def sgd_step(
        carry: tuple, batches: tuple[PPOBatch, tuple[Any, ...]], weights: LossWeights
    ) -> tuple[tuple, Metrics]:
        params, opt_state = carry
        batch, samples = batches
        batch = jax.tree.map(lambda x: jax.lax.with_sharding_constraint(x, batch_sharding), batch)
        batch = batch._replace(term_samples=samples)
        grad_fn = jax.value_and_grad(ppo_loss, has_aux=True)
        (_, metrics), grads = grad_fn(params, batch, networks, settings, terms, weights)
        updates, opt_state = optimizer.update(grads, opt_state, params)
        params = optax.apply_updates(params, updates)
        metrics["grad_norm"] = optax.tree.norm(grads)
        return (params, opt_state), metrics

    def update(
        state: TrainingState, env_params: Any, inputs: tuple[Any, ...]
    ) -> tuple[TrainingState, Metrics]:
        key, key_rollout, key_sgd = jax.random.split(state.key, 3)
        state, traj, ep = rollout(state, key_rollout, env_params)
        last_in = critic_input(state.normalizer, state.env_state, normalise(state.normalizer, state.obs))
        last_value = networks.value(state.params, last_in)
        next_values = successor_values(
            traj.value, last_value, traj.final_value, traj.termination, traj.truncation
        )
        advantages, targets = compute_gae(
            traj.reward * cfg.reward_scale,
            traj.value,
            next_values,
            traj.termination,
            traj.truncation,
            cfg.gamma,
            cfg.gae_lambda,
        )
        last_obs = normalise(state.normalizer, state.obs)
        term_data = tuple(
            t.transition_data(
                TermContext(traj.obs, traj.termination, traj.truncation, last_obs, kept, key_sgd)
            )
            for t, kept in zip(terms, traj.term_data, strict=True)
        )
        # [T, N, ...] -> env-major [N * T, ...] so that the sharded env axis stays the leading block.
        data = PPOBatch(
            traj.obs,
            traj.raw_action,
            traj.log_prob,
            traj.value,
            advantages,
            targets,
            term_data,
            critic_obs=traj.critic_obs,
        )
        weights = loss_weights(state.update_step)
        data = jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1).reshape((n_batch,) + x.shape[2:]), data)
        # per-minibatch samples of the terms' inputs [epochs, minibatches, mb_size, ...]
        shape = (cfg.epochs, cfg.minibatches, mb_size)
        samples = tuple(
            t.samples(key_sgd, x, shape, partial(normalise, state.normalizer))
            for t, x in zip(terms, inputs, strict=True)
        )

        def epoch(carry: tuple, xs: tuple[jax.Array, Any]) -> tuple[tuple, Metrics]:
            key, samples_epoch = xs
            perm = shuffle.permutation(key, n_batch)  # = jax.random.permutation, faster
            shuffled = jax.tree.map(
                lambda x: jnp.take(x, perm, axis=0).reshape((cfg.minibatches, mb_size) + x.shape[1:]), data
            )
            return jax.lax.scan(lambda c, b: sgd_step(c, b, weights), carry, (shuffled, samples_epoch))

        (params, opt_state), metrics = jax.lax.scan(
            epoch, (state.params, state.opt_state), (jax.random.split(key_sgd, cfg.epochs), samples)
        )
        normalizer = state.normalizer
        if cfg.normalize_observations:
            normalizer = obs_norm.update_stats(normalizer, traj.raw_obs)
        state = state.replace(
            params=params,
            opt_state=opt_state,
            normalizer=normalizer,
            key=key,
            update_step=state.update_step + 1,
        )
        metrics = jax.tree.map(jnp.mean, metrics)
        metrics["value_target_mean"] = jnp.mean(targets)
        metrics["reward_mean"] = jnp.mean(traj.reward)
        metrics["termination_rate"] = jnp.mean(traj.termination)
        return state, {**metrics, **{f"ep_{k}": v for k, v in ep.items()}}

    def period_one(
        state: TrainingState, env_params: Any, inputs: tuple[Any, ...]
    ) -> tuple[TrainingState, Metrics]:
        state, metrics = jax.lax.scan(
            lambda s, _: update(s, env_params, inputs), state, None, length=ppo_config.updates_per_period(cfg)
        )
        out = {k: jnp.mean(v) for k, v in metrics.items() if not k.startswith("ep_")}
        ep = {k[3:]: jnp.sum(v) for k, v in metrics.items() if k.startswith("ep_")}
        n_ep = ep["episodes"]
        safe = jnp.maximum(n_ep, 1.0)
        nan = jnp.asarray(jnp.nan, jnp.float32)
        out["episodes"] = n_ep
        out["episode_return"] = jnp.where(n_ep > 0, ep["return_sum"] / safe, nan)
        out["episode_length"] = jnp.where(n_ep > 0, ep["length_sum"] / safe, nan)
        for k in info_keys:
            out[f"episode/{k}"] = jnp.where(n_ep > 0, ep[f"info_{k}"] / safe, nan)
        return state, out

    traces = [0]

    def init_all(keys: jax.Array, env_params: Any) -> TrainingState:
        # The networks of the seeds are initialised one after the other (lax.map), never as one batch: a
        # batched orthogonal init is a batched LAPACK QR per layer, and XLA:CPU deadlocks when several of
        # those run at once (see ``PPONetworks.init_seeds``). Same numbers as a vmap, seed by seed.
        params = networks.init_seeds(jax.vmap(lambda k: jax.random.split(k, 3)[0])(keys))
        return jax.vmap(init_one, in_axes=(0, 0, None))(keys, params, env_params)

    def period_all(
        state: TrainingState, env_params: Any, inputs: tuple[Any, ...]
    ) -> tuple[TrainingState, Metrics]:
        traces[0] += 1  # Python side effect: runs only while tracing
        return jax.vmap(period_one, in_axes=(0, None, None))(state, env_params, inputs)

    # Shardings: env-axis leaves [S, N, ...] split over devices on axis 1; everything else replicated.
    replicated = sharding.replicated(mesh)
    env_sharded = sharding.env_sharded(mesh)
    keys_example = jax.random.split(jax.random.key(0), cfg.num_seeds)
    abstract = jax.eval_shape(init_all, keys_example, env_params)
    state_shardings = TrainingState(
        params=jax.tree.map(lambda _: replicated, abstract.params),
        opt_state=jax.tree.map(lambda _: replicated, abstract.opt_state),
        normalizer=jax.tree.map(lambda _: replicated, abstract.normalizer),
        env_state=jax.tree.map(lambda _: env_sharded, abstract.env_state),
        obs=env_sharded,
        episode_return=env_sharded,
        episode_length=env_sharded,
        key=replicated,
        update_step=replicated,
    )
    init = jax.jit(
        init_all,
        in_shardings=(replicated, replicated),
        out_shardings=state_shardings,
    )
    period_jit = jax.jit(
        period_all,
        in_shardings=(state_shardings, replicated, replicated),
        out_shardings=(state_shardings, replicated),
        donate_argnums=0,
    )
    period = BoundPeriod(period_jit, put_inputs(terms, replicated))
    return Trainer(init, period, networks, mesh, state_shardings, lambda: traces[0])


class BoundPeriod:
    """``period(state, env_params)``: the compiled period with the loss terms' inputs bound (arrays put on
    the devices once, arguments of its program rather than constants); ``lower`` as a jitted function's."""

    def __init__(self, jitted: Any, inputs: tuple[Any, ...]) -> None:
        self.jitted, self.inputs = jitted, inputs

    def __call__(self, state: TrainingState, env_params: Any) -> tuple[TrainingState, Metrics]:
        return self.jitted(state, env_params, self.inputs)

    def lower(self, state: Any, env_params: Any) -> Any:
        """``jax.jit(...).lower`` of the period at these arguments."""
        return self.jitted.lower(state, env_params, self.inputs)


def seed_keys(key: jax.Array, num_seeds: int) -> jax.Array:
    """Per-seed keys [S]: ``fold_in(key, s)`` for s = 0..S-1 (seed s is reproducible on its own)."""
    return jax.vmap(lambda s: jax.random.fold_in(key, s))(jnp.arange(num_seeds))
