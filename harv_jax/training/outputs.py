"""What a training run leaves in its folder: metrics.csv, policy/, spin_bank.npz and summary.json.

``metrics.csv``: one row per period, mean, std and per-seed value of every metric. ``policy/``:
``policy_seed<i>.npz`` for every seed, ``policy.npz`` and ``policy.stablehlo`` of the best seed
([`best_seed`][]: on the evaluation batch, or by final mean return). ``spin_bank.npz``: the spin-reset
states (if spin resets are on). ``summary.json``: see [`run_summary`][].
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import numpy as np

from harv_jax import atomic, policy_stablehlo
from harv_jax import policy as policy_api
from harv_jax.env import EnvParams
from harv_jax.env.env_settings import EnvSettings
from harv_jax.evaluation import seed_stats
from harv_jax.policy import Policy, make_policy, select_seed
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo.config import PPOConfig
from harv_jax.ppo.train_state import Trainer, TrainingState

#: Episode metrics summarised in ``summary.json`` (first and last period).
SUMMARY_METRICS = ("episode_return", "episode/recovered", "episode/final_omega_radps", "episode/terminated")


def write_metrics_csv(path: Path, history: list[dict[str, Any]]) -> None:
    """Rewrite ``metrics.csv`` from the whole history (so a resumed run has one row per period)."""
    if not history:
        return
    scalar = ("period", "env_steps", "wall_s", "period_s")
    names = list(dict.fromkeys(k for row in history for k in row if k not in scalar))  # eval rows add keys
    n_seeds = int(np.asarray(history[0][names[0]]).size) if names else 1
    header = list(scalar)
    for k in names:
        header += [k, f"{k}_std"] + [f"{k}/seed{i}" for i in range(n_seeds)]
    with atomic.open_atomic(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for row in history:
            out = [row[k] for k in scalar]
            for k in names:
                v = np.asarray(row.get(k, np.full(n_seeds, np.nan)), np.float64).reshape(-1)
                finite = v[np.isfinite(v)]
                out += [finite.mean() if finite.size else math.nan, finite.std() if finite.size else math.nan]
                out += list(v)
            w.writerow([f"{x:.6g}" if isinstance(x, float | np.floating) else x for x in out])


def _nanstat(fn: Callable[[np.ndarray], Any], v: np.ndarray) -> float:
    """``fn`` over the finite entries of ``v``; NaN (without a warning) if there are none."""
    v = v[np.isfinite(v)]
    return float(fn(v)) if v.size else math.nan


def export_seed_policies(
    pdir: Path,
    state: TrainingState,
    trainer: Trainer,
    cfg: PPOConfig,
    env_steps: int,
    loop: str = "none",
    demos: dict[str, Any] | None = None,
    measurement_path: dict[str, Any] | None = None,
) -> list[Policy]:
    """Write ``pdir/policy_seed<i>.npz`` for every seed; returns the policies.

    ``loop``: the loop the policies were trained in (``harv_jax.training.in_loop``), recorded in ``meta``;
    ``demos``: the demonstrations' record (path, SHA-256, runs), recorded in ``meta`` if given;
    ``measurement_path``: the path the policies observe through (``control.registry.path_record``), recorded
    in ``meta`` if given (the registry then flies them behind it).
    """
    params, normalizer = jax.device_get((state.params, state.normalizer))
    pols = []
    for s in range(cfg.num_seeds):
        meta = {
            "seed": s,
            "config": ppo_config.to_dict(cfg),
            "env_steps": env_steps,
            "normalize_observations": cfg.normalize_observations,
            "loop": loop,
        }
        if demos is not None:
            meta["demos"] = demos
        if measurement_path is not None:
            meta["measurement_path"] = measurement_path
        pol = make_policy(
            select_seed(params, s),
            select_seed(normalizer, s),
            trainer.networks,
            cfg.normalize_observations,
            meta,
        )
        policy_api.export_npz(pdir / f"policy_seed{s}.npz", pol)
        pols.append(pol)
    return pols


def best_seed(history: list[dict[str, Any]]) -> int:
    """Index of the best seed of a run's last period: by its evaluation (recovered fraction, then mean
    recovery time with not-recovered runs at the run length) if it has one, else by mean episode return."""
    if not history:
        return 0
    last = history[-1]
    if "eval/recovered" in last and "eval/t_recover_mean_s" in last:
        rec = np.asarray(last["eval/recovered"], np.float64).reshape(-1)
        t = np.asarray(last["eval/t_recover_mean_s"], np.float64).reshape(-1)
        return int(np.lexsort((np.nan_to_num(t, nan=np.inf), -np.nan_to_num(rec, nan=-1.0)))[0])
    ret = np.asarray(last["episode_return"], np.float64).reshape(-1)
    return int(np.nanargmax(np.where(np.isfinite(ret), ret, -np.inf))) if np.any(np.isfinite(ret)) else 0


def export_policies(
    out_dir: Path,
    state: TrainingState,
    trainer: Trainer,
    cfg: PPOConfig,
    history: list[dict[str, Any]],
    loop: str = "none",
    demos: dict[str, Any] | None = None,
    measurement_path: dict[str, Any] | None = None,
) -> int:
    """Write ``policy/policy_seed<i>.npz`` per seed and ``policy.npz``/``policy.stablehlo`` of the best.

    The best seed is picked on the last period's evaluation batch when the run evaluates (the highest
    recovered fraction, then the shortest mean recovery time; [`best_seed`][]), else by the highest mean
    episode return in the last period; returns its index.
    """
    best = best_seed(history)
    pdir = out_dir / "policy"
    steps = history[-1]["env_steps"] if history else 0
    pols = export_seed_policies(pdir, state, trainer, cfg, steps, loop, demos, measurement_path)
    policy_api.export_npz(pdir / "policy.npz", pols[best])
    # jax.export serialization needs flatbuffers; a policy behind a measurement path is flown by harv_jax only
    if policy_stablehlo.export_available() and pols[best].meta.get("measurement_path") is None:
        policy_stablehlo.export_stablehlo(pdir / "policy.stablehlo", pols[best])
    return best


def save_spin_bank(out_dir: Path, env: EnvSettings, env_params: EnvParams) -> None:
    """``spin_bank.npz`` in the run folder: the bank's states, deflections and provenance (if spin resets)."""
    if env.spin.reset_prob <= 0:
        return
    prov = env.provenance()
    atomic.savez(
        out_dir / "spin_bank.npz",
        x_wind=np.asarray(env_params.spin_states),
        delta_rad=np.asarray(env_params.spin_delta_rad),
        provenance=np.asarray(json.dumps(prov)),
    )


