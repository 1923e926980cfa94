"""Initial conditions: the paper's reset bounds (random upsets) and the developed-spin scenario.

Reset bounds: ``task.spec.RESET_BOUNDS`` (paper Table "Bounds for random initialization of state",
docs/model.md, "Envelope and reset bounds"), here also as arrays (``RESET_LOW``/``RESET_HIGH``) and a traced
pytree (``ResetBounds``); chi = 0 and h = ``task.spec.H0_FT`` (the paper starts its altitude record at
0 ft; here h is the true altitude and plots show h - h0).

Spin scenario (paper Sec. VI): the aircraft is held in a developed spin with pro-spin controls for
the first 30 s, then the controller takes over. Entry found by a grid search over entry states and
full-deflection control combinations (``experiments/smc_tuning/README.md``): from V = 300 ft/s,
alpha = 0.9 rad, p = r = -0.5 rad/s at 25,000 ft with full aft stick (de = -0.436 rad), full positive
aileron (da = +0.436) and full positive rudder (dr = +0.524) this model settles in a steep left spin:
alpha 60-85 deg, r about -1.5 rad/s, gamma about -83 deg, sink about 280 ft/s (about 6,500 ft lost
in 30 s). All entry values are inside the reset bounds.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics.plant import plant_step
from harv_jax.dynamics.state import (
    WIND_STATE_NAMES,
    BodyState,
    alpha_rad,
    from_wind,
    gamma_rad,
    h_ft,
    to_wind,
    yaw_rate_radps,
)
from harv_jax.task.spec import ALPHA_TARGET_BOUNDS_RAD, DT_S, H0_FT, RESET_BOUNDS, RESET_STATE_NAMES
from harv_jax.units import RAD_PER_DEG

#: Paper reset bounds as arrays [8] over ``RESET_STATE_NAMES`` (ft/s, rad, rad/s).
RESET_LOW = np.array([RESET_BOUNDS[n][0] for n in RESET_STATE_NAMES])
RESET_HIGH = np.array([RESET_BOUNDS[n][1] for n in RESET_STATE_NAMES])

#: Spin entry state (wind axes, ft/s, rad, rad/s, ft) -- see the module docstring.
SPIN_ENTRY: dict[str, float] = {
    "V": 300.0,
    "alpha": 0.9,
    "beta": 0.0,
    "p": -0.5,
    "q": 0.0,
    "r": -0.5,
    "mu": 0.0,
    "gamma": 0.0,
    "chi": 0.0,
    "h": H0_FT,
}
#: Pro-spin controls [de, da, dr], rad: full aft stick, full positive aileron and rudder (left spin).
SPIN_CONTROLS_RAD: tuple[float, float, float] = (-0.436, 0.436, 0.524)
#: Time held in the spin before the controller takes over, s (paper Sec. VI).
SPIN_DURATION_S = 30.0
#: Spin test thresholds over the last ``SPIN_WINDOW_S`` of the open-loop spin.
SPIN_WINDOW_S = 20.0
SPIN_MIN_ALPHA_RAD = 40.0 * RAD_PER_DEG
SPIN_MIN_YAW_RATE_RADPS = 0.5


@struct.dataclass
class ResetBounds:
    """Lower/upper reset bounds [8] over ``RESET_STATE_NAMES`` (traced: randomize or sweep them)."""

    low: jnp.ndarray
    high: jnp.ndarray


def reset_bounds(dtype=None) -> ResetBounds:
    """The paper's reset bounds as a pytree."""
    return ResetBounds(low=jnp.asarray(RESET_LOW, dtype=dtype), high=jnp.asarray(RESET_HIGH, dtype=dtype))


def sample_table_states(
    key: jax.Array,
    n: int,
    bounds: ResetBounds | None = None,
    h0_ft: float | jnp.ndarray = H0_FT,
    chi_rad: float | jnp.ndarray = 0.0,
) -> jnp.ndarray:
    """Initial wind states drawn uniformly from the reset bounds.

    Args:
        key: PRNG key.
        n: number of states (static).
        bounds: ResetBounds (default: the paper's Table).
        h0_ft: altitude, ft.
        chi_rad: flight-path azimuth, rad.

    Returns:
        [n, 10] wind states [V, alpha, beta, p, q, r, mu, gamma, chi, h].
    """
    bounds = reset_bounds() if bounds is None else bounds
    u = jax.random.uniform(key, (n, len(RESET_STATE_NAMES)), dtype=bounds.low.dtype)
    sampled = bounds.low[None] + u * (bounds.high - bounds.low)[None]
    fixed = jnp.broadcast_to(
        jnp.stack([jnp.asarray(chi_rad), jnp.asarray(h0_ft)]).astype(sampled.dtype), (n, 2)
    )
    return jnp.concatenate([sampled, fixed], axis=1)


def sample_alpha_targets(key: jax.Array, n: int) -> jnp.ndarray:
    """Target angles of attack [n], rad, uniform over the paper's alpha_d bounds."""
    lo, hi = ALPHA_TARGET_BOUNDS_RAD
    return jax.random.uniform(key, (n,), minval=lo, maxval=hi)


