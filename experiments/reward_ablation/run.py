"""Reward ablation at equal budget: the paper's reward vs each of our changes, 3 seeds each, 2-core CPU.

    python experiments/reward_ablation/run.py                       # every variant, 3 seeds, then the MCs
    python experiments/reward_ablation/run.py --variants paper,ours --seeds 3 --seed 100

Every variant is the ``recovery`` preset (same PPO settings, network, episode length and step budget) with
its reward/spin/randomization tables replaced as listed in ``VARIANTS``; ``paper`` is the paper's reward
(the ``[reward]`` table removed). Each is trained with ``harv-jax train --seeds N`` (the N seeds in one
compiled graph, evaluation during training on its fixed batch: learning curves against env steps and wall
time in ``metrics.csv``), then every seed's policy flies RL-only a Monte Carlo of ``--mc-runs`` reset-bound
runs (``harv-jax mc`` sampling, seed ``--mc-seed``, nominal aircraft, alpha_d 0.349 rad, 60 s) and the 30 s
developed spin. Results: ``results/<variant>/`` (run folder without checkpoints), ``results/ablation.json``
and ``results/ablation.md`` (mean +- std over seeds), ``results/learning_curves.png``.
"""

from __future__ import annotations

import argparse
import copy
import json
import shutil
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
PRESET = ROOT / "harv_jax" / "training" / "presets" / "recovery.toml"

#: variant -> (description, function of the preset dict that returns the variant's preset dict)
VARIANTS = {
    "paper": "the paper's reward (indicator bonuses, no dense terms), no spin resets",
    "bands": "smooth Gaussian bonus bands only, no spin resets",
    "bands+dense": "bands + dense per-channel terms, no spin resets",
    "ours-nospin": "our reward (bands, dense terms, recovered bonus, action weight), no spin resets",
    "ours": "our reward + spin resets (the recovery preset)",
    "ours+dr": "the recovery preset with full domain randomization (gust, noise, delay too)",
}


def variant_preset(name: str, base: dict) -> dict:
    """The preset dict of a variant (see ``VARIANTS``)."""
    p = copy.deepcopy(base)
    reward = p.get("reward", {})
    if name == "paper":
        p.pop("reward", None)
        p.pop("spin", None)
    elif name == "bands":
        p["reward"] = {k: reward[k] for k in ("bonus_shape", "bonus_width_rad") if k in reward}
        p.pop("spin", None)
    elif name == "bands+dense":
        p["reward"] = {k: reward[k] for k in ("bonus_shape", "bonus_width_rad", "w_track", "track_clip_rad")
                       if k in reward}  # fmt: skip
        p.pop("spin", None)
    elif name == "ours-nospin":
        p.pop("spin", None)
    elif name == "ours":
        pass
    elif name == "ours+dr":
        p.pop("randomization", None)
        p["env"]["domain_randomization"] = True
    else:
        raise SystemExit(f"unknown variant {name!r}; allowed: {', '.join(VARIANTS)}")
    p["description"] = f"reward ablation: {VARIANTS[name]}"
    return p


def to_toml(d: dict) -> str:
    """A minimal TOML writer for preset dicts (tables of scalars and lists)."""

    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list | tuple):
            return "[" + ", ".join(val(x) for x in v) + "]"
        return repr(v)

    lines = [f"description = {val(d['description'])}"] if "description" in d else []
    for table, body in d.items():
        if isinstance(body, dict):
            lines += ["", f"[{table}]"] + [f"{k} = {val(v)}" for k, v in body.items()]
    return "\n".join(lines) + "\n"


