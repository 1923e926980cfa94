"""PPO training in one compiled graph (brax style), multi-seed by vmap, multi-device by ``jax.sharding``.

``make_train(env, cfg)`` returns a :class:`Trainer` whose ``period(state, env_params)`` is jitted once and
runs ``updates_per_period(cfg)`` PPO updates inside a ``lax.scan``; each update is a rollout of ``num_envs``
vmapped envs for ``unroll`` steps (``lax.scan``), GAE, then ``epochs`` x ``minibatches`` Adam steps
(``lax.scan``). All of this is vmapped over ``num_seeds`` independent learners. The host loop
(:func:`run_training`) runs once per period: fetch metrics, report progress, checkpoint.

Environment interface (gymnax style, single env; the trainer vmaps it): ``env.reset(key, params) -> (obs
[O], state)``; ``env.step(key, state, action [A], params) -> (obs, state, reward, done, info)`` with
auto-reset inside ``step``, ``info["truncation"]`` (time limit; the episode is bootstrapped from
``V(info["final_obs"])``) and ``info["final_obs"]`` (last observation of the episode that just ended).
``episode_metrics_fn(info)`` (default: the top-level scalar ``info`` entries; for the HARV env
:func:`harv_episode_metrics`) is averaged over the episodes that end in a period, as ``episode/<name>``.

Staggered episodes (``cfg.stagger_episodes``): all envs reset together at init, so without it their episodes
stay in step; every update then sees one phase of the episode only (all envs in the initial transient, or
all settled), and the time-limit truncations of all envs fall into the same update. With it, ``init`` sets
each env's episode step counter (``env_state.step``) to a uniform draw in ``[0, episode_steps)``, so the first
episodes are truncated at spread times and episode phases stay mixed from then on (legged_gym's random
episode start). It needs the env's time limit (``env.episode_steps`` or ``env.config.episode_steps``) and a
``step`` field in the env state.

Multi-device: the env axis of the env state, observations and episode accumulators is sharded over a 1-D
mesh ``("envs",)``; parameters, optimizer state and normaliser are replicated. Minibatches are constrained
to be sharded along their batch axis, so each device computes the loss on its slice and XLA's partitioner
inserts the all-reduce that averages gradients. The algorithm does not depend on the device count (same PRNG
streams, global permutation), so 2-device and 1-device training agree to floating-point reduction order
(tested).

Multi-host (Python API; the ``harv-jax train`` command is single-process): start one process per host with
the same script and, before anything creates a jax array, call ``jax.distributed.initialize(
coordinator_address="host0:1234", num_processes=P, process_id=i)`` (on SLURM, Open MPI or TPU the arguments
are found automatically); then ``make_train(..., devices=jax.devices())`` builds the mesh over all global
devices (the default, :func:`default_devices`, does the same on accelerators; on CPU it takes one local
device), ``num_envs`` must divide by ``jax.device_count()``, and every process calls ``run_training`` with the
same arguments. Metrics and parameters are replicated, so every process sees the same history;
checkpoints all-gather the env-sharded state and only process 0 writes them (``run_dir`` must be on a
filesystem all processes share for ``resume=True``). Tested with 2 processes x 1 CPU device (gloo):
half a run + resume equals one process on one device to 1e-4 (``tests/test_train.py``, marked slow).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import struct
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from harv_jax.ppo import config as ppo_config
from harv_jax.ppo import normalize as obs_norm
from harv_jax.ppo.config import PPOConfig
from harv_jax.ppo.losses import PPOBatch, compute_gae, ppo_loss, successor_values
from harv_jax.ppo.networks import (
    PPONetworks,
    PPOParams,
    gaussian_log_prob,
    make_ppo_networks,
    postprocess,
    sample_raw_action,
)
from harv_jax.units import RAD_PER_DEG

Metrics = dict[str, jax.Array]
ENV_AXIS = "envs"
#: info entries that are not per-episode statistics.
_RESERVED_INFO = ("truncation", "final_obs")


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


class Trainer(NamedTuple):
    """What :func:`make_train` returns.

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


