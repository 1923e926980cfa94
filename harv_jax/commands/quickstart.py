"""`harv-jax quickstart`: the main job on shipped defaults.

1. the spin comparison: SMC-only, the braking SMC (``smc-brake``), RL-only and hybrid after a 30 s developed
   spin, and from a fixed upset (as ``harv-jax compare``), with the shipped policy;
2. a Monte Carlo of the same controllers from the paper's reset bounds (as ``harv-jax mc``);
3. the report of both (as ``harv-jax report``): report.md and report.html.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import typer

from harv_jax.cli_options import (
    aircraft_option,
    command_line,
    controller_options,
    disturbance_options,
    force_option,
    policy_option,
    warn_loop_mismatch,
    zeta_option,
)
from harv_jax.control.registry import build_controller
from harv_jax.evaluation.comparison import FIXED_STATE, compare, write_comparison
from harv_jax.evaluation.montecarlo.study import monte_carlo, write_monte_carlo
from harv_jax.guards import check_closed_loop_batch
from harv_jax.numfmt import fmt_num
from harv_jax.outdir import prepare_out_dir, read_paths
from harv_jax.report import build_report
from harv_jax.study_options import StudyOptions, study_options
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S

#: The controllers of the quickstart (names in harv_jax.control.registry).
QUICKSTART_CONTROLLERS = ("smc", "smc-brake", "smc-brake-zoom", "rl", "hybrid")
DURATION_S = 60.0
SPIN_S = 30.0
CHUNK: int | None = None  # runs per compiled call: guards.auto_chunk


@aircraft_option
@disturbance_options
@study_options(runs=1000, duration=False, target_alpha=False, help={"seed": "Seed of the Monte Carlo."})
def quickstart(
    out: Path = typer.Option(Path("runs/quickstart"), help="Output directory."),
    policy: str = policy_option(),
    zeta: str = zeta_option(),
    force: bool = force_option(),
    study: StudyOptions = StudyOptions(),
    disturbance_spec: Any = None,
    aircraft_name: str | None = None,
) -> None:
    """Spin comparison and a Monte Carlo of SMC, braking SMC, RL and hybrid with the shipped policy, plus
    a report."""
    names = list(QUICKSTART_CONTROLLERS)
    options = controller_options(names, policy, zeta)  # refuses an option none of them reads
    zeta = options.zeta
    check_closed_loop_batch(study.runs, round(DURATION_S / DT_S), 10, CHUNK, len(names))

    for name in names:
        build_controller(name, options)
    warn_loop_mismatch(names, policy, zeta)
    out_dir = prepare_out_dir(out, force, read_paths(policy))
    t0 = time.perf_counter()
    typer.echo(f"[quickstart] 1/3 spin comparison: 30 s developed spin, then {', '.join(names)} recover")
    prepare_out_dir(out_dir / "compare")  # with the run marker: --force may replace it later
    comp = compare(
        names,
        policy,
        zeta,
        ALPHA_TARGET_RAD,
        DURATION_S,
        SPIN_S,
        FIXED_STATE,
        study.seed,
        typer.echo,
        disturbances=disturbance_spec,
        aircraft=aircraft_name,
    )
    write_comparison(out_dir / "compare", comp, command_line())
    for r in comp.rows:
        if r["scenario"] == "spin":
            t_rec = r["recovery_time_s"]
            typer.echo(
                f"[quickstart]     {r['controller']}: {r['outcome']}, recovery time "
                f"{fmt_num(t_rec, unit='s', missing='- (not recovered)')}"
            )
    typer.echo(f"[quickstart] 2/3 Monte Carlo: {study.runs} runs x 60 s from the paper's reset bounds")
    prepare_out_dir(out_dir / "mc")  # with the run marker: --force may replace it later
    result = monte_carlo(
        names,
        policy,
        study.runs,
        ALPHA_TARGET_RAD,
        DURATION_S,
        study.seed,
        False,
        CHUNK,
        zeta=zeta,
        command=command_line(),
        progress=typer.echo,
        disturbances=disturbance_spec,
        aircraft=aircraft_name,
    )
    write_monte_carlo(out_dir / "mc", result)
    typer.echo("[quickstart] 3/3 report")
    paths = build_report(out_dir, out_dir)
    report = ": " + ", ".join(str(p) for p in paths)
    typer.echo(f"[quickstart] done in {time.perf_counter() - t0:.0f} s; results in {out_dir}" + report)
    for name, c in result.summary["controllers"].items():
        a = c["terminal_error_deg"]["alpha"]
        typer.echo(
            f"[quickstart] {name}: recovery rate {c['recovery_rate']:.3f}, terminal alpha error "
            f"{a['mean']:.3f} deg ({100 * a['within_0p5']:.1f}% within 0.5 deg), control TV "
            f"{c['control_tv']['mean']:.2f} rad"
        )


def register(app: typer.Typer) -> None:
    """Add the command(s) of this module to ``app``."""
    app.command()(quickstart)
