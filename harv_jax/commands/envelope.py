"""`harv-jax envelope`: recovery envelope map of one or more controllers over a 2-D initial-state grid.

Outputs in DIR: ``envelope_recovery.png`` (outcome maps side by side), ``envelope_time.png`` (recovery
time maps), ``envelope.json`` (grid axes, fixed states, per-controller recovery fraction, outcome
counts, recovery-time statistics, wall times), ``envelope_grid.csv`` (one row per controller and grid
point) and ``envelope_grid.npz`` (the maps as arrays: ``x_values``, ``y_values``, ``x0_wind`` and
``<controller>/<field>`` [n_y, n_x]). See ``harv_jax.evaluation.envelope_map`` for the grid layout and
the default fixed states.
"""

from __future__ import annotations

import csv
import math
import shlex
import sys
from pathlib import Path

import numpy as np
import typer

from harv_jax.commands.options import policy_option, zeta_option
from harv_jax.errors import UsageError
from harv_jax.numfmt import write_json
from harv_jax.policies import DEFAULT_POLICY_SPEC

MAX_POINTS_PER_AXIS = 1000
DT_S = 0.01


def _float(text: str, what: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise UsageError(f"{what}: {text!r} is not a number") from None
    if not math.isfinite(v):
        raise UsageError(f"{what}: {text!r} is not finite")
    return v


def parse_grid(text: str) -> tuple[tuple[str, tuple[float, float] | None], ...]:
    """``"X:Y"`` with optional ranges ``"alpha0=-0.2,1.0:r0"`` -> ((X, range|None), (Y, range|None)).

    Ranges are in state units (ft/s, rad, rad/s, ft). UsageError on a malformed text or unknown axis.
    """
    from harv_jax.evaluation.envelope_map import GRID_AXES

    parts = text.split(":")
    if len(parts) != 2:
        raise UsageError(f"--grid {text!r} must name two axes as X:Y (e.g. alpha0:r0, V0:alpha0)")
    axes = []
    for part in parts:
        name, _, rng = part.strip().partition("=")
        name = name.strip()
        if name not in GRID_AXES:
            raise UsageError(f"--grid axis {name!r} is unknown; allowed: {', '.join(GRID_AXES)}")
        if not rng:
            axes.append((name, None))
            continue
        bounds = rng.split(",")
        if len(bounds) != 2:
            raise UsageError(f"--grid range {part!r} must be NAME=LOW,HIGH (state units)")
        lo, hi = (_float(b, f"--grid range of {name}") for b in bounds)
        if not lo < hi:
            raise UsageError(f"--grid range of {name} must have LOW < HIGH (got {lo:g}, {hi:g})")
        axes.append((name, (lo, hi)))
    if axes[0][0] == axes[1][0]:
        raise UsageError(f"--grid {text!r} names {axes[0][0]} twice")
    return tuple(axes)


def parse_fixed(text: str) -> dict[str, float]:
    """``"V0=300,h0=20000"`` -> {"V": 300.0, "h": 20000.0} (state units); UsageError on bad input."""
    from harv_jax.dynamics.state import WIND_STATE_NAMES

    out: dict[str, float] = {}
    for item in (t.strip() for t in text.split(",")):
        if not item:
            continue
        name, eq, val = item.partition("=")
        name = name.strip()
        state = name[:-1] if name.endswith("0") else name
        if not eq or state not in WIND_STATE_NAMES:
            raise UsageError(
                f"--fixed {item!r} must be NAME=VALUE with NAME one of "
                f"{', '.join(n + '0' for n in WIND_STATE_NAMES)}"
            )
        out[state] = _float(val, f"--fixed {name}")
    return out


def build_grid(grid: str, n: int, fixed: str):
    """EnvelopeGrid from the CLI flags; UsageError (one line) for any bad value."""
    from harv_jax.evaluation.envelope_map import GRID_AXES, make_grid

    if not 2 <= n <= MAX_POINTS_PER_AXIS:
        raise UsageError(f"--n {n} must be in [2, {MAX_POINTS_PER_AXIS}] (points per grid axis)")
    (x_name, x_rng), (y_name, y_rng) = parse_grid(grid)
    fixed_values = parse_fixed(fixed)
    for name in (x_name, y_name):
        if GRID_AXES[name].state in fixed_values:
            raise UsageError(f"--fixed sets {name}, which is a grid axis")
    try:
        return make_grid(x_name, y_name, n, n, x_rng, y_rng, fixed_values)
    except ValueError as e:
        raise UsageError(str(e)) from None


def write_grid_csv(path: Path, grid, maps: dict) -> None:
    """One row per (controller, grid point): indices, the two grid values, outcome and metrics."""
    from harv_jax.evaluation.metrics import OUTCOME_NAMES

    xs, ys = grid.x_values, grid.y_values
    header = ["controller", "ix", "iy", grid.x_name, grid.y_name, "outcome", "recovered", "t_recover_s",
              "t_recover_alpha_s", "altitude_loss_ft", "terminal_alpha_err_deg", "terminal_beta_err_deg",
              "terminal_mu_err_deg"]  # fmt: skip
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for name, m in maps.items():
            term = np.degrees(m.terminal_error_rad)
            for iy in range(grid.n_y):
                for ix in range(grid.n_x):
                    w.writerow(
                        [
                            name,
                            ix,
                            iy,
                            f"{xs[ix]:.6g}",
                            f"{ys[iy]:.6g}",
                            OUTCOME_NAMES[int(m.outcome[iy, ix])],
                            bool(m.recovered[iy, ix]),
                            f"{m.t_recover_s[iy, ix]:.4g}",
                            f"{m.t_recover_alpha_s[iy, ix]:.4g}",
                            f"{m.altitude_loss_ft[iy, ix]:.5g}",
                            *[f"{v:.5g}" for v in term[iy, ix]],
                        ]  # fmt: skip
                    )


def run_envelope_map(
    controllers: list[str],
    policy: str | None,
    grid,
    target_alpha: float,
    duration: float,
    seed: int,
    out_dir: Path,
    chunk: int = 250,
    progress: bool = True,
    zeta: str = "continuous",
) -> dict:
    """Fly every controller from every grid point; write the maps, envelope.json, CSV and NPZ."""
    import jax
    import jax.numpy as jnp

    from harv_jax.aircraft import harv
    from harv_jax.commands.mc import build_controller
    from harv_jax.evaluation.envelope_map import (
        GRID_AXES,
        envelope_inputs,
        grid_description,
        grid_states,
        run_envelope,
        summarize_envelope,
    )
    from harv_jax.evaluation.metrics import OUTCOME_NAMES
    from harv_jax.plotting_maps import plot_outcome_maps, plot_time_maps

    ctrls = {name: build_controller(name, policy, zeta) for name in controllers}
    n_steps = int(round(duration / DT_S))
    reference = jnp.array([target_alpha, 0.0, 0.0])
    inputs = envelope_inputs(jax.random.key(seed), grid, harv())
    doc: dict = {
        "grid": grid_description(grid), "runs_per_controller": grid.n_runs, "target_alpha_rad": target_alpha,
        "reference_rad": [target_alpha, 0.0, 0.0], "duration_s": n_steps * DT_S, "dt_s": DT_S, "seed": seed,
        "aircraft": "nominal", "devices": [str(d) for d in jax.local_devices()],
        "policy": (policy or DEFAULT_POLICY_SPEC) if {"rl", "hybrid"} & set(controllers) else None,
        "zeta_schedule": zeta if "hybrid" in controllers else None,
        "command": "harv-jax " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
        "controllers": {},
    }  # fmt: skip
    maps = {}
    for name, ctrl in ctrls.items():
        if progress:
            typer.echo(
                f"[envelope] {name}: {grid.n_y} x {grid.n_x} = {grid.n_runs} runs x {n_steps} steps ..."
            )
        m, out, wall = run_envelope(ctrl, inputs, grid, reference, n_steps, DT_S, chunk)
        maps[name] = m
        doc["controllers"][name] = summarize_envelope(out, wall, n_steps)
        if progress:
            typer.echo(
                f"[envelope] {name}: recovered {100 * doc['controllers'][name]['recovery_fraction']:.1f}%, "
                f"compile {wall['compile']:.1f} s, run {wall['run']:.1f} s"
            )
    ax_x, ax_y = GRID_AXES[grid.x_name], GRID_AXES[grid.y_name]
    x_disp, y_disp = grid.x_values * ax_x.display_scale, grid.y_values * ax_y.display_scale
    x_label, y_label = f"{grid.x_name} [{ax_x.display_unit}]", f"{grid.y_name} [{ax_y.display_unit}]"
    fixed = ", ".join(f"{k}0={v:g}" for k, v in doc["grid"]["fixed_state"].items() if v != 0.0) + ", others 0"
    plot_outcome_maps(
        x_disp, y_disp, {n: m.outcome for n, m in maps.items()}, OUTCOME_NAMES, x_label, y_label,
        out_dir / "envelope_recovery.png",
        title=f"recovery outcome after {n_steps * DT_S:g} s, alpha_d = {np.degrees(target_alpha):.1f} deg"
        f"\n(fixed: {fixed})", duration_s=n_steps * DT_S,
    )  # fmt: skip
    plot_time_maps(
        x_disp, y_disp, {n: m.t_recover_s for n, m in maps.items()}, x_label, y_label,
        out_dir / "envelope_time.png",
        title=f"recovery time (grey: not recovered by {n_steps * DT_S:g} s), alpha_d = "
        f"{np.degrees(target_alpha):.1f} deg\n(fixed: {fixed})",
    )  # fmt: skip
    arrays = {"x_values": grid.x_values, "y_values": grid.y_values, "x0_wind": grid_states(grid)}
    for name, m in maps.items():
        arrays.update({f"{name}/{field}": np.asarray(v) for field, v in m._asdict().items()})
    np.savez_compressed(out_dir / "envelope_grid.npz", **arrays)
    write_grid_csv(out_dir / "envelope_grid.csv", grid, maps)
    write_json(out_dir / "envelope.json", doc)
    return doc


def register(app: typer.Typer) -> None:
    @app.command()
    def envelope(
        controller: str = typer.Option("smc", help="Controllers, comma-separated: smc, rl, hybrid."),
        policy: str = policy_option(),
        grid: str = typer.Option(
            "alpha0:r0",
            help="Grid axes X:Y from V0, alpha0, beta0, p0, q0, r0, mu0, gamma0, h0; optional ranges in "
            "state units (ft/s, rad, rad/s, ft), e.g. 'alpha0=-0.175,1.047:r0'. Default ranges: the "
            "paper's reset bounds.",
        ),
        n: int = typer.Option(100, help="Points per grid axis (n x n runs per controller)."),
        duration: float = typer.Option(60.0, help="Run length, s."),
        target_alpha: float = typer.Option(0.349, help="Target angle of attack, rad (beta_d = mu_d = 0)."),
        fixed: str = typer.Option(
            "",
            help="Off-grid initial states, e.g. 'V0=300,h0=20000' (default V0=800 ft/s, alpha0=0.436 rad, "
            "beta0=p0=q0=r0=mu0=gamma0=chi0=0, h0=25000 ft).",
        ),
        zeta: str = zeta_option(),
        seed: int = typer.Option(0, help="Seed of the controllers' keys (the grid itself is deterministic)."),
        chunk: int = typer.Option(250, help="Runs per compiled call (bounds memory)."),
        out: Path = typer.Option(Path("runs/envelope"), help="Output directory."),
        force: bool = typer.Option(False, help="Replace an existing non-empty output directory."),
    ) -> None:
        """Recovery envelope map: outcome and recovery time over an initial-state grid, per controller."""
        from harv_jax.commands.mc import build_controller, parse_controllers, validate
        from harv_jax.guards import check_closed_loop_batch, check_seed
        from harv_jax.outdir import prepare_out_dir

        names = parse_controllers(controller)
        g = build_grid(grid, n, fixed)
        validate(g.n_runs, target_alpha, duration, chunk)
        check_seed(seed)
        n_steps = round(duration / DT_S)
        check_closed_loop_batch(g.n_runs, n_steps, n_steps, chunk, len(names), runs_flag="--n x --n =")
        for name in names:
            build_controller(name, policy, zeta)  # fail fast, before creating the output directory
        out_dir = prepare_out_dir(out, force)
        run_envelope_map(names, policy, g, target_alpha, duration, seed, out_dir, chunk, zeta=zeta)
        typer.echo(
            f"wrote {out_dir}/envelope_recovery.png, envelope_time.png, envelope.json, envelope_grid.csv, "
            "envelope_grid.npz"
        )