def episode_length(env: Any) -> int:
    """The env's time limit in steps: ``env.episode_steps`` or ``env.config.episode_steps``.

    Used by ``stagger_episodes``, which also needs the env state to count the steps of its episode in a
    ``step`` field (truncation at ``step >= episode_steps``), as the HARV env's ``EnvState`` does.
    """
    n = getattr(env, "episode_steps", None) or getattr(getattr(env, "config", None), "episode_steps", None)
    if n is None:
        raise ValueError("stagger_episodes needs env.episode_steps or env.config.episode_steps")
    return int(n)


def make_optimizer(cfg: PPOConfig) -> optax.GradientTransformation:
    """Adam (eps 1e-5, as SB3) after global-norm clipping; constant or linearly decaying learning rate."""
    if cfg.lr_schedule == "linear":
        n_steps = ppo_config.total_updates(cfg) * cfg.epochs * cfg.minibatches
        lr: float | optax.Schedule = optax.linear_schedule(cfg.lr, 0.0, n_steps)
    else:
        lr = cfg.lr
    return optax.chain(optax.clip_by_global_norm(cfg.max_grad_norm), optax.adam(lr, eps=1e-5))


def _episode_metric_names(env: Any, env_params: Any, ep_fn: Callable) -> tuple[str, ...]:
    """Names returned by ``ep_fn`` on one step's info (found by tracing, no compute)."""

    def one_step(key: jax.Array) -> Any:
        _, state = env.reset(key, env_params)
        info = env.step(key, state, jnp.zeros((env.action_size,), jnp.float32), env_params)[4]
        return ep_fn(info)

    return tuple(sorted(jax.eval_shape(one_step, jax.random.key(0))))


def default_episode_metrics(info: dict[str, Any]) -> dict[str, jax.Array]:
    """Per-env scalar entries of ``info`` (top level), as float32; the generic episode metrics."""
    return {k: jnp.asarray(v, jnp.float32) for k, v in info.items()
            if k not in _RESERVED_INFO and not isinstance(v, dict) and jnp.ndim(v) == 0}  # fmt: skip


#: Recovery tolerances used for the training-time recovery metric (the issue's criterion, instantaneous).
ALPHA_TOL_RAD = 2.0 * RAD_PER_DEG
BETA_TOL_RAD = 1.0 * RAD_PER_DEG
MU_TOL_RAD = 2.0 * RAD_PER_DEG
OMEGA_TOL_RADPS = 0.17


def harv_episode_metrics(info: dict[str, Any]) -> dict[str, jax.Array]:
    """Episode-end metrics of the HARV recovery env, from one env's ``info`` (scalars).

    ``final_omega_radps``: ||(p, q, r)|| of the state the episode ended in; ``recovered``: 1 if the episode
    was not terminated and its final state meets |e_alpha| < 2 deg, |e_beta| < 1 deg, |e_mu| < 2 deg and
    ||omega|| < 0.17 rad/s (the issue's criterion at the last step only, without the 10 s hold);
    ``alpha_ok``: |e_alpha| < 2 deg at the end, not terminated; ``terminated``: left the envelope;
    ``final_omega_alive_radps`` and ``final_abs_e_alpha_rad``: ||omega|| and |e_alpha| at the end if not
    terminated, else 0 (divide their mean by ``1 - terminated`` for the mean over surviving episodes).
    """
    x = info["final_state_wind"]
    target = info["final_obs"][8:11]
    omega = jnp.sqrt(jnp.sum(jnp.square(x[3:6])))
    e_alpha = jnp.abs(x[1] - target[0])
    e_beta = jnp.abs(x[2] - target[1])
    e_mu = jnp.abs(jnp.mod(x[6] - target[2] + jnp.pi, 2.0 * jnp.pi) - jnp.pi)
    ok = ~info["terminated"]
    alpha_ok = ok & (e_alpha < ALPHA_TOL_RAD)
    recovered = alpha_ok & (e_beta < BETA_TOL_RAD) & (e_mu < MU_TOL_RAD) & (omega < OMEGA_TOL_RADPS)
    f32 = jnp.float32
    return {
        "recovered": recovered.astype(f32),
        "alpha_ok": alpha_ok.astype(f32),
        "final_omega_radps": jnp.where(jnp.isfinite(omega), omega, 0.0).astype(f32),
        "terminated": info["terminated"].astype(f32),
        "final_omega_alive_radps": jnp.where(ok & jnp.isfinite(omega), omega, 0.0).astype(f32),
        "final_abs_e_alpha_rad": jnp.where(ok & jnp.isfinite(e_alpha), e_alpha, 0.0).astype(f32),
    }