def mc_eval(policy: str, runs: int, seed: int) -> dict:
    """RL-only Monte Carlo and the 30 s spin of one policy (in this process)."""
    import jax
    import jax.numpy as jnp

    from harv_jax.aircraft import harv
    from harv_jax.control.rl import make_rl_controller
    from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
    from harv_jax.evaluation.policy_eval import make_eval_batch
    from harv_jax.evaluation.summary import summarize_controller
    from harv_jax.policy import resolve_policy
    from harv_jax.task.spec import ALPHA_TARGET_RAD as DEFAULT_ALPHA_TARGET_RAD

    ctrl = make_rl_controller(resolve_policy(policy).deterministic)
    ref = jnp.asarray([DEFAULT_ALPHA_TARGET_RAD, 0.0, 0.0])
    inputs = sample_mc_inputs(jax.random.key(seed), runs, harv())
    out, wall = run_mc(ctrl, inputs, ref, 6000, 0.01, 10, 256)
    s = summarize_controller(out, wall, 6000)
    spin = make_eval_batch(0, 1, harv())  # the scenario's developed spin, nominal aircraft
    from harv_jax.evaluation.closed_loop import closed_loop, score

    res = closed_loop(ctrl, harv(), spin.x0_wind[0], ref, jax.random.key(0), 6000, 0.01, spin.delta0_rad[0])
    m, _ = score(res, ref, harv(), 0.01)
    return {
        "recovery_rate": s["recovery_rate"],
        "t_recover_p50_s": s["recovery_time_s"]["p50"],
        "t_recover_p95_s": s["recovery_time_s"]["p95"],
        "control_tv_rad": s["control_tv"]["mean"],
        "spin_recovered": bool(m.recovered),
        "spin_t_recover_s": None if not bool(m.recovered) else float(m.t_recover_s),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=100, help="base training seed (not the seeds we tuned on)")
    ap.add_argument("--mc-runs", type=int, default=256)
    ap.add_argument("--mc-seed", type=int, default=7)
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--steps", type=int, default=None, help="env steps per seed (default: the preset's)")
    ap.add_argument("--skip-train", action="store_true", help="only (re)do the Monte Carlos and tables")
    ap.add_argument("--in-process", action="store_true", help="train through the Python API, not the CLI")
    args = ap.parse_args()
    base = tomllib.loads(PRESET.read_text())
    if args.steps:
        base["ppo"]["total_steps"] = args.steps
    args.out.mkdir(parents=True, exist_ok=True)
    results = (
        json.loads((args.out / "ablation.json").read_text()) if (args.out / "ablation.json").exists() else {}
    )
    for name in args.variants.split(","):
        run_dir = args.out / name
        preset = args.out / f"{name}.toml"
        if not args.skip_train:
            preset.write_text(to_toml(variant_preset(name, base)))
            cmd = [sys.executable, "-m", "harv_jax.cli", "train", "--preset", str(preset), "--seeds",
                   str(args.seeds), "--seed", str(args.seed), "--out", str(run_dir), "--force"]  # fmt: skip
            t0 = time.time()
            if args.in_process:
                train_in_process(preset, args.seeds, args.seed, run_dir)
            else:
                train_cli(cmd, name, run_dir, args.out)
            wall = time.time() - t0
            shutil.rmtree(run_dir / "checkpoints", ignore_errors=True)  # resumable only by re-running
        else:
            wall = results.get(name, {}).get("train_wall_s")
        per_seed = [mc_eval(str(run_dir / "policy" / f"policy_seed{s}.npz"), args.mc_runs, args.mc_seed)
                    for s in range(args.seeds)]  # fmt: skip
        results[name] = {"description": VARIANTS[name], "train_wall_s": wall, "seeds": per_seed}
        (args.out / "ablation.json").write_text(json.dumps(results, indent=2))
        print(name, json.dumps(per_seed), flush=True)
    write_table(results, args.out / "ablation.md")
    plot_curves(results, args.out)


def train_cli(cmd: list[str], name: str, run_dir: Path, out: Path) -> None:
    """``harv-jax train`` as a subprocess; a run the watchdog stopped (exit 3) is continued once."""
    with open(out / f"{name}.log", "w") as log:
        r = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT)
        if r.returncode == 3:  # the watchdog stopped a stalled run: continue it once
            again = [sys.executable, "-m", "harv_jax.cli", "train", "--resume", str(run_dir)]
            r = subprocess.run(again, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT)
        if r.returncode:
            raise SystemExit(f"{name}: harv-jax train failed ({r.returncode}); see {name}.log")


