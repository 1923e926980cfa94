"""`harv-jax fly`: closed-loop flight of a controller from a scenario; CSV, PNGs and metrics.json."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from harv_jax.aircraft.registry import DEFAULT_AIRCRAFT
from harv_jax.cli_options import (
    aircraft_option,
    check_fly_options,
    controller_options,
    disturbance_options,
    force_option,
    policy_option,
    real_number,
    warn_loop_mismatch,
    zeta_option,
)
from harv_jax.control.registry import build_controller
from harv_jax.evaluation.flight import fly as fly_scenario
from harv_jax.evaluation.flight import write_flight
from harv_jax.evaluation.summary import flight_settings
from harv_jax.outdir import prepare_out_dir, read_paths
from harv_jax.state_file import SCENARIOS, load_state_file
from harv_jax.study_options import StudyOptions, study_options
from harv_jax.task.spec import DT_S


@aircraft_option
@disturbance_options
@study_options(
    help={
        "duration": "Closed-loop flight time after engagement, s.",
        "seed": "Seed of the random scenario and of the controller key.",
    },
)
def fly(
    controller: str = typer.Option(
        "smc", help="Controller: smc, rl (policy only), hybrid or another in harv_jax.control.registry."
    ),
    policy: str = policy_option(),
    zeta: str = zeta_option(),
    scenario: str = typer.Option(
        "spin",
        help="spin (30 s pro-spin open loop, then the controller), random (one state from the "
        "paper's reset bounds, drawn with --seed) or a .json/.csv state file (V, alpha, beta, p, q, "
        "r, mu, gamma; optional chi, h).",
    ),
    out: Path = typer.Option(Path("runs/fly"), help="Output directory."),
    force: bool = force_option(),
    switching: str = typer.Option(
        None, help="SMC switching: sat (boundary layer, default) or sign (paper).", show_default=False
    ),
    spin_s: float = typer.Option(
        30.0, parser=real_number, help="Spin scenario: seconds held in the spin before engagement."
    ),
    study: StudyOptions = StudyOptions(),
    disturbance_spec: Any = None,
    aircraft_name: str | None = None,
) -> None:
    """Fly a controller closed loop: trajectory.csv, trajectory.png, sliding.png, metrics.json (and
    hybrid.png for the hybrid)."""
    check_fly_options(controller, switching, spin_s)
    opts = controller_options([controller], policy, zeta, switching)  # refuses an option it does not read
    zeta, switching = opts.zeta, opts.switching
    # validate the state file, the policy and zeta before creating the output directory
    state = scenario if scenario in SCENARIOS else load_state_file(Path(scenario))

    build_controller(controller, opts)
    warn_loop_mismatch([controller], policy, zeta)
    out_dir = prepare_out_dir(out, force, read_paths(policy, scenario))
    res = fly_scenario(
        state,
        study.target_alpha_rad,
        study.duration_s,
        study.seed,
        switching,
        spin_s,
        controller,
        policy,
        zeta,
        disturbances=disturbance_spec,
        aircraft=aircraft_name,
    )
    settings = flight_settings(
        controller,
        policy,
        zeta,
        switching,
        scenario,
        study.seed,
        study.duration_s,
        DT_S,
        study.target_alpha_rad,
        spin_s,
    )
    settings["disturbances"] = disturbance_spec.as_dict()
    settings["aircraft"] = aircraft_name or DEFAULT_AIRCRAFT
    write_flight(out_dir, res, settings)
    m = res.metrics
    t_rec = m["t_recover_s"]
    typer.echo(
        f"wrote {out_dir}/trajectory.csv, trajectory.png, sliding.png, metrics.json: outcome "
        f"{m['outcome_name']}" + (f", recovered {t_rec:.2f} s after engagement" if t_rec is not None else "")
    )


def register(app: typer.Typer) -> None:
    """Add the command(s) of this module to ``app``."""
    app.command()(fly)