def default_devices() -> list[jax.Device]:
    """Devices to shard envs over by default: all of them on accelerators, one on CPU.

    On CPU one device already uses every core (XLA's intra-op thread pool). Several host devices
    (``--xla_force_host_platform_device_count``) combined with several seeds deadlocked inside XLA's CPU
    runtime in our runs with the HARV env (jax 0.10.2; the toy env did not), so CPU sharding is opt-in:
    pass ``devices`` explicitly.
    """
    devices = jax.devices()
    return devices[:1] if devices[0].platform == "cpu" else devices


def make_train(
    env: Any,
    cfg: PPOConfig,
    env_params: Any,
    devices: Sequence[jax.Device] | None = None,
    episode_metrics_fn: Callable[[dict[str, Any]], dict[str, jax.Array]] | None = None,
) -> Trainer:
    """Build the jitted init and period functions for ``env`` and ``cfg``.

    Args:
        env: gymnax-style environment (see module docstring).
        cfg: validated PPO config; its shapes and loop lengths are closed over (static).
        env_params: an example of the env parameter pytree (used for shapes only; the real one is an argument
            of ``init``/``period`` so that it can change without recompiling).
        devices: devices to shard the envs over (default :func:`default_devices`: all accelerators, or one
            CPU device).
        episode_metrics_fn: one env's ``info`` -> dict of scalars, averaged over the episodes that end in a
            period and reported as ``episode/<name>`` (default :func:`default_episode_metrics`).

    Returns:
        A :class:`Trainer`.
    """
    devices = list(default_devices() if devices is None else devices)
    ppo_config.check_devices(cfg, len(devices))
    episode_steps = episode_length(env) if cfg.stagger_episodes else 0
    mesh = Mesh(np.asarray(devices), (ENV_AXIS,))
    obs_size, act_size = env_sizes(env, env_params)
    networks = make_ppo_networks(obs_size, act_size, cfg.hidden_sizes, cfg.init_log_std)
    optimizer = make_optimizer(cfg)
    ep_fn = episode_metrics_fn or default_episode_metrics
    info_keys = _episode_metric_names(env, env_params, ep_fn)
    n_envs, unroll = cfg.num_envs, cfg.unroll
    n_batch = ppo_config.batch_size(cfg)
    mb_size = ppo_config.minibatch_size(cfg)
    clip_value = cfg.clip_value_eps if cfg.clip_value_eps > 0 else None
    batch_sharding = NamedSharding(mesh, P(ENV_AXIS))

    def normalise(normalizer: obs_norm.RunningStats, obs: jax.Array) -> jax.Array:
        return obs_norm.normalize(normalizer, obs) if cfg.normalize_observations else obs

    def init_one(key: jax.Array, env_params: Any) -> TrainingState:
        key_params, key_env, key_train = jax.random.split(key, 3)
        key_stagger = jax.random.fold_in(key_env, 1)  # a new stream: the other draws stay as without stagger
        params = networks.init(key_params)
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
        ep0 = {"episodes": jnp.zeros((), jnp.float32), "return_sum": jnp.zeros((), jnp.float32),
               "length_sum": jnp.zeros((), jnp.float32)}  # fmt: skip
        ep0.update({f"info_{k}": v for k, v in zeros.items()})

        def step(carry: tuple, key: jax.Array) -> tuple[tuple, Rollout]:
            env_state, obs, ep_ret, ep_len, ep = carry
            key_act, key_env = jax.random.split(key)
            obs_in = normalise(normalizer, obs)
            mean, log_std = networks.policy(params, obs_in)
            raw = sample_raw_action(key_act, mean, log_std)
            log_prob = gaussian_log_prob(mean, log_std, raw)
            value = networks.value(params, obs_in)
            next_obs, env_state, reward, done, info = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
                jax.random.split(key_env, n_envs), env_state, postprocess(raw), env_params
            )
            reward = reward.astype(jnp.float32)
            trunc = info["truncation"].astype(jnp.float32)
            ended = jnp.maximum(done.astype(jnp.float32), trunc)
            term = ended * (1.0 - trunc)
            final_value = networks.value(params, normalise(normalizer, info["final_obs"].astype(jnp.float32)))
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
            transition = Rollout(obs_in, raw, log_prob, value, reward, term, trunc, final_value, obs)
            return (env_state, next_obs.astype(jnp.float32), ep_ret, ep_len, ep), transition

        carry0 = (state.env_state, state.obs, state.episode_return, state.episode_length, ep0)
        (env_state, obs, ep_ret, ep_len, ep), traj = jax.lax.scan(step, carry0, jax.random.split(key, unroll))
        state = state.replace(env_state=env_state, obs=obs, episode_return=ep_ret, episode_length=ep_len)
        return state, traj, ep

    def sgd_step(carry: tuple, batch: PPOBatch) -> tuple[tuple, Metrics]:
        params, opt_state = carry
        batch = jax.tree.map(lambda x: jax.lax.with_sharding_constraint(x, batch_sharding), batch)
        grad_fn = jax.value_and_grad(ppo_loss, has_aux=True)
        (_, metrics), grads = grad_fn(
            params, batch, networks, clip_eps=cfg.clip_eps, vf_coef=cfg.vf_coef, ent_coef=cfg.ent_coef,
            clip_value_eps=clip_value, normalize_advantage=cfg.normalize_advantage,
        )  # fmt: skip
        updates, opt_state = optimizer.update(grads, opt_state, params)
        params = optax.apply_updates(params, updates)
        metrics["grad_norm"] = optax.tree.norm(grads)
        return (params, opt_state), metrics

    def update(state: TrainingState, env_params: Any) -> tuple[TrainingState, Metrics]:
        key, key_rollout, key_sgd = jax.random.split(state.key, 3)
        state, traj, ep = rollout(state, key_rollout, env_params)
        last_value = networks.value(state.params, normalise(state.normalizer, state.obs))
        next_values = successor_values(
            traj.value, last_value, traj.final_value, traj.termination, traj.truncation
        )
        advantages, targets = compute_gae(
            traj.reward * cfg.reward_scale, traj.value, next_values, traj.termination, traj.truncation,
            cfg.gamma, cfg.gae_lambda,
        )  # fmt: skip
        # [T, N, ...] -> env-major [N * T, ...] so that the sharded env axis stays the leading block.
        data = PPOBatch(traj.obs, traj.raw_action, traj.log_prob, traj.value, advantages, targets)
        data = jax.tree.map(lambda x: jnp.swapaxes(x, 0, 1).reshape((n_batch,) + x.shape[2:]), data)

        def epoch(carry: tuple, key: jax.Array) -> tuple[tuple, Metrics]:
            perm = jax.random.permutation(key, n_batch)
            shuffled = jax.tree.map(
                lambda x: jnp.take(x, perm, axis=0).reshape((cfg.minibatches, mb_size) + x.shape[1:]), data
            )
            return jax.lax.scan(sgd_step, carry, shuffled)

        (params, opt_state), metrics = jax.lax.scan(
            epoch, (state.params, state.opt_state), jax.random.split(key_sgd, cfg.epochs)
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

    def period_one(state: TrainingState, env_params: Any) -> tuple[TrainingState, Metrics]:
        state, metrics = jax.lax.scan(lambda s, _: update(s, env_params), state, None,
                                      length=ppo_config.updates_per_period(cfg))  # fmt: skip
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

    def period_all(state: TrainingState, env_params: Any) -> tuple[TrainingState, Metrics]:
        traces[0] += 1  # Python side effect: runs only while tracing
        return jax.vmap(period_one, in_axes=(0, None))(state, env_params)

    # Shardings: env-axis leaves [S, N, ...] split over devices on axis 1; everything else replicated.
    replicated = NamedSharding(mesh, P())
    env_sharded = NamedSharding(mesh, P(None, ENV_AXIS))
    keys_example = jax.random.split(jax.random.key(0), cfg.num_seeds)
    abstract = jax.eval_shape(jax.vmap(init_one, in_axes=(0, None)), keys_example, env_params)
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
        jax.vmap(init_one, in_axes=(0, None)),
        in_shardings=(replicated, replicated),
        out_shardings=state_shardings,
    )
    period = jax.jit(
        period_all,
        in_shardings=(state_shardings, replicated),
        out_shardings=(state_shardings, replicated),
        donate_argnums=0,
    )
    return Trainer(init, period, networks, mesh, state_shardings, lambda: traces[0])


