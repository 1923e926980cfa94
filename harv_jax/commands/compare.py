"""`harv-jax compare`: controllers (default RL-only, SMC-only, hybrid) on the spin and a fixed upset state.

The work is ``harv_jax.evaluation.comparison``: every controller flies from the same state; the overlaid
time histories use the paper's four-figure layout and one metrics table (Markdown + CSV) has a row per
scenario and controller.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from harv_jax.cli_options import (
    aircraft_option,
    check_fly_options,
    command_line,
    controller_options,
    controllers_help,
    disturbance_options,
    force_option,
    policy_option,
    real_number,
    warn_loop_mismatch,
    zeta_option,
)
from harv_jax.control.registry import build_controller, parse_controllers
from harv_jax.errors import UsageError
from harv_jax.evaluation.comparison import FIXED_STATE, write_comparison
from harv_jax.evaluation.comparison import compare as compare_controllers
from harv_jax.outdir import prepare_out_dir, read_paths
from harv_jax.state_file import load_state_file
from harv_jax.study_options import StudyOptions, study_options


@aircraft_option
@disturbance_options
@study_options(
    help={
        "duration": "Closed-loop time after engagement, s.",
        "seed": "Seed of the controller keys and of the disturbance draws.",
    },
)
def compare(
    controller: str = typer.Option("rl,smc,hybrid", help=controllers_help()),
    policy: str = policy_option(),
    zeta: str = zeta_option(),
    spin_s: float = typer.Option(
        30.0, parser=real_number, help="Seconds held in the spin before engagement."
    ),
    state: Path = typer.Option(
        None, help="Fixed-state scenario file (.json/.csv; default: a built-in upset)."
    ),
    out: Path = typer.Option(Path("runs/compare"), help="Output directory."),
    force: bool = force_option(),
    study: StudyOptions = StudyOptions(),
    disturbance_spec: Any = None,
    aircraft_name: str | None = None,
) -> None:
    """RL vs SMC vs hybrid on the spin and a fixed state: overlaid histories, metrics table (md, csv)."""
    names = parse_controllers(controller)
    options = controller_options(names, policy, zeta)  # refuses an option none of them reads
    zeta = options.zeta
    for name in names:
        check_fly_options(name, "sat", spin_s)
        build_controller(name, options)
    warn_loop_mismatch(names, policy, zeta)
    fixed_state = None
    if state is not None:
        if not state.is_file():
            what = "does not exist" if not state.exists() else "is not a file"
            raise UsageError(f"--state {str(state)!r} {what}; give a .json or .csv state file")
        fixed_state = load_state_file(state)

    fixed_state = FIXED_STATE if fixed_state is None else fixed_state
    out_dir = prepare_out_dir(out, force, read_paths(policy, state))
    comp = compare_controllers(
        names,
        policy,
        zeta,
        study.target_alpha_rad,
        study.duration_s,
        spin_s,
        fixed_state,
        study.seed,
        typer.echo,
        disturbances=disturbance_spec,
        aircraft=aircraft_name,
    )
    write_comparison(out_dir, comp, command_line())
    typer.echo(f"wrote {out_dir}/compare_metrics.md, compare_metrics.csv, *_trajectories.png, compare.json")


def register(app: typer.Typer) -> None:
    """Add the command(s) of this module to ``app``."""
    app.command()(compare)
