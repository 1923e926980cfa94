"""`harv-jax robustness`: every controller over levels of sensor noise, delay, gust, model error, lag and
Dryden turbulence."""

from __future__ import annotations

from pathlib import Path

import typer

from harv_jax import atomic
from harv_jax.cli_options import (
    aircraft_option,
    command_line,
    controller_options,
    controllers_help,
    force_option,
    policy_option,
    warn_loop_mismatch,
    zeta_option,
)
from harv_jax.control.registry import build_controller, parse_controllers
from harv_jax.errors import UsageError
from harv_jax.evaluation.montecarlo.disturbances import parse_turbulence
from harv_jax.evaluation.robustness import (
    SWEEP_NAMES,
    levels_from_options,
    margins_table,
    robustness_sweep,
)
from harv_jax.evaluation.summary import controllers_setting
from harv_jax.guards import check_closed_loop_batch
from harv_jax.numfmt import write_json
from harv_jax.outdir import prepare_out_dir, read_paths
from harv_jax.plots.robustness import plot_robustness
from harv_jax.study_options import StudyOptions, study_options
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S


def _levels_help(name: str, unit: str, default: str) -> str:
    return f"Levels of {name}, comma list, {unit} (default {default})."


@aircraft_option
@study_options(
    runs=256,
    target_alpha=False,
    chunk=True,
    help={"runs": "Monte Carlo runs per level.", "seed": "Monte Carlo seed (the same runs at every level)."},
)
def robustness(
    controller: str = typer.Option("smc,smc-brake,rl,hybrid", help=controllers_help()),
    policy: str = policy_option(),
    zeta: str = zeta_option(),
    disturbances: str = typer.Option(
        "noise,delay,gust,model,lag,turbulence",
        help="Disturbances to sweep, comma list (the others stay off).",
    ),
    noise_levels: str = typer.Option(None, help=_levels_help("noise", "x the env's noise std", "0,1,2,3,5")),
    delay_levels: str = typer.Option(None, help=_levels_help("delay", "ms", "0,50,100,150,200")),
    gust_levels: str = typer.Option(None, help=_levels_help("gust", "ft/s", "0,2.5,5,10,20,30")),
    model_levels: str = typer.Option(
        None, help=_levels_help("model error", "x the randomization ranges", "0,0.5,1,1.5,2")
    ),
    lag_levels: str = typer.Option(None, help=_levels_help("actuator lag", "s", "0,0.03,0.06,0.1,0.2")),
    turbulence_levels: str = typer.Option(
        None,
        help=_levels_help("Dryden turbulence sigma", "ft/s above 2000 ft", "0,2.5,5,7.5,10,15,20")
        + " 0 is still air; the others are scored by the criterion in turbulence.",
    ),
    turbulence: str = typer.Option(
        "none",
        help="Dryden turbulence the levels of the other disturbances fly in: none, light, moderate, "
        "severe or a sigma in ft/s.",
    ),
    out: Path = typer.Option(Path("runs/robustness"), help="Output directory."),
    force: bool = force_option(),
    study: StudyOptions = StudyOptions(),
    aircraft_name: str | None = None,
) -> None:
    """Margins: recovery, mean recovery time and TV of each controller against each disturbance level."""
    names = parse_controllers(controller)
    options = controller_options(names, policy, zeta)  # refuses an option none of them reads
    zeta = options.zeta
    swept = [p.strip() for p in disturbances.split(",") if p.strip()]
    bad = [p for p in swept if p not in SWEEP_NAMES]
    if bad or not swept or len(set(swept)) < len(swept):
        raise UsageError(
            f"--disturbances {disturbances!r}: allowed: a comma list of {', '.join(SWEEP_NAMES)}, each once"
        )
    turbulence = parse_turbulence(turbulence)
    given = {
        "noise": noise_levels,
        "delay": delay_levels,
        "gust": gust_levels,
        "model": model_levels,
        "lag": lag_levels,
        "turbulence": turbulence_levels,
    }
    for name, text in given.items():
        if text is not None and name not in swept:
            raise UsageError(f"--{name}-levels {text!r} given but {name} is not in --disturbances")
    levels = levels_from_options(given, swept)
    check_closed_loop_batch(study.runs, round(study.duration_s / DT_S), 100, study.chunk, len(names))
    ctrls = {name: build_controller(name, options) for name in names}  # fails before any folder exists
    warn_loop_mismatch(names, policy, zeta)
    out_dir = prepare_out_dir(out, force, read_paths(policy))
    doc = robustness_sweep(
        ctrls,
        study.runs,
        study.seed,
        levels,
        ALPHA_TARGET_RAD,
        study.duration_s,
        study.chunk,
        typer.echo,
        aircraft=aircraft_name,
        turbulence=turbulence,
    )
    doc.update(controllers_setting(names, policy, zeta))
    doc["command"] = command_line()
    write_json(out_dir / "robustness.json", doc)
    plot_robustness(doc, out_dir)
    atomic.write_text(out_dir / "margins.md", "\n".join(margins_table(doc)) + "\n")
    typer.echo("\n".join(margins_table(doc)))
    typer.echo(f"wrote {out_dir}/robustness.json, margins.md, robustness_<disturbance>.png")


def register(app: typer.Typer) -> None:
    """Add ``harv-jax robustness`` to ``app``."""
    app.command()(robustness)
