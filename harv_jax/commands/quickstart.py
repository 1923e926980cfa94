"""`harv-jax quickstart`: the main job on shipped defaults.

Until a trained policy ships, it flies the sliding-mode controller: the paper's spin scenario
(30 s developed spin, then recovery) and a Monte Carlo from the paper's reset bounds, with figures.
"""

from __future__ import annotations

import time
from pathlib import Path

import typer


def register(app: typer.Typer) -> None:
    @app.command()
    def quickstart(
        out: Path = typer.Option(Path("runs/quickstart"), help="Output directory."),
        runs: int = typer.Option(1000, help="Monte Carlo runs."),
        seed: int = typer.Option(0, help="Seed of the Monte Carlo."),
        force: bool = typer.Option(False, help="Replace an existing non-empty output directory."),
    ) -> None:
        """Spin-recovery flight and a Monte Carlo of the SMC, with figures (a few minutes on 2 CPU cores)."""
        from harv_jax.commands.fly import DT_S, run_fly, write_outputs
        from harv_jax.commands.mc import run_monte_carlo, validate
        from harv_jax.outdir import prepare_out_dir

        validate(runs, 0.349, 60.0, 250)
        out_dir = prepare_out_dir(out, force)
        t0 = time.perf_counter()
        typer.echo(
            "[quickstart] 1/2 spin scenario: 30 s developed spin, then the SMC recovers (alpha_d 20 deg)"
        )
        res = run_fly("spin", 0.349, 60.0, seed, "sat", 30.0)
        meta = {"controller": "smc", "switching": "sat", "scenario": "spin", "seed": seed, "duration_s": 60.0,
                "dt_s": DT_S, "reference_rad": [0.349, 0.0, 0.0], "spin_s": 30.0}  # fmt: skip
        (out_dir / "spin").mkdir()
        write_outputs(out_dir / "spin", res, meta)
        m = res["metrics"]
        typer.echo(f"[quickstart]     outcome {m['outcome_name']}, recovery time {m['t_recover_s']} s")
        typer.echo(f"[quickstart] 2/2 Monte Carlo: {runs} runs x 60 s from the paper's reset bounds")
        (out_dir / "mc").mkdir()
        s = run_monte_carlo(["smc"], None, runs, 0.349, 60.0, seed, False, out_dir / "mc")
        c = s["controllers"]["smc"]
        a = c["terminal_error_deg"]["alpha"]
        typer.echo(
            f"[quickstart] done in {time.perf_counter() - t0:.0f} s: spin/trajectory.png, mc/bands_smc.png, "
            f"mc/terminal_errors.png, mc/summary.json in {out_dir}\n"
            f"[quickstart] SMC: recovery rate {c['recovery_rate']:.3f}, terminal alpha error mean "
            f"{a['mean']:.3f} deg, {100 * a['within_0p5']:.1f}% within 0.5 deg"
        )