def seed_keys(key: jax.Array, num_seeds: int) -> jax.Array:
    """Per-seed keys [S]: ``fold_in(key, s)`` for s = 0..S-1 (seed s is reproducible on its own)."""
    return jax.vmap(lambda s: jax.random.fold_in(key, s))(jnp.arange(num_seeds))


def check_init_policy(state: Any, params: PPOParams, normalizer: obs_norm.RunningStats) -> None:
    """Raise ValueError unless one policy's (params, normalizer) fit every seed of ``state``.

    ``state`` may be abstract (``jax.eval_shape`` of ``Trainer.init``): only structures and shapes are read.
    """
    old, treedef = jax.tree_util.tree_flatten_with_path((state.params, state.normalizer))
    if jax.tree_util.tree_structure((params, normalizer)) != treedef:
        raise ValueError("the initial policy's parameters do not have this run's structure (networks differ)")
    for (path, o), n in zip(old, jax.tree_util.tree_leaves((params, normalizer)), strict=True):
        need = tuple(o.shape[1:])  # o has the leading seed axis
        if np.shape(n) != need:
            name = jax.tree_util.keystr(path)
            raise ValueError(
                f"initial policy parameter {name} has shape {np.shape(n)}; this run needs {need}"
            )


def warm_start(state: TrainingState, params: PPOParams, normalizer: obs_norm.RunningStats) -> TrainingState:
    """Every seed of ``state`` starts from one policy's ``params`` and observation statistics.

    The optimizer state stays the fresh one (Adam's moments are zeros whatever the parameters), so this is
    fine-tuning from the policy with the run's own learning-rate schedule. Shardings are kept.

    Raises:
        ValueError: from :func:`check_init_policy`.
    """
    check_init_policy(state, params, normalizer)
    old, treedef = jax.tree_util.tree_flatten((state.params, state.normalizer))
    new = jax.tree_util.tree_leaves((params, normalizer))
    out = [
        _put_global(np.broadcast_to(np.asarray(n, o.dtype), o.shape), o.sharding)
        for o, n in zip(old, new, strict=True)
    ]
    params_b, normalizer_b = jax.tree_util.tree_unflatten(treedef, out)
    return state.replace(params=params_b, normalizer=normalizer_b)


