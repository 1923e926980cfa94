"""`harv-jax simulate`: open-loop trajectory from an initial state with fixed controls."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import typer

from harv_jax import atomic
from harv_jax.aircraft.registry import DEFAULT_AIRCRAFT, get_aircraft
from harv_jax.cli_options import aircraft_option, force_option, real_number
from harv_jax.dynamics import CONTROL_NAMES, WIND_STATE_NAMES, rollout
from harv_jax.errors import UsageError
from harv_jax.guards import check_simulate
from harv_jax.outdir import prepare_out_dir
from harv_jax.state_file import validate_state
from harv_jax.task.spec import DT_S, H0_FT

#: Default initial state (straight and level near trim at 600 ft/s, 25,000 ft).
DEFAULT_STATE = {
    "V": 600.0,
    "alpha": 0.089,
    "beta": 0.0,
    "p": 0.0,
    "q": 0.0,
    "r": 0.0,
    "mu": 0.0,
    "gamma": 0.0,
    "chi": 0.0,
    "h": H0_FT,
}
DEFAULT_CONTROLS = {"de": -0.0045, "da": 0.0, "dr": 0.0}


def parse_assignments(text: str, allowed: dict[str, float], what: str) -> dict[str, float]:
    """Parse ``"name=value,name=value"`` over ``allowed`` defaults; one-line UsageError if bad."""
    out = dict(allowed)
    if not text:
        return out
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        if "=" not in item:
            raise UsageError(f"{what} item {item!r} is not NAME=VALUE")
        name, value = (s.strip() for s in item.split("=", 1))
        if name not in allowed:
            raise UsageError(f"unknown {what} name {name!r}; allowed: {', '.join(allowed)}")
        try:
            v = float(value)
        except ValueError:
            raise UsageError(f"{what} {name}={value!r} is not a number") from None
        if not math.isfinite(v):
            raise UsageError(f"{what} {name}={value} is not finite")
        out[name] = v
    return out


def validate_controls(controls: dict[str, float], aircraft: str | None = None) -> None:
    """Raise UsageError if a deflection is outside the position limit (``u_min_rad``/``u_max_rad``) of
    ``aircraft``, a name of ``harv_jax.aircraft.registry`` (None: the default); compared in the limits'
    dtype, the one the simulation flies."""
    params = get_aircraft(aircraft or DEFAULT_AIRCRAFT)
    lo, hi = np.asarray(params.u_min_rad), np.asarray(params.u_max_rad)
    for i, name in enumerate(("de", "da", "dr")):
        v = np.asarray(controls[name], lo.dtype)
        if not lo[i] <= v <= hi[i]:
            raise UsageError(f"control {name}={controls[name]} rad is outside [{lo[i]:.6g}, {hi[i]:.6g}]")


def run_simulate(
    state: dict[str, float],
    controls: dict[str, float],
    duration_s: float,
    dt_s: float,
    throttle: float,
    aircraft: str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate; returns (t [T+1], columns [T+1, 13]) with columns t-less CSV order. ``aircraft``: a name
    of ``harv_jax.aircraft.registry`` (None: the default)."""
    import jax
    import jax.numpy as jnp

    n_steps = int(round(duration_s / dt_s))
    params = get_aircraft(aircraft or DEFAULT_AIRCRAFT, throttle=throttle)
    x0 = jnp.array([state[n] for n in WIND_STATE_NAMES], dtype=jnp.float32)
    u = jnp.array([controls["de"], controls["da"], controls["dr"]], dtype=jnp.float32)
    xs = jax.jit(rollout, static_argnames=())(x0, jnp.broadcast_to(u, (n_steps, 3)), params, dt_s)
    xs = np.asarray(xs)
    t = np.arange(n_steps + 1) * dt_s
    cols = np.concatenate([xs, np.broadcast_to(np.asarray(u), (n_steps + 1, 3))], axis=1)
    return t, cols


@aircraft_option
def simulate(
    state: str = typer.Option(
        "",
        help="Initial state overrides, e.g. 'V=500,alpha=0.3,h=20000' "
        "(ft/s, rad, rad/s, ft). Defaults: near trim at 600 ft/s, 25,000 ft.",
    ),
    controls: str = typer.Option("", help="Fixed deflections, e.g. 'de=-0.3,da=0.1,dr=0.2' (rad)."),
    duration: float = typer.Option(30.0, parser=real_number, help="Duration, s (> 0)."),
    dt: float = typer.Option(DT_S, parser=real_number, help="RK4 step, s (0 < dt <= 0.05)."),
    throttle: float = typer.Option(0.2, parser=real_number, help="Fixed throttle in [0, 1]."),
    out: Path = typer.Option(Path("runs/simulate"), help="Output directory."),
    force: bool = force_option(),
    aircraft_name: str | None = None,
) -> None:
    """Open-loop simulation with fixed controls: writes trajectory.csv and trajectory.png."""
    s = parse_assignments(state, DEFAULT_STATE, "state")
    c = parse_assignments(controls, DEFAULT_CONTROLS, "control")
    validate_state(s)
    validate_controls(c, aircraft_name)
    if not (math.isfinite(duration) and duration > 0):
        raise UsageError(f"--duration {duration} must be a positive number of seconds")
    if not (math.isfinite(dt) and 0 < dt <= 0.05):
        raise UsageError(f"--dt {dt} must be in (0, 0.05] s")
    if not 0.0 <= throttle <= 1.0:
        raise UsageError(f"--throttle {throttle} is outside [0, 1]")
    check_simulate(duration, dt)
    out_dir = prepare_out_dir(out, force)
    t, cols = run_simulate(s, c, duration, dt, throttle, aircraft_name)
    names = ("t",) + WIND_STATE_NAMES + CONTROL_NAMES
    atomic.savetxt(
        out_dir / "trajectory.csv",
        np.column_stack([t, cols]),
        delimiter=",",
        header=",".join(names),
        comments="",
        fmt="%.8g",
    )
    columns = {n: cols[:, i] for i, n in enumerate(WIND_STATE_NAMES + CONTROL_NAMES)}
    # matplotlib: imported here, not by every command (tools/results/house/cli_startup.json)
    from harv_jax.plots.time_histories import plot_time_histories

    plot_time_histories(
        t, {"open loop": columns}, out_dir / "trajectory.png", title="harv-jax simulate (open loop)"
    )
    finite = bool(np.all(np.isfinite(cols)))
    typer.echo(
        f"wrote {out_dir / 'trajectory.csv'} and trajectory.png "
        f"({len(t)} rows{'' if finite else ', NON-FINITE values'})"
    )


def register(app: typer.Typer) -> None:
    """Add the command(s) of this module to ``app``."""
    app.command()(simulate)
