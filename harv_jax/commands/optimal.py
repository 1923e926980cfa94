"""`harv-jax optimal`: near-optimal recoveries by gradient search through the JAX rollout, against the
registry's controllers (``harv_jax.optimal``)."""

from __future__ import annotations

import math
from pathlib import Path

import typer

from harv_jax import atomic
from harv_jax.aircraft.registry import DEFAULT_AIRCRAFT
from harv_jax.cli_options import (
    aircraft_option,
    command_line,
    force_option,
    real_number,
    whole_number,
)
from harv_jax.errors import UsageError
from harv_jax.optimal.demos import check_demos_path
from harv_jax.outdir import check_out_dir, prepare_out_dir, read_paths
from harv_jax.report.optimal_section import optimal_markdown
from harv_jax.state_file import SCENARIOS, load_state_file
from harv_jax.study_options import StudyOptions, study_options
from harv_jax.task.spec import DT_S

#: The search's run length (the Monte Carlo's) and its surrogate's hold window, s (``optimal.search``
#: defaults; repeated here so that the arguments are checked before the search is imported).
RUN_S = 60.0
SURROGATE_HOLD_S = 5.0


@aircraft_option
@study_options(
    runs=256,
    duration=False,
    help={
        "runs": "Monte Carlo runs (scenario random).",
        "seed": "Seed of the Monte Carlo draw (as harv-jax mc).",
    },
)
def optimal(
    scenario: str = typer.Option(
        "random",
        help="random (the standard Monte Carlo draw), spin (the developed spin) or a state file.",
    ),
    iterations: int = typer.Option(12, parser=whole_number, help="Gradient steps per run."),
    horizon: float = typer.Option(15.0, parser=real_number, help="Optimization horizon, s."),
    knot_spacing: float = typer.Option(1.0, parser=real_number, help="Spacing of the reference knots, s."),
    learning_rate: float = typer.Option(
        0.3,
        parser=real_number,
        help="Length of each step in the raw knots (per-run normalized gradient).",
    ),
    spin_s: float = typer.Option(30.0, parser=real_number, help="Seconds in the spin before engagement."),
    out: Path = typer.Option(Path("runs/optimal"), help="Output directory."),
    force: bool = force_option(),
    save_demos: Path = typer.Option(None, help="Also write the optimized trajectories as demos (.npz)."),
    study: StudyOptions = StudyOptions(),
    aircraft_name: str | None = None,
) -> None:
    """Per run a recovery near the fastest the aircraft allows, against smc, smc-brake, rl, hybrid."""
    if iterations < 1:
        raise UsageError(f"--iterations {iterations} must be >= 1")
    hold_s, run_s = SURROGATE_HOLD_S, RUN_S
    if not (math.isfinite(horizon) and hold_s < horizon <= run_s):
        raise UsageError(
            f"--horizon {horizon} s must be in ({hold_s:g}, {run_s:g}] s (longer than the surrogate's "
            f"{hold_s:g} s hold window, at most the run length)"
        )
    span_s = horizon - hold_s
    if not (math.isfinite(knot_spacing) and DT_S <= knot_spacing <= span_s):
        raise UsageError(
            f"--knot-spacing {knot_spacing} s must be in [{DT_S:g}, {span_s:g}] s (the plant step to the "
            "horizon less the hold window)"
        )
    if not (math.isfinite(learning_rate) and 0.0 < learning_rate <= 10.0):
        raise UsageError(f"--learning-rate {learning_rate} must be in (0, 10]")
    if not (math.isfinite(spin_s) and 0.0 <= spin_s <= 600.0):
        raise UsageError(f"--spin-s {spin_s} must be in [0, 600] s")
    state = None if scenario in SCENARIOS else load_state_file(Path(scenario))
    if save_demos is not None:
        try:
            check_demos_path(save_demos)
        except ValueError as e:
            raise UsageError(str(e)) from None
    check_out_dir(out, force, read_paths(scenario))
    # the search pulls optax: imported here, not by every command (tools/results/house/cli_startup.json)
    from harv_jax.optimal.outputs import build_summary, write_demos, write_optimal
    from harv_jax.optimal.search import SearchConfig, rounds_for
    from harv_jax.optimal.study import mc_scenario, optimal_study, spin_scenario, state_scenario

    cfg = SearchConfig(
        horizon_s=horizon,
        knot_dt_s=knot_spacing,
        iterations=iterations,
        rounds=rounds_for(iterations),
        learning_rate=learning_rate,
    )
    out_dir = prepare_out_dir(out, force, read_paths(scenario))
    if scenario == "random":
        sc = mc_scenario(study.seed, study.runs, aircraft_name)
    elif scenario == "spin":
        sc = spin_scenario(spin_s, study.seed, aircraft_name)
    else:
        sc = state_scenario(state, study.seed, aircraft_name)
    result = optimal_study(sc, study.target_alpha_rad, cfg, progress=typer.echo)
    summary = build_summary(result, cfg, study.target_alpha_rad, study.seed, command_line(), sc.name)
    summary["aircraft"] = aircraft_name or DEFAULT_AIRCRAFT
    if scenario == "spin":
        summary["spin_s"] = spin_s
    write_optimal(out_dir, result, summary, cfg)
    atomic.write_text(out_dir / "optimal_report.md", optimal_markdown(summary))
    typer.echo(
        f"wrote {out_dir}/runs.csv, optimal_runs.csv, summary.json, vs_optimal.png, "
        "search_progress.png, optimal_report.md"
    )
    if save_demos is not None:
        typer.echo(f"wrote {write_demos(save_demos, result, study.target_alpha_rad)}")


def register(app: typer.Typer) -> None:
    """Add the command(s) of this module to ``app``."""
    app.command()(optimal)
