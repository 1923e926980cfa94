"""The host driver of PPO training: init or resume, run periods, report, checkpoint, warm start.

[`run_training`][] calls the compiled ``Trainer.period`` ([`harv_jax.ppo.train`][]) once per period:
fetch its metrics to the host, call ``progress_fn`` and ``period_hook``, checkpoint every
``cfg.checkpoint_every`` periods and at the last. ``resume=True`` continues from the newest intact
checkpoint of ``run_dir`` ([`harv_jax.ppo.checkpoint`][]).

Multi-host (Python API; the ``harv-jax train`` command is single-process): start one process per host with
the same script and, before anything creates a jax array, call ``jax.distributed.initialize(
coordinator_address="host0:1234", num_processes=P, process_id=i)`` (on SLURM, Open MPI or TPU the arguments
are found automatically); then ``make_train(..., devices=jax.devices())`` builds the mesh over all global
devices (the default, `default_devices`, does the same on accelerators; on CPU
it takes one local device), ``num_envs`` must divide by ``jax.device_count()``, and every process calls
``run_training`` with the same arguments. Metrics and parameters are replicated, so every process sees the
same history; checkpoints all-gather the env-sharded state and only process 0 writes them (``run_dir`` must
be on a filesystem all processes share for ``resume=True``). Tested with 2 processes x 1 CPU device (gloo):
half a run + resume equals one process on one device to 1e-4 (``tests/test_train.py``, marked slow).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import jax
import numpy as np

from harv_jax.ppo import checkpoint
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo import normalize as obs_norm
from harv_jax.ppo.acting import EpisodeMetricsFn
from harv_jax.ppo.config import PPOConfig
from harv_jax.ppo.networks import PPOParams
from harv_jax.ppo.sharding import put_global
from harv_jax.ppo.train import make_train, seed_keys
from harv_jax.ppo.train_state import Trainer, TrainingState


class TrainResult(NamedTuple):
    """What [`run_training`][] returns.

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
        ValueError: from [`check_init_policy`][].
    """
    check_init_policy(state, params, normalizer)
    old, treedef = jax.tree_util.tree_flatten((state.params, state.normalizer))
    new = jax.tree_util.tree_leaves((params, normalizer))
    out = [
        put_global(np.broadcast_to(np.asarray(n, o.dtype), o.shape), o.sharding)
        for o, n in zip(old, new, strict=True)
    ]
    params_b, normalizer_b = jax.tree_util.tree_unflatten(treedef, out)
    return state.replace(params=params_b, normalizer=normalizer_b)


def _tidy_checkpoints(ckpt_dir: Path, restored: Any) -> None:
    """After a resume: rename the damaged newer checkpoints that were skipped to ``*.corrupt`` (so that the
    pruning of the continued run does not keep them instead of good ones) and drop stale temporary files."""
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
    episode_metrics_fn: EpisodeMetricsFn | None = None,
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
        episode_metrics_fn: see [`make_train`][harv_jax.ppo.train.make_train].
        trainer: a trainer already built by ``make_train`` for the same env and cfg (reuses its compiled
            functions; ``devices`` and ``episode_metrics_fn`` are then ignored).
        init_policy: (params, normalizer) of one policy every seed starts from ([`warm_start`][]);
            ignored on resume (the checkpoint has the state).
        period_hook: called after each period as ``period_hook(period_index, state)``; returns (entries
            added to that period's history row, e.g. evaluation metrics; stop: True ends training after this
            period's checkpoint, which is then always written).

    Returns:
        A [`TrainResult`][].
    """
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
        state = jax.tree.map(put_global, restored.state, trainer.state_shardings)
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
