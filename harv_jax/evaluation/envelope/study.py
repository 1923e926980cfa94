"""A recovery envelope map of registered controllers (``harv-jax envelope``): run and write its folder.

[`envelope_study`][] flies every controller from every point of an ``EnvelopeGrid``
(``harv_jax.evaluation.envelope.grid``) and returns an [`EnvelopeStudy`][]; [`write_envelope`][]
writes envelope_recovery.png, envelope_time.png, envelope.json, envelope_grid.csv and envelope_grid.npz.
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
from harv_jax.evaluation.envelope.grid import (
    GRID_AXES,
    EnvelopeGrid,
    EnvelopeMap,
    envelope_inputs,
    grid_description,
    grid_states,
    run_envelope,
)
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.evaluation.montecarlo.rollout import sample_mc_inputs
from harv_jax.evaluation.summary import RECOVERY_RATE, envelope_summary, summarize_envelope
from harv_jax.numfmt import write_json
from harv_jax.task.criteria import OUTCOME_NAMES
from harv_jax.task.spec import DT_S

if TYPE_CHECKING:
    from harv_jax.aircraft.params import AircraftParams


@dataclasses.dataclass(frozen=True)
class EnvelopeStudy:
    """The outcome of [`envelope_study`][].

    Attributes:
        summary: the envelope.json document (``harv_jax.evaluation.summary.envelope_summary``).
        grid: the grid flown.
        maps: controller -> EnvelopeMap ([n_y, n_x] fields).
    """

    summary: dict[str, Any]
    grid: EnvelopeGrid
    maps: dict[str, EnvelopeMap]


def envelope_study(
    controllers: list[str] | Mapping[str, Controller],
    policy: str | None,
    grid: EnvelopeGrid,
    target_alpha_rad: float,
    duration_s: float,
    seed: int,
    chunk: int | None = None,
    zeta: str = DEFAULT_ZETA,
    command: str = "",
    progress: Callable[[str], None] | None = None,
    disturbances: DisturbanceSpec | None = None,
    aircraft: str | AircraftParams | None = None,
) -> EnvelopeStudy:
    """Fly every controller from every grid point (no files); ``disturbances``: the draws of a Monte Carlo
    with ``seed`` and as many runs (``montecarlo.inputs.sample_mc_inputs``), the grid's initial states;
    ``aircraft``: the nominal aircraft (a registry name or ``AircraftParams``; None: the default)."""
    import jax
    import jax.numpy as jnp

    say = progress or (lambda _msg: None)
    options = ControllerOptions(policy=policy, zeta=zeta)
    if isinstance(controllers, Mapping):  # a user's own controllers, name -> Controller
        ctrls = dict(controllers)
    else:
        ctrls = {name: build_controller(name, options) for name in controllers}
    controllers = list(ctrls)
    n_steps = int(round(duration_s / DT_S))
    reference = jnp.array([target_alpha_rad, 0.0, 0.0])
    aircraft_name, nominal = resolve_aircraft(aircraft)
    inputs = envelope_inputs(jax.random.key(seed), grid, nominal)
    spec = disturbances or DisturbanceSpec()
    if spec.active:
        drawn = sample_mc_inputs(jax.random.key(seed), grid.n_runs, nominal, disturbances=spec)
        inputs = drawn.replace(x0_wind=inputs.x0_wind, keys=inputs.keys)
    doc = envelope_summary(
        controllers,
        policy,
        zeta,
        grid_description(grid),
        grid.n_runs,
        target_alpha_rad,
        n_steps * DT_S,
        DT_S,
        seed,
        [str(d) for d in jax.local_devices()],
        command,
    )
    doc["disturbances"] = spec.as_dict()
    doc["aircraft"] = aircraft_name
    maps = {}
    for name, ctrl in ctrls.items():
        say(f"[envelope] {name}: {grid.n_y} x {grid.n_x} = {grid.n_runs} runs x {n_steps} steps ...")
        m, out, wall = run_envelope(ctrl, inputs, grid, reference, n_steps, DT_S, chunk)
        maps[name] = m
        block = doc["controllers"][name] = summarize_envelope(out, wall, n_steps)
        say(
            f"[envelope] {name}: recovered {100 * block[RECOVERY_RATE]:.1f}%, "
            f"compile {wall['compile']:.1f} s, run {wall['run']:.1f} s"
        )
    return EnvelopeStudy(doc, grid, maps)


def write_grid_csv(path: Path, grid: EnvelopeGrid, maps: dict[str, EnvelopeMap]) -> None:
    """One row per (controller, grid point): indices, the two grid values, outcome and metrics."""

    xs, ys = grid.x_values, grid.y_values
    header = [
        "controller",
        "ix",
        "iy",
        grid.x_name,
        grid.y_name,
        "outcome",
        "recovered",
        "t_recover_s",
        "t_recover_alpha_s",
        "altitude_loss_ft",
        "terminal_alpha_err_deg",
        "terminal_beta_err_deg",
        "terminal_mu_err_deg",
    ]
    with atomic.open_atomic(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for name, m in maps.items():
            term = np.degrees(m.terminal_error_rad)
            for iy in range(grid.n_y):
                for ix in range(grid.n_x):
                    w.writerow(
                        [
                            name,
                            ix,
                            iy,
                            f"{xs[ix]:.6g}",
                            f"{ys[iy]:.6g}",
                            OUTCOME_NAMES[int(m.outcome[iy, ix])],
                            bool(m.recovered[iy, ix]),
                            f"{m.t_recover_s[iy, ix]:.4g}",
                            f"{m.t_recover_alpha_s[iy, ix]:.4g}",
                            f"{m.altitude_loss_ft[iy, ix]:.5g}",
                            *[f"{v:.5g}" for v in term[iy, ix]],
                        ]
                    )


def write_envelope(out_dir: Path, study: EnvelopeStudy) -> None:
    """envelope_recovery.png, envelope_time.png, envelope_grid.npz, envelope_grid.csv and envelope.json."""
    from harv_jax.plots.maps import plot_outcome_maps, plot_time_maps

    doc, grid, maps = study.summary, study.grid, study.maps
    duration_s, alpha_deg = doc["duration_s"], np.degrees(doc["target_alpha_rad"])
    ax_x, ax_y = GRID_AXES[grid.x_name], GRID_AXES[grid.y_name]
    x_disp, y_disp = grid.x_values * ax_x.display_scale, grid.y_values * ax_y.display_scale
    x_label, y_label = f"{grid.x_name} [{ax_x.display_unit}]", f"{grid.y_name} [{ax_y.display_unit}]"
    fixed = ", ".join(f"{k}0={v:g}" for k, v in doc["grid"]["fixed_state"].items() if v != 0.0) + ", others 0"
    plot_outcome_maps(
        x_disp,
        y_disp,
        {n: m.outcome for n, m in maps.items()},
        OUTCOME_NAMES,
        x_label,
        y_label,
        out_dir / "envelope_recovery.png",
        title=f"recovery outcome after {duration_s:g} s, alpha_d = {alpha_deg:.1f} deg\n(fixed: {fixed})",
        duration_s=duration_s,
    )
    plot_time_maps(
        x_disp,
        y_disp,
        {n: m.t_recover_s for n, m in maps.items()},
        x_label,
        y_label,
        out_dir / "envelope_time.png",
        title=f"recovery time (grey: not recovered by {duration_s:g} s), alpha_d = "
        f"{alpha_deg:.1f} deg\n(fixed: {fixed})",
    )
    arrays = {"x_values": grid.x_values, "y_values": grid.y_values, "x0_wind": grid_states(grid)}
    for name, m in maps.items():
        arrays.update({f"{name}/{field}": np.asarray(v) for field, v in m._asdict().items()})
    atomic.savez(out_dir / "envelope_grid.npz", compressed=True, **arrays)
    write_grid_csv(out_dir / "envelope_grid.csv", grid, maps)
    write_json(out_dir / "envelope.json", doc)
