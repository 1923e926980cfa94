"""A Monte Carlo study of registered controllers (``harv-jax mc``): run, summarize, write its folder.

[`monte_carlo`][] flies every controller on the same sampled aircraft and initial states
(``montecarlo.inputs.sample_mc_inputs``, common random numbers) and returns a [`MonteCarloStudy`][];
[`write_monte_carlo`][] writes summary.json, the band figures and CSVs, terminal_errors.png and runs.csv.
"""

from __future__ import annotations

import csv
import dataclasses
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from harv_jax import atomic
from harv_jax.aircraft.registry import resolve_aircraft
from harv_jax.control.base import Controller
from harv_jax.control.hybrid.settings import DEFAULT_ZETA
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.dynamics import WIND_STATE_NAMES
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec, describe_disturbances
from harv_jax.evaluation.montecarlo.paired import paired_vs_smc
from harv_jax.evaluation.montecarlo.rollout import MCRunOutput, run_mc, sample_mc_inputs
from harv_jax.evaluation.summary import mc_summary, summarize_controller
from harv_jax.numfmt import fmt_num, write_json
from harv_jax.task.criteria import OUTCOME_NAMES
from harv_jax.task.disturbance_table import BY_NAME
from harv_jax.task.spec import DT_S, H0_FT
from harv_jax.task.turbulent_criterion import criterion_record

if TYPE_CHECKING:
    from harv_jax.aircraft.params import AircraftParams


@dataclasses.dataclass(frozen=True)
class MonteCarloStudy:
    """The outcome of [`monte_carlo`][].

    Attributes:
        summary: the summary.json document (``harv_jax.evaluation.summary.mc_summary``).
        outputs: controller -> per-run MCRunOutput (numpy leaves, leading axis: run).
        x0_wind: [N, 10] the sampled initial wind states.
        t_record_s: [T_rec] times of the decimated histories, s.
        reference_rad: [3] alpha_d, beta_d, mu_d.
        disturbances: what the runs met (all zero: none).
    """

    summary: dict[str, Any]
    outputs: dict[str, MCRunOutput]
    x0_wind: np.ndarray
    t_record_s: np.ndarray
    reference_rad: np.ndarray
    disturbances: DisturbanceSpec = DisturbanceSpec()


def monte_carlo(
    controllers: list[str] | Mapping[str, Controller],
    policy: str | None,
    runs: int,
    target_alpha_rad: float,
    duration_s: float,
    seed: int,
    randomize: bool,
    chunk: int | None = None,
    record_every: int = 10,
    zeta: str = DEFAULT_ZETA,
    command: str = "",
    progress: Callable[[str], None] | None = None,
    disturbances: DisturbanceSpec | None = None,
    aircraft: str | AircraftParams | None = None,
) -> MonteCarloStudy:
    """Fly every controller on ``runs`` sampled runs (no files).

    ``controllers``: names of ``harv_jax.control.registry`` (built with ``policy`` and ``zeta``), or
    name -> ``Controller`` (a user's own controllers; ``policy`` and ``zeta`` are then only recorded).

    ``randomize``: the plant aircraft drawn per run, the controllers built on the nominal one (unless
    ``disturbances.controller_knows_aircraft``); ``disturbances``: noise, delay, gust, model error and lag
    (``harv_jax.evaluation.montecarlo.disturbances``; None: none). ``aircraft``: the nominal aircraft, a name
    of ``harv_jax.aircraft.registry`` or ``AircraftParams`` (None: the registry's default); recorded by name.
    """
    import jax
    import jax.numpy as jnp

    say = progress or (lambda _msg: None)
    options = ControllerOptions(policy=policy, zeta=zeta)
    if isinstance(controllers, Mapping):
        ctrls = dict(controllers)
    else:
        ctrls = {name: build_controller(name, options) for name in controllers}
    controllers = list(ctrls)
    n_steps = int(round(duration_s / DT_S))
    n_steps -= n_steps % record_every
    reference = jnp.array([target_alpha_rad, 0.0, 0.0])
    spec = disturbances or DisturbanceSpec()
    if randomize and spec.model_error == 0:
        spec = dataclasses.replace(spec, model_error=1.0)
    aircraft_name, nominal = resolve_aircraft(aircraft)
    inputs = sample_mc_inputs(jax.random.key(seed), runs, nominal, h0_ft=H0_FT, disturbances=spec)
    summary = mc_summary(
        controllers,
        policy,
        zeta,
        runs,
        target_alpha_rad,
        n_steps * DT_S,
        seed,
        randomize,
        DT_S,
        H0_FT,
        [str(d) for d in jax.local_devices()],
        command,
    )
    summary["disturbances"] = spec.as_dict()
    summary["recovery_criterion"] = criterion_record(spec.turbulence != "none")
    summary["aircraft"] = aircraft_name
    if spec.active:
        say(f"[mc] disturbances: {describe_disturbances(spec)}")
    outs = {}
    for name, ctrl in ctrls.items():
        say(f"[mc] {name}: {runs} runs x {n_steps} steps ...")
        out, wall = run_mc(ctrl, inputs, reference, n_steps, DT_S, record_every, chunk)
        outs[name] = out
        s = summary["controllers"][name] = summarize_controller(out, wall, n_steps, n_steps * DT_S)
        say(
            f"[mc] {name}: recovery {s['recovery_rate']:.3f}, outcomes {s['outcomes']}, recovery time "
            f"median {fmt_num(s['recovery_time_s']['p50'], unit='s')}, mean (not recovered at "
            f"{n_steps * DT_S:g} s) {fmt_num(s['t_recover_mean_nr_at_run_s'], unit='s')}, "
            f"compile {wall['compile']:.1f} s, run {wall['run']:.1f} s"
        )
    times = {name: (out.metrics.t_recover_s, out.metrics.recovered) for name, out in outs.items()}
    for name, vs in paired_vs_smc(times, n_steps * DT_S).items():
        summary["controllers"][name]["vs_smc"] = vs
        say(f"[mc] {name} vs smc: {paired_line(vs)}")
    n_rec = next(iter(outs.values())).history.shape[1]
    t_rec = np.arange(n_rec) * record_every * DT_S
    return MonteCarloStudy(summary, outs, np.asarray(inputs.x0_wind), t_rec, np.asarray(reference), spec)


