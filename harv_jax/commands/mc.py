"""`harv-jax mc`: Monte Carlo of one or more controllers on common random initial states/aircraft."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from harv_jax.cli_options import (
    aircraft_option,
    chunk_option,
    controllers_help,
    disturbance_options,
    force_option,
    knows_aircraft_option,
    policy_option,
    real_number,
    whole_number,
    zeta_option,
)
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S


def register(app: typer.Typer) -> None:
    @app.command()
    @aircraft_option
    @disturbance_options
    def mc(
        controller: str = typer.Option("smc", help=controllers_help()),
        policy: str = policy_option(),
        zeta: str = zeta_option(),
        runs: int = typer.Option(1000, parser=whole_number, help="Number of Monte Carlo runs."),
        target_alpha: float = typer.Option(
            ALPHA_TARGET_RAD, parser=real_number, help="Target angle of attack, rad."
        ),
        duration: float = typer.Option(60.0, parser=real_number, help="Run length, s."),
        seed: int = typer.Option(
            0, parser=whole_number, help="Seed of initial states, aircraft and controller keys."
        ),
        randomize: bool = typer.Option(
            False,
            help="Randomize mass, inertia and aero per run; the controllers are built on the nominal "
            "aircraft (model error; the same as model in --disturbances).",
        ),
        controller_knows_aircraft: bool = knows_aircraft_option(),
        chunk: int | None = chunk_option(),
        out: Path = typer.Option(Path("runs/mc"), help="Output directory."),
        force: bool = force_option(),
        save_trajectories: bool = typer.Option(
            False, help="Also write trajectories_<controller>.npz (alpha, beta, mu of every run every 0.1 s)."
        ),
        disturbance_spec: Any = None,
        aircraft_name: str | None = None,
    ) -> None:
        """Monte Carlo: same sampled aircraft/initial states for every controller; summary + figures."""
        from harv_jax.cli_options import (
            check_mc_options,
            command_line,
            controller_options,
            warn_loop_mismatch,
        )
        from harv_jax.control.registry import build_controller, parse_controllers
        from harv_jax.guards import check_closed_loop_batch, check_seed
        from harv_jax.outdir import prepare_out_dir, read_paths

        names = parse_controllers(controller)
        options = controller_options(names, policy, zeta)  # refuses an option none of them reads
        zeta = options.zeta
        check_mc_options(runs, target_alpha, duration, chunk)
        check_seed(seed)
        check_closed_loop_batch(runs, round(duration / DT_S), 10, chunk, len(names))
        # the heavy imports (jax) only after the arguments are checked: bad input fails fast
        from harv_jax.evaluation.montecarlo.study import monte_carlo, write_monte_carlo

        for name in names:  # fail fast, before creating the output directory
            build_controller(name, options)
        warn_loop_mismatch(names, policy, zeta)
        out_dir = prepare_out_dir(out, force, read_paths(policy))
        study = monte_carlo(
            names,
            policy,
            runs,
            target_alpha,
            duration,
            seed,
            randomize,
            chunk,
            zeta=zeta,
            command=command_line(),
            progress=typer.echo,
            disturbances=disturbance_spec,
            aircraft=aircraft_name,
        )
        write_monte_carlo(out_dir, study, save_trajectories)
        typer.echo(f"wrote {out_dir}/summary.json, bands_*.png/.csv, terminal_errors.png, runs.csv")
