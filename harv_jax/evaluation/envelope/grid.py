"""Recovery envelope map: the closed-loop outcome over a 2-D grid of initial conditions.

Two initial-state components (e.g. alpha0 x r0, or V0 x alpha0) span an ``n_y x n_x`` grid; every other
component is held at a fixed value (``DEFAULT_FIXED_STATE`` unless overridden). Every grid point is one
closed-loop run of the same nominal aircraft; all runs of a controller go through ``run_mc`` (one jitted,
vmapped, chunked and device-sharded rollout), so a map point is exactly a ``closed_loop`` run scored by
``score`` from that state, and the map's recovery flag and time are the Monte Carlo's.

Default fixed components (wind state, ft/s, rad, rad/s, ft):

| name  | value  | why                                                   |
|-------|--------|-------------------------------------------------------|
| V     | 800    | centre of the paper's reset bounds [100, 1500] ft/s    |
| alpha | 0.436  | centre of the reset bounds [-0.175, 1.047] rad         |
| beta  | 0      | centre of the reset bounds                            |
| p,q,r | 0      | centre of the reset bounds                            |
| mu    | 0      | as the paper's Monte Carlo (mu0 = gamma0 = 0)          |
| gamma | 0      | as the paper's Monte Carlo                            |
| chi   | 0      | irrelevant to the dynamics                            |
| h     | 25,000 | ``task.spec.H0_FT``                                   |

Grid layout: maps are ``[n_y, n_x]`` (row = y value, column = x value, as ``imshow``/``pcolormesh``); the
runs are the grid points in row-major order, run ``k`` = point ``(k // n_x, k % n_x)``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.dynamics.state import WIND_INDEX, WIND_STATE_NAMES
from harv_jax.evaluation.montecarlo.rollout import MCInputs, MCRunOutput, run_mc
from harv_jax.task.spec import DT_S, H0_FT, RESET_BOUNDS, V_MAX_FPS
from harv_jax.units import DEG_PER_RAD


class GridAxis(NamedTuple):
    """A state component that can span a grid axis.

    Attributes:
        state: wind-state component name (``WIND_STATE_NAMES``).
        default_range: (low, high) in state units (ft/s, rad, rad/s, ft).
        display_scale: factor from state units to display units.
        display_unit: unit shown on figures.
    """

    state: str
    default_range: tuple[float, float]
    display_scale: float
    display_unit: str


#: Grid axes by CLI name; default ranges are the paper's reset bounds (h0: 10,000-40,000 ft).
GRID_AXES: dict[str, GridAxis] = {
    "V0": GridAxis("V", RESET_BOUNDS["V"], 1.0, "ft/s"),
    "alpha0": GridAxis("alpha", RESET_BOUNDS["alpha"], DEG_PER_RAD, "deg"),
    "beta0": GridAxis("beta", RESET_BOUNDS["beta"], DEG_PER_RAD, "deg"),
    "p0": GridAxis("p", RESET_BOUNDS["p"], DEG_PER_RAD, "deg/s"),
    "q0": GridAxis("q", RESET_BOUNDS["q"], DEG_PER_RAD, "deg/s"),
    "r0": GridAxis("r", RESET_BOUNDS["r"], DEG_PER_RAD, "deg/s"),
    "mu0": GridAxis("mu", RESET_BOUNDS["mu"], DEG_PER_RAD, "deg"),
    "gamma0": GridAxis("gamma", RESET_BOUNDS["gamma"], DEG_PER_RAD, "deg"),
    "h0": GridAxis("h", (10_000.0, 40_000.0), 1.0, "ft"),
}

#: Initial-state components off the grid (see the module docstring), wind-state units.
DEFAULT_FIXED_STATE: dict[str, float] = {
    "V": 800.0,
    "alpha": 0.436,
    "beta": 0.0,
    "p": 0.0,
    "q": 0.0,
    "r": 0.0,
    "mu": 0.0,
    "gamma": 0.0,
    "chi": 0.0,
    "h": H0_FT,
}


@dataclasses.dataclass(frozen=True)
class EnvelopeGrid:
    """A 2-D grid of initial states (host-side description; static).

    Attributes:
        x_name: grid-axis name of the columns (a ``GRID_AXES`` key, e.g. ``"alpha0"``).
        y_name: grid-axis name of the rows (e.g. ``"r0"``).
        x_range: (low, high) of x, state units; n_x points including both ends.
        y_range: (low, high) of y, state units.
        n_x: points along x.
        n_y: points along y.
        fixed: value of every wind-state component (``WIND_STATE_NAMES``) off the grid.
    """

    x_name: str
    y_name: str
    x_range: tuple[float, float]
    y_range: tuple[float, float]
    n_x: int
    n_y: int
    fixed: Mapping[str, float]

    @property
    def x_values(self) -> np.ndarray:
        """[n_x] x values, state units."""
        return np.linspace(self.x_range[0], self.x_range[1], self.n_x)

    @property
    def y_values(self) -> np.ndarray:
        """[n_y] y values, state units."""
        return np.linspace(self.y_range[0], self.y_range[1], self.n_y)

    @property
    def n_runs(self) -> int:
        return self.n_x * self.n_y


def make_grid(
    x_name: str,
    y_name: str,
    n_x: int,
    n_y: int,
    x_range: tuple[float, float] | None = None,
    y_range: tuple[float, float] | None = None,
    fixed: Mapping[str, float] | None = None,
) -> EnvelopeGrid:
    """An ``EnvelopeGrid`` with default ranges (``GRID_AXES``) and fixed states (``DEFAULT_FIXED_STATE``).

    Args:
        x_name, y_name: ``GRID_AXES`` keys (distinct).
        n_x, n_y: points per axis (>= 2).
        x_range, y_range: (low, high), state units (default: the axis's default range).
        fixed: overrides of ``DEFAULT_FIXED_STATE``, keyed by wind-state name (``"V"``, ``"h"``, ...).

    Raises:
        ValueError: unknown or repeated axis, fewer than 2 points, an empty or non-finite range.
    """
    for name in (x_name, y_name):
        if name not in GRID_AXES:
            raise ValueError(f"grid axis {name!r} is unknown; allowed: {', '.join(GRID_AXES)}")
    if x_name == y_name:
        raise ValueError(f"grid axes must differ (got {x_name!r} twice)")
    if min(n_x, n_y) < 2:
        raise ValueError(f"a grid needs >= 2 points per axis (got {n_x} x {n_y})")
    ranges = []
    for name, rng in ((x_name, x_range), (y_name, y_range)):
        lo, hi = GRID_AXES[name].default_range if rng is None else rng
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise ValueError(f"range of {name} must be finite with low < high (got {lo}, {hi})")
        ranges.append((float(lo), float(hi)))
    values = dict(DEFAULT_FIXED_STATE)
    for k, v in (fixed or {}).items():
        if k not in values:
            raise ValueError(f"fixed state {k!r} is unknown; allowed: {', '.join(WIND_STATE_NAMES)}")
        values[k] = float(v)
        if not np.isfinite(values[k]):
            raise ValueError(f"fixed state {k}={v} is not finite")
    grid = EnvelopeGrid(x_name, y_name, ranges[0], ranges[1], int(n_x), int(n_y), values)
    _check_physical(grid)
    return grid


#: Where an initial wind state is meaningful (state name -> open/closed bounds checked by _check_physical).
_V_MAX_FPS = V_MAX_FPS
_BETA_MAX_RAD = 1.5  # the wind->body change is singular at |beta| = pi/2


def _check_physical(grid: EnvelopeGrid) -> None:
    """ValueError if any grid state has V <= 0 or > 2000 ft/s, |beta| >= 1.5 rad or h <= 0 ft."""
    x0 = grid_states(grid)
    checks = (
        ("V", lambda v: (v > 0.0) & (v <= _V_MAX_FPS), f"in (0, {_V_MAX_FPS:g}] ft/s"),
        ("beta", lambda b: np.abs(b) < _BETA_MAX_RAD, f"within +-{_BETA_MAX_RAD} rad"),
        ("h", lambda h: h > 0.0, "above 0 ft"),
    )
    for name, ok, what in checks:
        v = x0[..., WIND_INDEX[name]]
        if not np.all(ok(v)):
            raise ValueError(f"initial {name} must be {what} (got {v.min():g} .. {v.max():g})")


def grid_states(grid: EnvelopeGrid) -> np.ndarray:
    """Initial wind states of every grid point, [n_y, n_x, 10] (state units, float64)."""
    base = np.array([grid.fixed[n] for n in WIND_STATE_NAMES], dtype=np.float64)
    x0 = np.broadcast_to(base, (grid.n_y, grid.n_x, len(WIND_STATE_NAMES))).copy()
    x0[:, :, WIND_INDEX[GRID_AXES[grid.x_name].state]] = grid.x_values[None, :]
    x0[:, :, WIND_INDEX[GRID_AXES[grid.y_name].state]] = grid.y_values[:, None]
    return x0


def envelope_inputs(key: jax.Array, grid: EnvelopeGrid, nominal: AircraftParams) -> MCInputs:
    """``MCInputs`` of the grid: the grid states in row-major order, the nominal aircraft for every run,
    and per-run controller keys ``split(key, n_runs)``."""
    x0 = jnp.asarray(grid_states(grid).reshape(grid.n_runs, -1), dtype=jnp.result_type(nominal.mass_slug))
    params = jax.tree.map(lambda a: jnp.broadcast_to(a, (grid.n_runs,) + jnp.shape(a)), nominal)
    return MCInputs(x0_wind=x0, params=params, keys=jax.random.split(key, grid.n_runs))


class EnvelopeMap(NamedTuple):
    """Per-grid-point results of one controller, each [n_y, n_x] (terminal error [n_y, n_x, 3]).

    Attributes:
        outcome: ``Outcome`` code.
        recovered: the recovery criterion held over the final hold window.
        t_recover_s: time from which the full criterion holds, s (NaN if not recovered).
        t_recover_alpha_s: time from which |e_alpha| and ||omega|| stay within tolerance, s (NaN: never).
        altitude_loss_ft: h(0) - min h, ft.
        terminal_error_rad: mean alpha, beta, mu errors over the last second, rad.
    """

    outcome: np.ndarray
    recovered: np.ndarray
    t_recover_s: np.ndarray
    t_recover_alpha_s: np.ndarray
    altitude_loss_ft: np.ndarray
    terminal_error_rad: np.ndarray


def to_map(out: MCRunOutput, grid: EnvelopeGrid) -> EnvelopeMap:
    """Reshape per-run Monte Carlo results (row-major grid order) into [n_y, n_x] maps."""
    shape = (grid.n_y, grid.n_x)
    m = out.metrics
    return EnvelopeMap(
        outcome=np.asarray(m.outcome).reshape(shape),
        recovered=np.asarray(m.recovered).reshape(shape),
        t_recover_s=np.asarray(m.t_recover_s).reshape(shape),
        t_recover_alpha_s=np.asarray(m.t_recover_alpha_s).reshape(shape),
        altitude_loss_ft=np.asarray(m.altitude_loss_ft).reshape(shape),
        terminal_error_rad=np.asarray(out.terminal_error_rad).reshape(shape + (3,)),
    )


def run_envelope(
    controller: Controller,
    inputs: MCInputs,
    grid: EnvelopeGrid,
    reference_rad: jnp.ndarray,
    n_steps: int,
    dt_s: float = DT_S,
    chunk_size: int | None = None,
) -> tuple[EnvelopeMap, MCRunOutput, dict[str, float]]:
    """Fly ``controller`` from every grid point (one ``run_mc`` call; no trajectory history kept).

    Args:
        controller: Controller(init, apply).
        inputs: ``envelope_inputs(key, grid, nominal)``.
        grid: the grid ``inputs`` were built from.
        reference_rad: [3] [alpha_d, beta_d, mu_d], rad.
        n_steps: plant steps per run (static).
        dt_s: plant step, s.
        chunk_size: runs per compiled call (bounds memory; ``None``: ``guards.auto_chunk``).

    Returns:
        (EnvelopeMap, per-run MCRunOutput, {"compile": s, "run": s, "chunk_runs": runs per call}).
    """
    if int(inputs.x0_wind.shape[0]) != grid.n_runs:
        raise ValueError(f"inputs hold {inputs.x0_wind.shape[0]} runs, the grid {grid.n_runs}")
    # record_every = n_steps: the decimated history is a single sample per run (memory stays tiny)
    out, wall = run_mc(controller, inputs, reference_rad, n_steps, dt_s, n_steps, chunk_size)
    return to_map(out, grid), out, wall


def grid_description(grid: EnvelopeGrid) -> dict[str, Any]:
    """JSON-ready description of the grid axes and the fixed states."""

    def axis(name: str, values: np.ndarray) -> dict[str, Any]:
        ax = GRID_AXES[name]
        return {
            "name": name,
            "state": ax.state,
            "low": float(values[0]),
            "high": float(values[-1]),
            "n": int(values.size),
            "values": [float(v) for v in values],
            "display_unit": ax.display_unit,
            "display_scale": ax.display_scale,
        }

    on_grid = {GRID_AXES[grid.x_name].state, GRID_AXES[grid.y_name].state}
    return {
        "x": axis(grid.x_name, grid.x_values),
        "y": axis(grid.y_name, grid.y_values),
        "layout": "maps are [n_y, n_x]; run k is grid point (k // n_x, k % n_x)",
        "fixed_state": {n: float(grid.fixed[n]) for n in WIND_STATE_NAMES if n not in on_grid},
        "state_units": "ft/s, rad, rad/s, ft",
    }
