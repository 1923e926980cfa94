"""Evaluation during training: every ``[eval] every`` periods each seed's policy flies a fixed batch."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import numpy as np

from harv_jax.control.hybrid.law import HybridConfig, make_hybrid
from harv_jax.control.registry import with_measurement_path
from harv_jax.control.rl import make_rl_controller
from harv_jax.env import EnvParams
from harv_jax.evaluation.policy_eval import make_eval_batch, make_policy_eval, summarize_eval
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo import normalize as obs_norm
from harv_jax.ppo.networks import postprocess
from harv_jax.ppo.train_state import Trainer, TrainingState
from harv_jax.task.measurement_path import path_record
from harv_jax.training import outputs
from harv_jax.training.spec import TrainSpec

#: ``period_hook`` of [`harv_jax.ppo.runner.run_training`][]: (period index, state) -> (row entries, stop).
PeriodHook = Callable[[int, TrainingState], tuple[dict[str, Any], bool]]


def make_eval_hook(
    trainer: Trainer, spec: TrainSpec, env_params: EnvParams, out_dir: Path | None = None
) -> tuple[PeriodHook | None, str]:
    """The period hook of evaluation during training (``[eval]`` table), or (None, "") when it is off.

    Every ``eval.every`` periods (and at the last) every seed's deterministic policy flies the fixed batch of
    ``harv_jax.evaluation.policy_eval`` RL-only (a run trained in the hybrid's loop: in that loop); its
    recovery fractions and median recovery time go into the period's row. With ``spec.target_recovery``
    training stops at the first evaluation where every seed recovers at least that fraction (that period's
    checkpoint is written). With ``out_dir`` every evaluated period's policies are kept as
    ``policy/period_<N>/policy_seed<s>.npz`` (a few kB each).
    """
    cfg, loop, target_recovery = spec.ppo, spec.loop, spec.target_recovery
    ev = spec.env.eval
    if target_recovery is not None and not ev.every:
        ev = dataclasses.replace(ev, every=1)
    if not ev.every:
        return None, ""
    batch = make_eval_batch(ev.upset_runs, ev.spin_runs, env_params.aircraft)
    path = None if spec.path is None else path_record(spec.path)

    def act(params: Any, normalizer: Any, obs: jax.Array) -> jax.Array:
        obs_in = obs_norm.normalize(normalizer, obs) if cfg.normalize_observations else obs
        mean, _ = trainer.networks.policy(params, obs_in)
        return postprocess(mean)

    def make_controller(act_obs):
        ctrl = make_rl_controller(act_obs)
        return ctrl if spec.path is None else with_measurement_path(ctrl, spec.path)

    if loop != "none":  # the policy flies in the loop it trains in
        hybrid_cfg = HybridConfig(schedule=loop.removeprefix("hybrid:"))

        def make_controller(act_obs):
            return make_hybrid(act_obs, hybrid_cfg)

    evaluate = jax.jit(jax.vmap(make_policy_eval(act, batch, ev.duration_s, make_controller=make_controller)))
    n_periods = ppo_config.num_periods(cfg)
    is_spin = jax.device_get(batch.is_spin)

    def hook(p: int, state: TrainingState) -> tuple[dict[str, Any], bool]:
        if (p + 1) % ev.every and p + 1 != n_periods:
            return {}, False
        out = summarize_eval(jax.device_get(evaluate(state.params, state.normalizer)), is_spin, ev.duration_s)
        stop = target_recovery is not None and bool(np.all(out["eval/recovered"] >= target_recovery))
        if out_dir is not None:
            steps = (p + 1) * ppo_config.steps_per_period(cfg)
            outputs.export_seed_policies(
                out_dir / "policy" / f"period_{p + 1:04d}", state, trainer, cfg, steps, loop, None, path
            )
        return out, stop

    flown = "RL-only" if loop == "none" else f"in the loop {loop}"
    desc = f"evaluation every {ev.every} period(s): {ev.upset_runs} upsets + {ev.spin_runs} spins, {flown}"
    return hook, desc