def spin_entry_state(h0_ft: float = H0_FT, dtype=None) -> jnp.ndarray:
    """Wind state [10] of the spin entry (``SPIN_ENTRY``) at altitude ``h0_ft``."""
    vals = {**SPIN_ENTRY, "h": h0_ft}
    return jnp.asarray([vals[n] for n in WIND_STATE_NAMES], dtype=dtype)


def spin_controls_rad(dtype=None) -> jnp.ndarray:
    """Pro-spin deflection command [3], rad."""
    return jnp.asarray(SPIN_CONTROLS_RAD, dtype=dtype)


def open_loop(
    params: AircraftParams,
    x0: BodyState | jnp.ndarray,
    cmd_rad: jnp.ndarray,
    n_steps: int,
    dt_s: float = DT_S,
    delta0_rad: jnp.ndarray | None = None,
) -> tuple[jnp.ndarray, jnp.ndarray, BodyState, jnp.ndarray]:
    """Open-loop flight with a fixed command through the actuator model (rate limits apply).

    Args:
        params: aircraft.
        x0: initial BodyState or wind state [10].
        cmd_rad: [3] fixed deflection command, rad.
        n_steps: number of steps (static).
        dt_s: step, s.
        delta0_rad: [3] initial deflections (default 0).

    Returns:
        (x_wind [n_steps + 1, 10], delta [n_steps, 3] applied over each step, final BodyState,
        final deflections [3]).
    """
    body0 = x0 if isinstance(x0, BodyState) else from_wind(x0)
    dtype = body0.uvw_fps.dtype
    delta0 = jnp.zeros((3,), dtype) if delta0_rad is None else jnp.asarray(delta0_rad, dtype)
    cmd = jnp.asarray(cmd_rad, dtype)

    def step(carry, _):
        state, delta, x = plant_step(*carry, cmd, params, dt_s)
        return (state, delta), (x, delta)

    (state, delta), (xs, deltas) = jax.lax.scan(step, (body0, delta0), None, length=n_steps)
    return jnp.concatenate([to_wind(body0)[None], xs], axis=0), deltas, state, delta


def open_loop_spin(
    params: AircraftParams,
    spin_s: float = SPIN_DURATION_S,
    dt_s: float = DT_S,
    h0_ft: float = H0_FT,
) -> tuple[jnp.ndarray, jnp.ndarray, BodyState, jnp.ndarray]:
    """The spin phase: from ``spin_entry_state`` with the pro-spin command for ``spin_s`` seconds.

    Returns:
        Same as ``open_loop``: (x_wind [T + 1, 10], delta [T, 3], final BodyState, final deflections [3]).
    """
    n = int(round(spin_s / dt_s))
    dtype = jnp.result_type(params.mass_slug)
    return open_loop(params, spin_entry_state(h0_ft, dtype), spin_controls_rad(dtype), n, dt_s)


def developed_spin_state(
    params: AircraftParams,
    spin_s: float = SPIN_DURATION_S,
    dt_s: float = DT_S,
    h0_ft: float = H0_FT,
) -> tuple[BodyState, jnp.ndarray]:
    """State and deflections after ``spin_s`` s of the open-loop spin (e.g. for spin resets).

    Returns:
        (BodyState, deflections [3] rad) at the end of the spin phase.
    """
    _, _, state, delta = open_loop_spin(params, spin_s, dt_s, h0_ft)
    return state, delta


class SpinCheck(struct.PyTreeNode):
    """Spin indicators over the last ``SPIN_WINDOW_S`` of an open-loop trajectory."""

    min_alpha_rad: jnp.ndarray
    min_abs_yaw_rate_radps: jnp.ndarray
    mean_yaw_rate_radps: jnp.ndarray
    altitude_loss_ft: jnp.ndarray
    mean_gamma_rad: jnp.ndarray
    spinning: jnp.ndarray


def spin_check(x_wind: jnp.ndarray, dt_s: float = DT_S, window_s: float = SPIN_WINDOW_S) -> SpinCheck:
    """Is ``x_wind`` [T, 10] a developed spin? alpha > 40 deg and |r| > 0.5 rad/s over the whole last
    ``window_s`` (static) with the same sign of r, and altitude lost over the run."""
    n_win = int(round(window_s / dt_s))
    w = x_wind[-n_win:]
    r = yaw_rate_radps(w)
    min_alpha = jnp.min(alpha_rad(w))
    min_abs_r = jnp.min(jnp.abs(r))
    same_sign = jnp.all(jnp.sign(r) == jnp.sign(r[0]))
    alt_loss = h_ft(x_wind[0]) - h_ft(x_wind[-1])
    spinning = (
        (min_alpha > SPIN_MIN_ALPHA_RAD) & (min_abs_r > SPIN_MIN_YAW_RATE_RADPS) & same_sign & (alt_loss > 0)
    )
    return SpinCheck(
        min_alpha_rad=min_alpha,
        min_abs_yaw_rate_radps=min_abs_r,
        mean_yaw_rate_radps=jnp.mean(r),
        altitude_loss_ft=alt_loss,
        mean_gamma_rad=jnp.mean(gamma_rad(w)),
        spinning=spinning,
    )
