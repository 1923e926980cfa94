"""Small PPO sweep in the vectorized regime, and evaluation of trained runs against their initial policy.

Usage::

    # train each variant (on top of a preset) with S seeds in one graph, then evaluate; variants
    # combine with "+" (e.g. stagger+linear-lr+seed1)
    python experiments/ppo_sweep/run.py sweep --preset smoke --seeds 2 --variants base,lr3e-4,epochs10 \
        [--steps N] [--out experiments/ppo_sweep/results]
    # evaluate a finished `harv-jax train` run: initial vs trained deterministic policy, every seed
    python experiments/ppo_sweep/run.py evaluate RUN_DIR [--eval-envs 256]

Evaluation: each seed's initial parameters (re-created from the run's seed) and its trained parameters fly
the same ``--eval-envs`` initial states (common random numbers: one evaluation key) for one episode of the
env's ``episode_steps`` with the deterministic policy ``clip(mean)``. Reported per seed and as mean +- std
over seeds: episode return, ||omega|| at the episode end, fraction terminated (left the envelope), fraction
with |e_alpha| < 2 deg at the end, fraction meeting the full recovery criterion at the end (instantaneous,
no 10 s hold); over the episodes that were not terminated, ||omega|| and |e_alpha| at the end and their
averages over the episode (``mean/...``: how fast the rates are damped, not only where they end). Results
are JSON in ``--out``; the markdown in ``experiments/ppo_sweep/README.md`` is written by hand from them.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from harv_jax.env.episode_metrics import harv_episode_metrics  # noqa: E402
from harv_jax.ppo import checkpoint  # noqa: E402
from harv_jax.ppo import config as ppo_config  # noqa: E402
from harv_jax.ppo.acting import make_evaluate  # noqa: E402
from harv_jax.ppo.runner import run_training  # noqa: E402
from harv_jax.ppo.train import make_train, seed_keys  # noqa: E402
from harv_jax.training.environment import make_harv_env  # noqa: E402
from harv_jax.training.presets import load_preset  # noqa: E402

#: Variants: changes on top of the preset's [ppo] table.
VARIANTS: dict[str, dict[str, Any]] = {
    "base": {},
    "lr3e-4": {"lr": 3e-4},
    "lr3e-3": {"lr": 3e-3},
    "epochs10": {"epochs": 10},
    "mb16": {"minibatches": 16},
    "unroll64": {"unroll": 64},
    "no-obs-norm": {"normalize_observations": False},
    "ent1e-3": {"ent_coef": 1e-3},
    "logstd-1": {"init_log_std": -1.0},
    "linear-lr": {"lr_schedule": "linear"},
    "envs512": {"num_envs": 512},
    "envs64": {"num_envs": 64},
    "envs256": {"num_envs": 256},
    "stagger": {"stagger_episodes": True},
    "no-stagger": {"stagger_episodes": False},
    "const-lr": {"lr_schedule": "constant"},
    "lr2e-3": {"lr": 2e-3},
    "epochs2": {"epochs": 2},
    "mb8": {"minibatches": 8},
    "mb2": {"minibatches": 2},
    "unroll16": {"unroll": 16},
    "envs256-unroll16": {"num_envs": 256, "unroll": 16},
    "logstd0": {"init_log_std": 0.0},
    "ent1e-2": {"ent_coef": 1e-2},
    "lambda0.9": {"gae_lambda": 0.9},
    # other base seeds (seed s of a run trains with fold_in(key(base), s)): robustness checks
    "seed1": {"seed": 1},
    "seed2": {"seed": 2},
    # the paper's SB3 settings transplanted as they are (lr 5e-5, 10 epochs, batch 64 per minibatch)
    "paper-sb3": {"lr": 5e-5, "epochs": 10, "minibatches": 64},
}
EVAL_KEY = 12345
METRICS = ("return", "final_omega_radps", "terminated", "alpha_ok", "recovered")
#: Means over the episodes that were not terminated (the metric is 0 for terminated ones).
ALIVE_METRICS = ("final_omega_alive_radps", "final_abs_e_alpha_rad", "mean/final_omega_alive_radps",
                 "mean/final_abs_e_alpha_rad")  # fmt: skip


def evaluate_params(env, env_params, trainer, cfg, state, eval_envs: int, eval_steps: int) -> dict[str, Any]:
    """Deterministic evaluation of every seed of ``state`` on common initial states."""
    evaluate = jax.jit(
        make_evaluate(
            env, trainer.networks, eval_envs, eval_steps, cfg.normalize_observations, harv_episode_metrics
        )  # fmt: skip
    )
    out: dict[str, list[float]] = {k: [] for k in METRICS + ALIVE_METRICS}
    host_params, host_norm = jax.device_get((state.params, state.normalizer))
    for s in range(cfg.num_seeds):
        params = jax.tree.map(lambda x, s=s: x[s], host_params)
        normalizer = jax.tree.map(lambda x, s=s: x[s], host_norm)
        r = jax.device_get(evaluate(jax.random.key(EVAL_KEY), params, normalizer, env_params))
        for k in METRICS:
            out[k].append(float(np.mean(r[k])))
        alive = 1.0 - np.asarray(r["terminated"])
        for k in ALIVE_METRICS:
            out[k].append(float(np.sum(alive * np.asarray(r[k])) / max(np.sum(alive), 1.0)))
    summary = {k: {"per_seed": v, "mean": float(np.mean(v)), "std": float(np.std(v))} for k, v in out.items()}
    return summary


def compare(env, env_params, trainer, cfg, final_state, eval_envs: int, eval_steps: int) -> dict[str, Any]:
    """Evaluate initial (re-created) and final parameters of every seed (``env``: the evaluation env)."""
    init_state = trainer.init(seed_keys(jax.random.key(cfg.seed), cfg.num_seeds), env_params)
    return {
        "initial": evaluate_params(env, env_params, trainer, cfg, init_state, eval_envs, eval_steps),
        "trained": evaluate_params(env, env_params, trainer, cfg, final_state, eval_envs, eval_steps),
        "eval_envs": eval_envs,
        "eval_steps": eval_steps,
    }


def _line(name: str, res: dict[str, Any]) -> str:
    i, t = res["initial"], res["trained"]
    return (
        f"{name:>12}: return {i['return']['mean']:9.1f} -> {t['return']['mean']:9.1f} "
        f"(+-{t['return']['std']:.1f})  |w|end(alive) {i['final_omega_alive_radps']['mean']:.3f} -> "
        f"{t['final_omega_alive_radps']['mean']:.3f}  |w|mean(alive) "
        f"{i['mean/final_omega_alive_radps']['mean']:.3f} -> "
        f"{t['mean/final_omega_alive_radps']['mean']:.3f}  "
        f"|e_a|end(alive) {i['final_abs_e_alpha_rad']['mean']:.3f} -> "
        f"{t['final_abs_e_alpha_rad']['mean']:.3f}  terminated {i['terminated']['mean']:.2f} -> "
        f"{t['terminated']['mean']:.2f}  alpha_ok {t['alpha_ok']['mean']:.2f}  "
        f"recovered {t['recovered']['mean']:.2f}"
    )


def eval_env(env_table: dict[str, Any], episode_steps: int | None, eval_steps: int | None) -> tuple:
    """(env, env_params, flight steps) for the evaluation: the training env, or its copy with another time
    limit (``--eval-episode-steps``: e.g. fly 5 s-trained policies for 10 s)."""
    if episode_steps:
        env_table = dict(env_table, episode_steps=episode_steps)
    env, env_params = make_harv_env(env_table)
    return env, env_params, eval_steps or int(env_table.get("episode_steps", 1000))


def cmd_sweep(args: argparse.Namespace) -> None:
    base, env_table = load_preset(args.preset)
    if args.episode_steps:
        env_table = dict(env_table, episode_steps=args.episode_steps)
    env, env_params = make_harv_env(env_table)
    env_ev, env_params_ev, eval_steps = eval_env(env_table, args.eval_episode_steps, args.eval_steps)
    results = {"preset": args.preset, "env": env_table, "seeds": args.seeds, "variants": {}}
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / f"ppo_sweep_{args.preset}_{args.tag}.json"
    for name in args.variants.split(","):
        parts = name.split("+")  # "a+b": both variants' changes, later ones win
        unknown = [v for v in parts if v not in VARIANTS]
        if unknown:
            raise SystemExit(f"unknown variant {unknown[0]!r}; known: {', '.join(VARIANTS)}")
        changes = {k: v for part in parts for k, v in VARIANTS[part].items()}
        changes["num_seeds"] = args.seeds
        if args.steps:
            changes["total_steps"] = args.steps
        cfg = ppo_config.from_dict(changes, base=base, source=name)
        t0 = time.perf_counter()
        trainer = make_train(env, cfg, env_params, episode_metrics_fn=harv_episode_metrics)
        res = run_training(jax.random.key(cfg.seed), env, env_params, cfg, trainer=trainer)
        wall = time.perf_counter() - t0
        cmp = compare(env_ev, env_params_ev, trainer, cfg, res.state, args.eval_envs, eval_steps)
        curve = [{"env_steps": row["env_steps"], "episode_return": np.asarray(row["episode_return"]).tolist(),
                  "terminated": np.asarray(row.get("episode/terminated", np.nan)).tolist()}
                 for row in res.history]  # fmt: skip
        results["variants"][name] = {
            "config": ppo_config.to_dict(cfg),
            "wall_s": wall,
            "compile_and_first_period_s": res.compile_s,
            **cmp,
            "curve": curve,
        }
        print(_line(name, cmp) + f"  ({wall:.0f} s)", flush=True)
        path.write_text(json.dumps(results, indent=2))
    print(f"wrote {path}")


def cmd_evaluate(args: argparse.Namespace) -> None:
    run = Path(args.run)
    cfg, env_table = checkpoint.stored_configs(run)
    env, env_params = make_harv_env(env_table)
    trainer = make_train(env, cfg, env_params, episode_metrics_fn=harv_episode_metrics)
    template = jax.eval_shape(trainer.init, seed_keys(jax.random.key(cfg.seed), cfg.num_seeds), env_params)
    restored = checkpoint.restore_latest(run / "checkpoints", template, cfg)
    env_ev, env_params_ev, eval_steps = eval_env(env_table, args.eval_episode_steps, args.eval_steps)
    cmp = compare(env_ev, env_params_ev, trainer, cfg, restored.state, args.eval_envs, eval_steps)
    cmp["run"] = str(run)
    cmp["env_steps_per_seed"] = restored.history[-1]["env_steps"] if restored.history else 0
    print(_line(run.name, cmp))
    out = run / (f"evaluation_{eval_steps}.json" if args.eval_episode_steps else "evaluation.json")
    out.write_text(json.dumps(cmp, indent=2))
    print(f"wrote {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    sw = sub.add_parser("sweep")
    sw.add_argument("--preset", default="smoke")
    sw.add_argument("--variants", default="base,lr3e-4,epochs10,no-obs-norm")
    sw.add_argument("--seeds", type=int, default=2)
    sw.add_argument("--steps", type=int, default=None)
    sw.add_argument("--eval-envs", type=int, default=256)
    sw.add_argument("--eval-steps", type=int, default=None)
    sw.add_argument("--episode-steps", type=int, default=None, help="training time limit (env override)")
    sw.add_argument("--eval-episode-steps", type=int, default=None, help="evaluation flight length, steps")
    sw.add_argument("--tag", default="cpu")
    sw.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "results")
    ev = sub.add_parser("evaluate")
    ev.add_argument("run")
    ev.add_argument("--eval-envs", type=int, default=256)
    ev.add_argument("--eval-steps", type=int, default=None)
    ev.add_argument("--eval-episode-steps", type=int, default=None, help="evaluation flight length, steps")
    args = ap.parse_args()
    cmd_sweep(args) if args.cmd == "sweep" else cmd_evaluate(args)


if __name__ == "__main__":
    main()
