"""One training run through the Python API, as the README shows it, with jax's defaults.

    python experiments/train_stress/api_run.py PRESET STEPS SEEDS SEED

Prints ``period N`` after each period and ``done`` at the end (``run.py`` counts them).
"""

from __future__ import annotations

import dataclasses
import sys

import jax

from harv_jax.env.episode_metrics import harv_episode_metrics
from harv_jax.ppo.loss_terms import terms_from_config
from harv_jax.ppo.runner import run_training
from harv_jax.ppo.train import make_train
from harv_jax.training.environment import make_harv_env
from harv_jax.training.presets import load_preset
from harv_jax.training.teacher import TEACHER_ACTION_KEY


def main() -> None:
    preset, steps, seeds, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
    cfg, env_table = load_preset(preset)
    cfg = dataclasses.replace(cfg, total_steps=steps, num_seeds=seeds, seed=seed)
    env, env_params = make_harv_env(env_table)
    labels = TEACHER_ACTION_KEY if env_table.get("teacher") else None
    terms = terms_from_config(cfg, labels)
    trainer = make_train(env, cfg, env_params, episode_metrics_fn=harv_episode_metrics, terms=terms)

    def progress(p: int, row: dict) -> None:
        print(f"period {p + 1}", file=sys.stderr, flush=True)

    run_training(jax.random.key(cfg.seed), env, env_params, cfg, trainer=trainer, progress_fn=progress)
    print("done", file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
