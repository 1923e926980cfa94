"""The files of ``harv-jax optimal``: runs.csv (the Monte Carlo's layout), optimal_runs.csv, summary.json,
the figures and, if asked, the demonstrations."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np

from harv_jax import atomic
from harv_jax.evaluation.montecarlo.paired import times_nr_at_run_s
from harv_jax.machine import cpu_model
from harv_jax.optimal.search import SearchConfig
from harv_jax.optimal.study import OPTIMAL, OptimalStudy
from harv_jax.task.spec import DT_S, H0_FT

#: What the optimum is an optimum over (recorded in summary.json and the report).
CONTROL_CLASS = (
    "the braking SMC (smc-brake's feedback law, standard gains) fed a reference offset that is a "
    "piecewise-linear function of time since engagement (knots every knot_dt_s, bounded by tanh, 0 after "
    "the last knot), braking on or off per run by the warm start; per run the better of that and the best "
    "registry controller"
)


def _times(study: OptimalStudy, run_s: float) -> dict[str, np.ndarray]:
    return {
        k: times_nr_at_run_s(o.metrics.t_recover_s, o.metrics.recovered, run_s)
        for k, o in study.outputs.items()
    }


def ratio_table(study: OptimalStudy, run_s: float) -> dict[str, dict[str, float]]:
    """controller -> median, p95 and mean of (its time / the optimum's), not-recovered at the run length."""
    t = _times(study, run_s)
    t_opt = np.maximum(t[OPTIMAL], DT_S)
    out = {}
    for name, tc in t.items():
        if name == OPTIMAL:
            continue
        r = tc / t_opt
        out[name] = {
            "median": float(np.median(r)),
            "p95": float(np.percentile(r, 95)),
            "mean": float(np.mean(r)),
        }
    return out


def optimal_block(study: OptimalStudy, cfg: SearchConfig) -> dict[str, Any]:
    """The ``optimal`` block of summary.json."""
    t = _times(study, cfg.run_s)
    baselines = [k for k in t if k != OPTIMAL]
    t_best = np.min(np.stack([t[k] for k in baselines]), axis=0)
    res = study.search
    return {
        "control_class": CONTROL_CLASS,
        "search": {
            "horizon_s": cfg.horizon_s,
            "knot_dt_s": cfg.knot_dt_s,
            "n_knots": cfg.n_knots,
            "iterations": cfg.iterations,
            "rounds": cfg.rounds,
            "learning_rate": cfg.learning_rate,
            "hold_weight": cfg.hold_weight,
            "run_s": cfg.run_s,
            "optimizer": "optax.sgd with momentum on the per-run normalized gradient",
        },
        "recovered_fraction": float(np.mean(study.outputs[OPTIMAL].metrics.recovered)),
        "never_slower_than_best": bool(np.all(t[OPTIMAL] <= t_best)),
        "strictly_faster_fraction": float(np.mean(t[OPTIMAL] < t_best)),
        "source_counts": {s: int(np.sum(study.source == s)) for s in np.unique(study.source)},
        "best_controller_counts": {s: int(np.sum(study.best == s)) for s in np.unique(study.best)},
        "warm_start_braking_fraction": float(np.mean(study.v_switch_fps < 1000.0)),
        "ratio_to_optimal": ratio_table(study, cfg.run_s),
        "recovery_time_s": {
            k: {"median": float(np.median(v)), "p95": float(np.percentile(v, 95)), "mean": float(np.mean(v))}
            for k, v in t.items()
        },
        "objective_mean_by_iteration": [float(v) for v in np.mean(res.objective, axis=1)],
        "searched_median_t_by_round_s": [
            float(np.nanmedian(r)) if np.any(np.isfinite(r)) else None for r in res.round_t_recover_s
        ],
        "wall_time_s": {**study.wall_s, **{f"search_{k}": v for k, v in res.wall_s.items()}},
        "cpu": cpu_model(),
    }


def write_optimal_runs_csv(path: Path, study: OptimalStudy, run_s: float) -> None:
    """One row per run: where the optimum came from, the best controller, every controller's time."""
    t = _times(study, run_s)
    names = list(t)
    searched = study.search.metrics
    with atomic.open_atomic(path, "w", newline="") as f:
        w = csv.writer(f)
        others = [n for n in names if n != OPTIMAL]
        w.writerow(
            [
                "run",
                "source",
                "best_controller",
                "warm_start",
                "t_searched_s",
                *[f"t_{n}_s" for n in names],
                *[f"ratio_{n}" for n in others],
            ]
        )
        for i in range(len(study.source)):
            ts = searched.t_recover_s[i] if searched.recovered[i] else np.nan
            w.writerow(
                [
                    i,
                    study.source[i],
                    study.best[i],
                    "smc-brake" if study.v_switch_fps[i] < 1000.0 else "smc",
                    f"{ts:.4g}",
                    *[f"{t[n][i]:.4g}" for n in names],
                    *[f"{t[n][i] / max(t[OPTIMAL][i], DT_S):.4g}" for n in others],
                ]
            )


def build_summary(
    study: OptimalStudy, cfg: SearchConfig, target_alpha_rad: float, seed: int, command: str, scenario: str
) -> dict[str, Any]:
    """summary.json: the Monte Carlo's layout (settings, one block per controller) plus ``optimal``."""
    import jax

    from harv_jax.evaluation.summary import mc_summary, summarize_controller
    from harv_jax.optimal.study import BASELINES

    n = len(study.source)
    n_steps = int(round(cfg.run_s / DT_S))
    s = mc_summary(
        [*BASELINES, OPTIMAL],
        None,
        "simplex",
        n,
        target_alpha_rad,
        n_steps * DT_S,
        seed,
        False,
        DT_S,
        float(study.scenario.x0_wind[0, 9]) if n else H0_FT,
        [str(d) for d in jax.local_devices()],
        command,
    )
    s["scenario"] = scenario
    wall = {"compile": 0.0, "run": 0.0}
    for name, out in study.outputs.items():
        s["controllers"][name] = summarize_controller(out, wall, n_steps, n_steps * DT_S)
    s["optimal"] = optimal_block(study, cfg)
    return s


def write_optimal(out_dir: Path, study: OptimalStudy, summary: dict[str, Any], cfg: SearchConfig) -> None:
    """runs.csv, optimal_runs.csv, summary.json, vs_optimal.png, search_progress.png (the report section,
    optimal_report.md, is written by the command: ``harv_jax.report`` sits above this layer)."""
    from harv_jax.evaluation.montecarlo.study import write_runs_csv
    from harv_jax.numfmt import write_json
    from harv_jax.plots.optimal import plot_search_progress, plot_vs_optimal

    write_runs_csv(out_dir / "runs.csv", np.asarray(study.scenario.x0_wind), study.outputs)
    write_optimal_runs_csv(out_dir / "optimal_runs.csv", study, cfg.run_s)
    write_json(out_dir / "summary.json", summary)
    t = _times(study, cfg.run_s)
    plot_vs_optimal(
        t[OPTIMAL],
        {k: v for k, v in t.items() if k != OPTIMAL},
        out_dir / "vs_optimal.png",
        title=f"{summary['scenario']}: {len(study.source)} runs, each controller against the optimum",
    )
    plot_search_progress(
        study.search.objective,
        study.search.round_t_recover_s,
        cfg.iterations // cfg.rounds,
        out_dir / "search_progress.png",
    )


def write_demos(path: Path, study: OptimalStudy, target_alpha_rad: float) -> Path:
    """The searched control's re-simulated trajectories as demonstrations (``optimal.demos`` format)."""
    from harv_jax.optimal.demos import make_demos, save_demos

    x_all, u_cmd = study.trajectories
    m = study.search.metrics
    t = _times(study, 1e9)
    t_best = np.min(np.stack([t[k] for k in t if k != OPTIMAL]), axis=0)
    t_s = np.where(m.recovered, m.t_recover_s, np.nan)
    p = study.scenario.params
    beats = np.asarray(m.recovered) & (np.nan_to_num(t_s, nan=np.inf) < t_best)
    demos = make_demos(
        x_all,
        u_cmd,
        np.array([target_alpha_rad, 0.0, 0.0]),
        np.asarray(p.u_min_rad),
        np.asarray(p.u_max_rad),
        t_s,
        m.recovered,
        beats,
        DT_S,
    )
    return save_demos(path, demos)