def run_summary(
    out_dir: Path, history: list[dict[str, Any]], best_seed: int, target_recovery: float | None
) -> dict[str, Any]:
    """The run's ``summary.json`` content: periods, best seed, last evaluation, first/last episode metrics.

    ``eval``: the ``eval/`` entries (per seed), env steps and wall time of the last evaluated period;
    ``target_reached_at_env_steps``: with ``target_recovery``, the first evaluation where every seed recovered
    at least that fraction (None if none did); ``episode_return``, ``episode/recovered``,
    ``episode/final_omega_radps``, ``episode/terminated``: mean over seeds in the first and last period and
    the std over seeds in the last.
    """
    summary: dict[str, Any] = {
        "out": str(out_dir),
        "periods": len(history),
        "best_seed": best_seed,
        "env_steps_per_seed": history[-1]["env_steps"] if history else 0,
    }
    evals = [row for row in history if "eval/recovered" in row]
    if evals:
        summary["eval"] = {
            k: np.asarray(v, np.float64).reshape(-1).tolist()
            for k, v in evals[-1].items()
            if k.startswith("eval/")
        }
        summary["eval"]["env_steps"] = evals[-1]["env_steps"]
        summary["eval"]["wall_s"] = evals[-1]["wall_s"]
        if target_recovery is not None:
            reached = [r for r in evals if np.all(np.asarray(r["eval/recovered"]) >= target_recovery)]
            summary["target_reached_at_env_steps"] = reached[0]["env_steps"] if reached else None
        summary["seeds"] = seed_summary(evals[-1], target_recovery)
    for k in SUMMARY_METRICS:
        if history and k in history[-1]:
            first = np.asarray(history[0][k], np.float64).reshape(-1)
            last = np.asarray(history[-1][k], np.float64).reshape(-1)
            summary[k] = {
                "first_mean": _nanstat(np.nanmean, first),
                "last_mean": _nanstat(np.nanmean, last),
                "last_std": _nanstat(np.nanstd, last),
            }
    return summary


#: Evaluation entries summarised over seeds (``summary.json`` "seeds"), by their short name.
SEED_METRICS = {
    "recovered": "eval/recovered",
    "recovered_spin": "eval/recovered_spin",
    "t_recover_mean_s": "eval/t_recover_mean_s",
    "t_recover_median_s": "eval/t_recover_median_s",
    "tv_median_rad": "eval/tv_median_rad",
}


def seed_summary(row: dict[str, Any], target_recovery: float | None = None) -> dict[str, Any]:
    """Each seed's evaluation in ``row``, the IQM with a 95% bootstrap CI of each, and which seeds recover
    at least ``target_recovery`` (default
    [`SEED_RECOVERY_BAR`][harv_jax.evaluation.seed_stats.SEED_RECOVERY_BAR]) of the evaluation batch."""
    per_seed = {name: row[key] for name, key in SEED_METRICS.items() if key in row}
    bar = seed_stats.SEED_RECOVERY_BAR if target_recovery is None else target_recovery
    return seed_stats.seed_table(per_seed, bar)


def seed_verdict(seeds: dict[str, Any]) -> str:
    """One line: which seeds meet the recovery bar on the evaluation batch, with the IQMs."""
    rec = seeds["per_seed"].get("recovered", [])
    ok = seeds["seeds_meeting_bar"]
    head = (
        f"all {len(rec)} seeds"
        if len(ok) == len(rec)
        else f"{len(ok)} of {len(rec)} seeds ({', '.join(map(str, ok)) or 'none'})"
    )
    line = f"{head} recover >= {seeds['bar']:.1%} of the evaluation batch"
    parts = []
    for name, unit in (("recovered", ""), ("t_recover_mean_s", " s")):
        if name in seeds["iqm"]:
            q = seeds["iqm"][name]
            parts.append(f"{name} IQM {q['iqm']:.4g}{unit} [95% CI {q['ci_low']:.4g}, {q['ci_high']:.4g}]")
    values = "; ".join(f"seed {i}: {r:.1%}" for i, r in enumerate(rec))
    return f"{line} ({values}); " + "; ".join(parts) if parts else line


def write_summary(path: Path, summary: dict[str, Any]) -> None:
    """``summary.json`` (indented JSON)."""
    atomic.write_text(path, json.dumps(summary, indent=2))
