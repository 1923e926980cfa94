"""`harv-jax envelope`: recovery envelope map of one or more controllers over a 2-D initial-state grid.

The command parses the grid flags; the work is ``harv_jax.evaluation.envelope.study``.

Outputs in DIR: ``envelope_recovery.png`` (outcome maps side by side), ``envelope_time.png`` (recovery
time maps), ``envelope.json`` (grid axes, fixed states, per-controller recovery rate, outcome
counts, recovery-time statistics, wall times), ``envelope_grid.csv`` (one row per controller and grid
point) and ``envelope_grid.npz`` (the maps as arrays: ``x_values``, ``y_values``, ``x0_wind`` and
``<controller>/<field>`` [n_y, n_x]). See ``harv_jax.evaluation.envelope.grid`` for the grid layout and
the default fixed states.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import typer

from harv_jax.cli_options import (
    aircraft_option,
    command_line,
    controller_options,
    controllers_help,
    disturbance_options,
    force_option,
    policy_option,
    warn_loop_mismatch,
    whole_number,
    zeta_option,
)
from harv_jax.control.registry import build_controller, parse_controllers
from harv_jax.dynamics.state import WIND_STATE_NAMES
from harv_jax.errors import UsageError
from harv_jax.evaluation.envelope.grid import GRID_AXES, make_grid
from harv_jax.evaluation.envelope.study import envelope_study, write_envelope
from harv_jax.guards import check_closed_loop_batch
from harv_jax.outdir import prepare_out_dir, read_paths
from harv_jax.study_options import StudyOptions, study_options
from harv_jax.task.spec import DT_S, H0_FT

MAX_POINTS_PER_AXIS = 1000


def _float(text: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise UsageError(f"{what}: {text!r} is not a number") from None
    if not math.isfinite(v):
        raise UsageError(f"{what}: {text!r} is not finite")
    return v


def parse_grid(text: str) -> tuple[tuple[str, tuple[float, float] | None], ...]:
    """``"X:Y"`` with optional ranges ``"alpha0=-0.2,1.0:r0"`` -> ((X, range|None), (Y, range|None)).

    Ranges are in state units (ft/s, rad, rad/s, ft). UsageError on a malformed text or unknown axis.
    """
    parts = text.split(":")
    if len(parts) != 2:
        raise UsageError(f"--grid {text!r} must name two axes as X:Y (e.g. alpha0:r0, V0:alpha0)")
    axes = []
    for part in parts:
        name, _, rng = part.strip().partition("=")
        name = name.strip()
        if name not in GRID_AXES:
            raise UsageError(f"--grid axis {name!r} is unknown; allowed: {', '.join(GRID_AXES)}")
        if not rng:
            axes.append((name, None))
            continue
        bounds = rng.split(",")
        if len(bounds) != 2:
            raise UsageError(f"--grid range {part!r} must be NAME=LOW,HIGH (state units)")
        lo, hi = (_float(b, f"--grid range of {name}") for b in bounds)
        if not lo < hi:
            raise UsageError(f"--grid range of {name} must have LOW < HIGH (got {lo:g}, {hi:g})")
        axes.append((name, (lo, hi)))
    if axes[0][0] == axes[1][0]:
        raise UsageError(f"--grid {text!r} names {axes[0][0]} twice")
    return tuple(axes)


def parse_fixed(text: str) -> dict[str, float]:
    """``"V0=300,h0=20000"`` -> {"V": 300.0, "h": 20000.0} (state units); UsageError on bad input."""
    out: dict[str, float] = {}
    for item in (t.strip() for t in text.split(",")):
        if not item:
            continue
        name, eq, val = item.partition("=")
        name = name.strip()
        state = name[:-1] if name.endswith("0") else name
        if not eq or state not in WIND_STATE_NAMES:
            raise UsageError(
                f"--fixed {item!r} must be NAME=VALUE with NAME one of "
                f"{', '.join(n + '0' for n in WIND_STATE_NAMES)}"
            )
        out[state] = _float(val, f"--fixed {name}")
    return out


def build_grid(grid: str, n: int, fixed: str):
    """EnvelopeGrid from the CLI flags; UsageError (one line) for any bad value."""
    if not 2 <= n <= MAX_POINTS_PER_AXIS:
        raise UsageError(f"--n {n} must be in [2, {MAX_POINTS_PER_AXIS}] (points per grid axis)")
    (x_name, x_rng), (y_name, y_rng) = parse_grid(grid)
    fixed_values = parse_fixed(fixed)
    for name in (x_name, y_name):
        if GRID_AXES[name].state in fixed_values:
            raise UsageError(f"--fixed sets {name}, which is a grid axis")
    try:
        return make_grid(x_name, y_name, n, n, x_rng, y_rng, fixed_values)
    except ValueError as e:
        raise UsageError(str(e)) from None


@aircraft_option
@disturbance_options
@study_options(
    chunk=True,
    help={"seed": "Seed of the controllers' keys (the grid itself is deterministic)."},
)
def envelope(
    controller: str = typer.Option("smc", help=controllers_help()),
    policy: str = policy_option(),
    grid: str = typer.Option(
        "alpha0:r0",
        help="Grid axes X:Y from V0, alpha0, beta0, p0, q0, r0, mu0, gamma0, h0; optional ranges in "
        "state units (ft/s, rad, rad/s, ft), e.g. 'alpha0=-0.175,1.047:r0'. Default ranges: the "
        "paper's reset bounds.",
    ),
    n: int = typer.Option(100, parser=whole_number, help="Points per grid axis (n x n runs per controller)."),
    fixed: str = typer.Option(
        "",
        help="Off-grid initial states, e.g. 'V0=300,h0=20000' (default V0=800 ft/s, alpha0=0.436 rad, "
        f"beta0=p0=q0=r0=mu0=gamma0=chi0=0, h0={H0_FT:g} ft).",
    ),
    zeta: str = zeta_option(),
    out: Path = typer.Option(Path("runs/envelope"), help="Output directory."),
    force: bool = force_option(),
    study: StudyOptions = StudyOptions(),
    disturbance_spec: Any = None,
    aircraft_name: str | None = None,
) -> None:
    """Recovery envelope map: outcome and recovery time over an initial-state grid, per controller."""
    names = parse_controllers(controller)
    options = controller_options(names, policy, zeta)  # refuses an option none of them reads
    zeta = options.zeta
    g = build_grid(grid, n, fixed)
    study = replace(study, runs=g.n_runs)  # checks the grid's run count as --runs
    n_steps = round(study.duration_s / DT_S)
    check_closed_loop_batch(g.n_runs, n_steps, n_steps, study.chunk, len(names), runs_flag="--n x --n =")
    for name in names:  # fail fast, before creating the output directory
        build_controller(name, options)
    warn_loop_mismatch(names, policy, zeta)
    out_dir = prepare_out_dir(out, force, read_paths(policy))
    result = envelope_study(
        names,
        policy,
        g,
        study.target_alpha_rad,
        study.duration_s,
        study.seed,
        study.chunk,
        zeta,
        command_line(),
        typer.echo,
        disturbances=disturbance_spec,
        aircraft=aircraft_name,
    )
    write_envelope(out_dir, result)
    typer.echo(
        f"wrote {out_dir}/envelope_recovery.png, envelope_time.png, envelope.json, envelope_grid.csv, "
        "envelope_grid.npz"
    )


def register(app: typer.Typer) -> None:
    """Add the command(s) of this module to ``app``."""
    app.command()(envelope)
