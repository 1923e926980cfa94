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
    disturbance_options,
    force_option,
    policy_option,
    whole_number,
    zeta_option,
)

#: The controllers of the quickstart (names in harv_jax.control.registry).
QUICKSTART_CONTROLLERS = ("smc", "smc-brake", "smc-brake-zoom", "rl", "hybrid")
DURATION_S = 60.0
SPIN_S = 30.0
CHUNK: int | None = None  # runs per compiled call: guards.auto_chunk


def register(app: typer.Typer) -> None:
    @app.command()
    @aircraft_option
    @disturbance_options
    def quickstart(
        out: Path = typer.Option(Path("runs/quickstart"), help="Output directory."),
        runs: int = typer.Option(1000, parser=whole_number, help="Monte Carlo runs."),
        seed: int = typer.Option(0, parser=whole_number, help="Seed of the Monte Carlo."),
        policy: str = policy_option(),
        zeta: str = zeta_option(),
        force: bool = force_option(),
        disturbance_spec: Any = None,
        aircraft_name: str | None = None,
    ) -> None:
        """Spin comparison and a Monte Carlo of SMC, braking SMC, RL and hybrid with the shipped policy, plus
        a report."""
        from harv_jax.cli_options import (
            check_mc_options,
            command_line,
            controller_options,
            warn_loop_mismatch,
        )
        from harv_jax.control.registry import build_controller
        from harv_jax.guards import check_closed_loop_batch, check_seed
        from harv_jax.numfmt import fmt_num
        from harv_jax.outdir import prepare_out_dir, read_paths
        from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S

        names = list(QUICKSTART_CONTROLLERS)
        options = controller_options(names, policy, zeta)  # refuses an option none of them reads
        zeta = options.zeta
        check_mc_options(runs, ALPHA_TARGET_RAD, DURATION_S, CHUNK)
        check_seed(seed)
        check_closed_loop_batch(runs, round(DURATION_S / DT_S), 10, CHUNK, len(names))
        # the heavy imports (jax) only after the arguments are checked: bad input fails fast
        from harv_jax.evaluation.comparison import FIXED_STATE, compare, write_comparison
        from harv_jax.evaluation.montecarlo.study import monte_carlo, write_monte_carlo
        from harv_jax.report import build_report

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
            seed,
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
        typer.echo(f"[quickstart] 2/3 Monte Carlo: {runs} runs x 60 s from the paper's reset bounds")
        prepare_out_dir(out_dir / "mc")  # with the run marker: --force may replace it later
        study = monte_carlo(
            names,
            policy,
            runs,
            ALPHA_TARGET_RAD,
            DURATION_S,
            seed,
            False,
            CHUNK,
            zeta=zeta,
            command=command_line(),
            progress=typer.echo,
            disturbances=disturbance_spec,
            aircraft=aircraft_name,
        )
        write_monte_carlo(out_dir / "mc", study)
        typer.echo("[quickstart] 3/3 report")
        paths = build_report(out_dir, out_dir)
        report = ": " + ", ".join(str(p) for p in paths)
        typer.echo(f"[quickstart] done in {time.perf_counter() - t0:.0f} s; results in {out_dir}" + report)
        for name, c in study.summary["controllers"].items():
            a = c["terminal_error_deg"]["alpha"]
            typer.echo(
                f"[quickstart] {name}: recovery rate {c['recovery_rate']:.3f}, terminal alpha error "
                f"{a['mean']:.3f} deg ({100 * a['within_0p5']:.1f}% within 0.5 deg), control TV "
                f"{c['control_tv']['mean']:.2f} rad"
            )