# ---------------------------------------------------------------------------------------------- evaluation


def make_evaluate(
    env: Any,
    networks: PPONetworks,
    num_envs: int,
    num_steps: int,
    normalize_obs: bool = True,
    episode_metrics_fn: Callable[[dict[str, Any]], dict[str, jax.Array]] | None = None,
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

        names = _episode_metric_names(env, env_params, ep_fn)
        last0 = {k: jnp.zeros((num_envs,), jnp.float32) for k in names}
        ones = jnp.ones((num_envs,), jnp.float32)
        carry0 = (state, obs.astype(jnp.float32), 0.0 * ones, ones, last0, last0, 0.0 * ones)
        (_, _, ret, alive, last, total, n), _ = jax.lax.scan(
            step, carry0, jax.random.split(key_steps, num_steps)
        )
        means = {f"mean/{k}": v / jnp.maximum(n, 1.0) for k, v in total.items()}
        return {"return": ret, "ended": 1.0 - alive, "steps": n, **last, **means}

    return evaluate


# ---------------------------------------------------------------------------------------------- host driver


class TrainResult(NamedTuple):
    """What :func:`run_training` returns.

    Attributes:
        state: final training state (leading [S] axis).
        history: one dict per period: ``env_steps`` (per seed), ``wall_s``, metric name -> [S] array.
        compile_s: seconds of the first period call (compile + run), 0 if no period ran.
        trainer: the trainer (networks, mesh, trace counter).
    """

    state: TrainingState
    history: list[dict[str, Any]]
    compile_s: float
    trainer: Trainer


def _put_global(x: Any, sharding: jax.sharding.Sharding) -> jax.Array:
    """A host value (numpy or key array) as a jax.Array with ``sharding``, also when the sharding spans
    several processes (``jax.device_put`` accepts only process-local shardings there): each process builds
    its own shards from the same host value."""
    if jnp.issubdtype(getattr(x, "dtype", np.float32), jax.dtypes.prng_key):
        data = np.asarray(jax.random.key_data(x))
        arr = jax.make_array_from_callback(data.shape, sharding, lambda idx: data[idx])
        return jax.random.wrap_key_data(arr, impl=jax.random.key_impl(x))
    x = np.asarray(x)
    return jax.make_array_from_callback(x.shape, sharding, lambda idx: x[idx])


def _tidy_checkpoints(ckpt_dir: Path, restored: Any) -> None:
    """After a resume: rename the damaged newer checkpoints that were skipped to ``*.corrupt`` (so that the
    pruning of the continued run does not keep them instead of good ones) and drop stale temporary files."""
    from harv_jax.ppo import checkpoint

    if jax.process_index() != 0:
        return
    for path, _ in restored.skipped:
        checkpoint.set_aside(path)
    checkpoint.remove_stale_tmp(ckpt_dir)


def run_training(
    key: jax.Array,
    env: Any,
    env_params: Any,
    cfg: PPOConfig,
    *,
    run_dir: str | Path | None = None,
    resume: bool = False,
    env_config: dict[str, Any] | None = None,
    devices: Sequence[jax.Device] | None = None,
    progress_fn: Callable[[int, dict[str, Any]], None] | None = None,
    stop_after_periods: int | None = None,
    episode_metrics_fn: Callable[[dict[str, Any]], dict[str, jax.Array]] | None = None,
    trainer: Trainer | None = None,
    init_policy: tuple[PPOParams, obs_norm.RunningStats] | None = None,
    period_hook: Callable[[int, TrainingState], tuple[dict[str, Any], bool]] | None = None,
) -> TrainResult:
    """Host loop: init or resume, run periods, call ``progress_fn``, checkpoint every K periods and last.

    Args:
        key: base PRNG key; seed s trains with ``fold_in(key, s)``.
        env: the environment.
        env_params: env parameter pytree (traced argument).
        cfg: PPO config.
        run_dir: directory for ``checkpoints/`` (None: no checkpoints).
        resume: continue from the newest intact checkpoint in ``run_dir`` (its state, history and
            counters); damaged newer ones are skipped and renamed ``*.corrupt``.
        env_config: env settings stored in checkpoints (for the record and for ``policy.load``).
        devices: devices to shard envs over (default all).
        progress_fn: called after each period as ``progress_fn(period_index, history_row)``.
        stop_after_periods: stop (after checkpointing) once this many periods are done in total; for tests
            that emulate an interrupted run.
        episode_metrics_fn: see :func:`make_train`.
        trainer: a trainer already built by ``make_train`` for the same env and cfg (reuses its compiled
            functions; ``devices`` and ``episode_metrics_fn`` are then ignored).
        init_policy: (params, normalizer) of one policy every seed starts from (:func:`warm_start`);
            ignored on resume (the checkpoint has the state).
        period_hook: called after each period as ``period_hook(period_index, state)``; returns (entries
            added to that period's history row, e.g. evaluation metrics; stop: True ends training after this
            period's checkpoint, which is then always written).

    Returns:
        A :class:`TrainResult`.
    """
    from harv_jax.ppo import checkpoint

    if trainer is None:
        trainer = make_train(env, cfg, env_params, devices, episode_metrics_fn)
    n_periods = ppo_config.num_periods(cfg)
    history: list[dict[str, Any]] = []
    start = 0
    ckpt_dir = Path(run_dir) / "checkpoints" if run_dir is not None else None
    if resume:
        if ckpt_dir is None:
            raise ValueError("resume needs run_dir")
        template = jax.eval_shape(trainer.init, seed_keys(key, cfg.num_seeds), env_params)
        restored = checkpoint.restore_latest(ckpt_dir, template, cfg)
        _tidy_checkpoints(ckpt_dir, restored)
        state = jax.tree.map(_put_global, restored.state, trainer.state_shardings)
        history, start = restored.history, restored.period
    else:
        state = trainer.init(seed_keys(key, cfg.num_seeds), env_params)
        if init_policy is not None:
            state = warm_start(state, *init_policy)
    del key
    compile_s = 0.0
    last = n_periods if stop_after_periods is None else min(n_periods, stop_after_periods)
    t_run = time.perf_counter()
    for p in range(start, last):
        t0 = time.perf_counter()
        state, metrics = trainer.period(state, env_params)
        metrics = jax.device_get(metrics)
        dt = time.perf_counter() - t0
        if p == start:
            compile_s = dt
        row: dict[str, Any] = {
            "period": p + 1,
            "env_steps": (p + 1) * ppo_config.steps_per_period(cfg),
            "wall_s": time.perf_counter() - t_run,
            "period_s": dt,
            **{k: np.asarray(v) for k, v in metrics.items()},
        }
        stop = False
        if period_hook is not None:
            extra, stop = period_hook(p, state)
            row.update(extra)
        history.append(row)
        if progress_fn is not None:
            progress_fn(p, row)
        if ckpt_dir is not None and ((p + 1) % cfg.checkpoint_every == 0 or p + 1 == last or stop):
            checkpoint.save(ckpt_dir, state, cfg, period=p + 1, history=history, env_config=env_config or {})
        if stop:
            break
    return TrainResult(state, history, compile_s, trainer)


def history_arrays(history: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Stack a history into name -> array [periods] (scalars) or [periods, S] (per-seed metrics)."""
    if not history:
        return {}
    keys = [k for k in history[0] if all(k in row for row in history)]
    return {k: np.stack([np.asarray(row[k], dtype=np.float64) for row in history]) for k in keys}


def is_finite_metrics(metrics: dict[str, Any]) -> bool:
    """True if every non-episode metric is finite (episode statistics are NaN when no episode ended)."""
    return all(
        bool(np.all(np.isfinite(np.asarray(v)))) for k, v in metrics.items() if not k.startswith("episode")
    )