def paired_line(vs: dict[str, Any]) -> str:
    """One line of a ``vs_smc`` block: shares of runs faster / slower by the margin, ratio of means."""
    ratio = vs["mean_ratio"]
    return (
        f"{100 * vs['faster_fraction']:.1f}% of runs faster by > {vs['margin_s']:g} s, "
        f"{100 * vs['slower_fraction']:.1f}% slower, mean recovery time "
        + ("-" if ratio is None else f"{ratio:.3f}x")
        + f" the smc's (paired, not recovered at {vs['run_length_s']:g} s)"
    )


def write_runs_csv(
    path: Path, x0: np.ndarray, outs: dict[str, MCRunOutput], disturbances: DisturbanceSpec | None = None
) -> None:
    """One row per (controller, run): initial state, outcome, metrics; with disturbances on, their levels
    (``noise_scale``, ``delay_ms``, ``gust_fps``, ``model_error``, ``actuator_lag_s``, the level option of
    each disturbance added to the table that is on, ``turbulence``) as the last columns."""

    header = (
        ["controller", "run"]
        + [f"{n}0" for n in WIND_STATE_NAMES]
        + [
            "outcome",
            "recovered",
            "t_recover_s",
            "terminal_alpha_err_deg",
            "terminal_beta_err_deg",
            "terminal_mu_err_deg",
            "altitude_loss_ft",
            "control_tv_rad",
            "chatter_index_rad2",
            "sat_position_fraction",
            "left_envelope",
        ]
    )
    extra: list[str] = []
    if disturbances is not None and disturbances.active:
        header += [BY_NAME[name].parameter for name in disturbances.levels] + ["turbulence"]
        extra = [f"{v:g}" for v in disturbances.levels.values()] + [disturbances.turbulence]
    with atomic.open_atomic(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for name, out in outs.items():
            m = out.metrics
            term = np.degrees(out.terminal_error_rad)
            for i in range(x0.shape[0]):
                w.writerow(
                    [
                        name,
                        i,
                        *[f"{v:.6g}" for v in x0[i]],
                        OUTCOME_NAMES[int(m.outcome[i])],
                        bool(m.recovered[i]),
                        f"{m.t_recover_s[i]:.4g}",
                        *[f"{v:.5g}" for v in term[i]],
                        f"{m.altitude_loss_ft[i]:.5g}",
                        f"{np.sum(m.control_tv_rad[i]):.5g}",
                        f"{np.sum(m.chatter_index_rad2[i]):.4g}",
                        f"{np.mean(m.sat_position_fraction[i]):.4g}",
                        bool(m.left_envelope[i]),
                        *extra,
                    ]
                )


def write_monte_carlo(out_dir: Path, study: MonteCarloStudy, save_trajectories: bool = False) -> None:
    """summary.json, bands_*.png/.csv (bands_all.png: every controller side by side, one column each; all
    band plots share one y-scale per variable), terminal_errors.png, runs.csv (and trajectories_*.npz:
    t_s [T], alpha_beta_mu_rad [N, T, 3] every ``record_every`` steps, if asked)."""
    from harv_jax.plots.mc import (
        band_limits_deg,
        plot_mc_bands,
        plot_mc_bands_overlay,
        plot_terminal_errors,
        write_bands_csv,
    )

    t_rec, outs, ref = study.t_record_s, study.outputs, study.reference_rad
    for name, out in outs.items():
        write_bands_csv(t_rec, out.history, out_dir / f"bands_{name}.csv")
        if save_trajectories:
            np.savez_compressed(
                out_dir / f"trajectories_{name}.npz", t_s=t_rec, alpha_beta_mu_rad=out.history
            )
    histories = {n: o.history for n, o in outs.items()}
    lims = band_limits_deg(histories, ref)  # one y-scale per variable across controllers
    s = study.summary
    alpha_deg = np.degrees(s["target_alpha_rad"])
    setting = f"N = {s['runs']}, alpha_d = {alpha_deg:.1f} deg, h0 = {s['h0_ft']:,.0f} ft"
    for name, h in histories.items():
        plot_mc_bands(
            t_rec,
            h,
            ref,
            out_dir / f"bands_{name}.png",
            title=f"{name}: Monte Carlo bands ({setting})",
            ylims_deg=lims,
        )
    if len(histories) > 1:
        plot_mc_bands_overlay(
            t_rec,
            histories,
            ref,
            out_dir / "bands_all.png",
            title=f"{', '.join(histories)}: Monte Carlo bands ({setting})",
        )
    plot_terminal_errors(
        {n: np.degrees(o.terminal_error_rad) for n, o in outs.items()}, out_dir / "terminal_errors.png"
    )
    write_runs_csv(out_dir / "runs.csv", study.x0_wind, outs, study.disturbances)
    write_json(out_dir / "summary.json", s)
