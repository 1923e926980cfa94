"""`harv-jax quickstart`: the main job on shipped defaults.

1. the spin comparison: RL-only vs SMC-only vs hybrid after a 30 s developed spin, and from a fixed upset
   (``harv-jax compare``), with the shipped policy;
2. a Monte Carlo of SMC, RL and hybrid from the paper's reset bounds (``harv-jax mc``);
3. the report of both (``harv-jax report``): report.md and report.html.
"""

from __future__ import annotations

import time
from pathlib import Path

import typer

from harv_jax.commands.options import policy_option, zeta_option


def register(app: typer.Typer) -> None:
    @app.command()
    def quickstart(
        out: Path = typer.Option(Path("runs/quickstart"), help="Output directory."),
        runs: int = typer.Option(1000, help="Monte Carlo runs."),
        seed: int = typer.Option(0, help="Seed of the Monte Carlo."),
        policy: str = policy_option(),
        zeta: str = zeta_option(),
        force: bool = typer.Option(False, help="Replace an existing non-empty output directory."),
    ) -> None:
        """Spin comparison and a Monte Carlo of SMC, RL and hybrid with the shipped policy, plus a report."""
        from harv_jax.commands.compare import run_compare
        from harv_jax.commands.mc import build_controller, run_monte_carlo, validate
        from harv_jax.guards import check_closed_loop_batch, check_seed
        from harv_jax.numfmt import fmt_num
        from harv_jax.outdir import prepare_out_dir

        validate(runs, 0.349, 60.0, 250)
        check_seed(seed)
        check_closed_loop_batch(runs, 6000, 10, 250, 3)
        names = ["smc", "rl", "hybrid"]
        for name in names:
            build_controller(name, policy, zeta)
        out_dir = prepare_out_dir(out, force)
        t0 = time.perf_counter()
        typer.echo("[quickstart] 1/3 spin comparison: 30 s developed spin, then RL, SMC and hybrid recover")
        prepare_out_dir(out_dir / "compare")  # with the run marker: --force may replace it later
        rows = run_compare(names, policy, zeta, 0.349, 60.0, 30.0, None, seed, out_dir / "compare")
        for r in rows:
            if r["scenario"] == "spin":
                t_rec = r["recovery_time_s"]
                typer.echo(
                    f"[quickstart]     {r['controller']}: {r['outcome']}, recovery time "
                    f"{fmt_num(t_rec, unit='s', missing='- (not recovered)')}"
                )
        typer.echo(f"[quickstart] 2/3 Monte Carlo: {runs} runs x 60 s from the paper's reset bounds")
        prepare_out_dir(out_dir / "mc")  # with the run marker: --force may replace it later
        s = run_monte_carlo(names, policy, runs, 0.349, 60.0, seed, False, out_dir / "mc", zeta=zeta)
        typer.echo("[quickstart] 3/3 report")
        report = _write_report(out_dir)
        typer.echo(f"[quickstart] done in {time.perf_counter() - t0:.0f} s; results in {out_dir}" + report)
        for name, c in s["controllers"].items():
            a = c["terminal_error_deg"]["alpha"]
            typer.echo(
                f"[quickstart] {name}: recovery rate {c['recovery_rate']:.3f}, terminal alpha error "
                f"{a['mean']:.3f} deg ({100 * a['within_0p5']:.1f}% within 0.5 deg), control TV "
                f"{c['control_tv']['mean']:.2f} rad"
            )


def _write_report(out_dir: Path) -> str:
    """Run ``harv-jax report`` on the quickstart folder; returns a note for the final message."""
    from harv_jax.commands.report import build_report

    paths = build_report(out_dir, out_dir)
    return ": " + ", ".join(str(p) for p in paths)
