"""Straight, wings-level trim: solve V_dot = alpha_dot = q_dot = 0 for (alpha, de, throttle)."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics.eom import derivatives
from harv_jax.dynamics.state import WIND_INDEX

NEWTON_ITERS = 30


class Trim(NamedTuple):
    """Trim solution: alpha_rad, de_rad, throttle, and the max |residual| of (V_dot, alpha_dot, q_dot)."""

    alpha_rad: jnp.ndarray
    de_rad: jnp.ndarray
    throttle: jnp.ndarray
    residual: jnp.ndarray


def level_flight_state(vt_fps, h_ft, alpha_rad) -> jnp.ndarray:
    """Wind-axis state [10] of straight and level flight (beta = p = q = r = mu = gamma = chi = 0)."""
    z = jnp.zeros_like(jnp.asarray(vt_fps, dtype=jnp.result_type(float)))
    return jnp.stack([vt_fps + z, alpha_rad + z, z, z, z, z, z, z, z, h_ft + z])


def _residual(z: jnp.ndarray, vt_fps, h_ft, params: AircraftParams) -> jnp.ndarray:
    alpha, de, throttle = z[0], z[1], z[2]
    x = level_flight_state(vt_fps, h_ft, alpha)
    u = jnp.stack([de, 0.0 * de, 0.0 * de])
    xd = derivatives(x, u, params.replace(throttle=throttle))
    # V_dot in ft/s^2, alpha_dot (= -gamma_dot at level flight) in rad/s, q_dot in rad/s^2
    return jnp.stack([xd[WIND_INDEX[n]] for n in ("V", "alpha", "q")])


@jax.jit
def level_flight(vt_fps: float | jnp.ndarray, h_ft: float | jnp.ndarray, params: AircraftParams) -> Trim:
    """Trim for straight, wings-level flight at airspeed ``vt_fps`` and altitude ``h_ft``.

    Newton's method with the autodiff Jacobian (fixed iteration count, jittable, vmappable).
    Use float64 (``jax_enable_x64``) for residuals near 1e-8 and below.

    Returns:
        Trim(alpha_rad, de_rad, throttle, residual); residual = max |(V_dot, alpha_dot, q_dot)|.
        The throttle is not clipped to [0, 1]; check it for feasibility.
    """
    dtype = jnp.result_type(float)
    z0 = jnp.array([0.1, 0.0, 0.3], dtype=dtype)

    def body(_, z):
        res = _residual(z, vt_fps, h_ft, params)
        jac = jax.jacfwd(_residual)(z, vt_fps, h_ft, params)
        dz = jnp.linalg.solve(jac, res)
        return z - jnp.clip(dz, -0.2, 0.2)

    z = jax.lax.fori_loop(0, NEWTON_ITERS, body, z0)
    res = _residual(z, vt_fps, h_ft, params)
    return Trim(z[0], z[1], z[2], jnp.max(jnp.abs(res)))
