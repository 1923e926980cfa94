"""`harv-jax mc`: Monte Carlo of one or more controllers on common random initial states/aircraft."""

from __future__ import annotations

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
    knows_aircraft_option,
    policy_option,
    warn_loop_mismatch,
    zeta_option,
)
from harv_jax.control.registry import build_controller, parse_controllers
from harv_jax.evaluation.montecarlo.study import monte_carlo, write_monte_carlo
from harv_jax.guards import check_closed_loop_batch
from harv_jax.outdir import prepare_out_dir, read_paths
from harv_jax.study_options import StudyOptions, study_options
from harv_jax.task.spec import DT_S


@aircraft_option
@disturbance_options
@study_options(runs=1000, chunk=True)
def mc(
    controller: str = typer.Option("smc", help=controllers_help()),
    policy: str = policy_option(),
    zeta: str = zeta_option(),
    randomize: bool = typer.Option(
        False,
        help="Randomize mass, inertia and aero per run; the controllers are built on the nominal "
        "aircraft (model error; the same as model in --disturbances).",
    ),
    controller_knows_aircraft: bool = knows_aircraft_option(),
    out: Path = typer.Option(Path("runs/mc"), help="Output directory."),
    force: bool = force_option(),
    save_trajectories: bool = typer.Option(
        False, help="Also write trajectories_<controller>.npz (alpha, beta, mu of every run every 0.1 s)."
    ),
    study: StudyOptions = StudyOptions(),
    disturbance_spec: Any = None,
    aircraft_name: str | None = None,
) -> None:
    """Monte Carlo: same sampled aircraft/initial states for every controller; summary + figures."""
    names = parse_controllers(controller)
    options = controller_options(names, policy, zeta)  # refuses an option none of them reads
    steps = round(study.duration_s / DT_S)
    check_closed_loop_batch(study.runs, steps, 10, study.chunk, len(names))
    for name in names:  # fail fast, before creating the output directory
        build_controller(name, options)
    warn_loop_mismatch(names, policy, options.zeta)
    out_dir = prepare_out_dir(out, force, read_paths(policy))
    result = monte_carlo(
        names,
        policy,
        study.runs,
        study.target_alpha_rad,
        study.duration_s,
        study.seed,
        randomize,
        study.chunk,
        zeta=options.zeta,
        command=command_line(),
        progress=typer.echo,
        disturbances=disturbance_spec,
        aircraft=aircraft_name,
    )
    write_monte_carlo(out_dir, result, save_trajectories)
    typer.echo(f"wrote {out_dir}/summary.json, bands_*.png/.csv, terminal_errors.png, runs.csv")


def register(app: typer.Typer) -> None:
    """Add ``harv-jax mc`` to ``app``."""
    app.command()(mc)
