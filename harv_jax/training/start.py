"""The pieces of a training run before its first period: env, trainer, initial policy, run record.

[`build_training`][] makes the recovery env from the env settings and the generic trainer with the HARV
episode metrics (``harv_jax.env.episode_metrics``); [`write_run_record`][] writes the run folder's
``config.json`` (what ``--resume`` restarts from when no checkpoint was written) and its spin bank.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import jax

from harv_jax import atomic
from harv_jax.env import Env, EnvParams
from harv_jax.env.episode_metrics import harv_episode_metrics
from harv_jax.errors import UsageError
from harv_jax.policy import Policy, resolve_policy
from harv_jax.ppo import normalize as obs_norm
from harv_jax.ppo.config import PPOConfig
from harv_jax.ppo.loss_terms import terms_from_config
from harv_jax.ppo.networks import PPOParams
from harv_jax.ppo.runner import check_init_policy
from harv_jax.ppo.train import make_train
from harv_jax.ppo.train_state import Trainer
from harv_jax.task.spaces import ACTION_SIZE, OBSERVATION_SIZE
from harv_jax.training.demos import RunDemos, load_run_demos
from harv_jax.training.environment import make_harv_env
from harv_jax.training.outputs import save_spin_bank
from harv_jax.training.spec import TrainSpec
from harv_jax.training.teacher import TEACHER_ACTION_KEY


class TrainingSetup(NamedTuple):
    """What [`build_training`][] returns.

    Attributes:
        env: the recovery env.
        env_params: its traced parameters.
        trainer: ``make_train`` of env and config, with the HARV episode metrics.
        init_policy: (params, normalizer) every seed starts from, or None (random initialization).
        demos: the demonstration set cloned besides (or instead of) a teacher, or None.
    """

    env: Env
    env_params: EnvParams
    trainer: Trainer
    init_policy: tuple[PPOParams, obs_norm.RunningStats] | None
    demos: RunDemos | None = None


def load_init_policy(
    spec: str, trainer: Trainer, cfg: PPOConfig, env_params: EnvParams, pol: Policy | None = None
) -> tuple[PPOParams, obs_norm.RunningStats]:
    """(params, normalizer) of the policy ``spec`` (``shipped:NAME``, a path[@seed]; ``pol``: already loaded
    from it), checked against the run's abstract state (nothing is allocated); UsageError naming
    ``--init-policy`` if it does not fit."""
    pol = resolve_policy(spec) if pol is None else pol
    init = (pol.params, pol.normalizer)
    keys = jax.random.split(jax.random.key(0), cfg.num_seeds)
    try:
        check_init_policy(jax.eval_shape(trainer.init, keys, env_params), *init)
    except ValueError as e:
        raise UsageError(f"--init-policy {spec!r}: {e}") from None
    return init


def check_init_sizes(spec: str, pol: Policy, cfg: PPOConfig, observation_size: int) -> None:
    """UsageError naming ``--init-policy`` unless the policy's observation, action and hidden sizes are the
    run's (checked before the env is built; [`load_init_policy`][] then checks every array)."""
    got = (pol.networks.observation_size, pol.networks.action_size, tuple(pol.networks.actor.hidden_sizes))
    want = (observation_size, ACTION_SIZE, cfg.hidden_sizes)
    if got != want:
        raise UsageError(
            f"--init-policy {spec!r} has {got[0]} observations, {got[1]} actions and hidden layers "
            f"{list(got[2])}; this run needs {want[0]}, {want[1]} and {list(want[2])} (hidden_sizes)"
        )


def build_training(spec: TrainSpec) -> TrainingSetup:
    """Env, env parameters and trainer of a run (with the loss terms its PPO config asks for), its initial
    policy (``spec.init_policy``) and its demonstrations (``spec.ppo.demos``; ``spec.demos_sha256``: the
    digest the file must have, on ``--resume``).

    Raises:
        UsageError: an initial policy that does not fit the run's networks, or bad demonstrations
            ([`load_run_demos`][harv_jax.training.demos.load_run_demos]).
    """
    cfg, init_policy = spec.ppo, spec.init_policy
    pol = None if init_policy is None else resolve_policy(init_policy)  # a bad file fails before the env
    if pol is not None:
        check_init_sizes(init_policy, pol, cfg, OBSERVATION_SIZE)
    demos = None
    if cfg.demos is not None:  # before the env is built: bad demos fail fast
        demos = load_run_demos(cfg.demos, OBSERVATION_SIZE, ACTION_SIZE, spec.demos_sha256)
    env, env_params = make_harv_env(spec)
    pairs = None if demos is None else (demos.observations, demos.actions)
    labels = TEACHER_ACTION_KEY if spec.teacher is not None else None
    terms = terms_from_config(cfg, labels, pairs)
    trainer = make_train(env, cfg, env_params, episode_metrics_fn=harv_episode_metrics, terms=terms)
    init = None if init_policy is None else load_init_policy(init_policy, trainer, cfg, env_params, pol)
    return TrainingSetup(env, env_params, trainer, init, demos)


def write_run_record(
    out_dir: Path, spec: TrainSpec, env_params: EnvParams, demos: RunDemos | None = None
) -> None:
    """Write ``config.json`` (the spec: [`TrainSpec.record`][harv_jax.training.spec.TrainSpec.record])
    and the spin bank."""
    record = spec.record(None if demos is None else demos.record())
    atomic.write_text(out_dir / "config.json", json.dumps(record, indent=2))
    save_spin_bank(out_dir, spec.env, env_params)