def train_in_process(preset: Path, seeds: int, seed: int, run_dir: Path) -> None:
    """The same training through the Python API (no progress display, TensorBoard or watchdog threads)."""
    import jax

    from harv_jax.env.episode_metrics import harv_episode_metrics
    from harv_jax.ppo.runner import run_training
    from harv_jax.ppo.train import make_train
    from harv_jax.training.environment import make_harv_env
    from harv_jax.training.eval_hook import make_eval_hook
    from harv_jax.training.outputs import export_policies, write_metrics_csv
    from harv_jax.training.presets import load_spec

    spec = load_spec(str(preset), {"num_seeds": seeds, "seed": seed})
    cfg = spec.ppo
    env, env_params = make_harv_env(spec)
    trainer = make_train(env, cfg, env_params, episode_metrics_fn=harv_episode_metrics)
    run_dir.mkdir(parents=True, exist_ok=True)
    hook, _ = make_eval_hook(trainer, spec, env_params, run_dir)

    def progress(p: int, row: dict) -> None:
        print(f"period {p + 1} {row['wall_s']:.0f} s", flush=True)

    res = run_training(
        jax.random.key(cfg.seed),
        env,
        env_params,
        cfg,
        trainer=trainer,
        period_hook=hook,
        progress_fn=progress,
    )
    write_metrics_csv(run_dir / "metrics.csv", res.history)
    export_policies(run_dir, res.state, trainer, cfg, res.history)


def _ms(values: list) -> str:
    v = np.array([np.nan if x is None else float(x) for x in values])
    v = v[np.isfinite(v)]
    if not v.size:
        return "–"
    return f"{v.mean():.3g} ± {v.std():.2g}" + ("" if v.size == len(values) else f" (n={v.size})")


def write_table(results: dict, path: Path) -> None:
    """Mean ± std over seeds of every variant."""
    rows = [
        "| variant | RL-only recovered | median recovery (s) | p95 (s) | control TV (rad) | spin recovered "
        "| spin recovery (s) | train wall (s) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, r in results.items():
        s = r["seeds"]
        rows.append(
            f"| {name} | {_ms([x['recovery_rate'] for x in s])} | {_ms([x['t_recover_p50_s'] for x in s])} "
            f"| {_ms([x['t_recover_p95_s'] for x in s])} | {_ms([x['control_tv_rad'] for x in s])} "
            f"| {sum(x['spin_recovered'] for x in s)}/{len(s)} | {_ms([x['spin_t_recover_s'] for x in s])} "
            f"| {r['train_wall_s']:.0f} |"
        )
    path.write_text("\n".join(rows) + "\n")


def plot_curves(results: dict, out: Path) -> None:
    """Evaluation recovery during training vs env steps and vs wall time, mean and per seed."""
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    for i, name in enumerate(results):
        f = out / name / "metrics.csv"
        if not f.exists():
            continue
        rows = [r for r in csv.DictReader(f.open()) if r.get("eval/recovered")]
        if not rows:
            continue
        steps = np.array([float(r["env_steps"]) for r in rows])
        wall = np.array([float(r["wall_s"]) for r in rows])
        rec = np.array([float(r["eval/recovered"]) for r in rows])
        for ax, x in zip(axes, (steps, wall), strict=True):
            ax.plot(x, rec, color=f"C{i}", label=name)
    axes[0].set_xlabel("env steps per seed")
    axes[1].set_xlabel("wall time (s, all seeds together, 2-core CPU)")
    for ax in axes:
        ax.set_ylabel("RL-only recovered (eval batch, mean over seeds)")
        ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "learning_curves.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
