"""Jittable, vmappable, differentiable aerodynamic lookup and coefficient build-up.

Linear interpolation in alpha (deg) on the uniform 4-deg grid, alpha wrapped to (-pi, pi] and
clamped to [-14, 90] deg. Rate derivatives multiply the non-dimensional rates p b/(2V),
q cbar/(2V), r b/(2V); symmetric stabilator deflection de uses C_X,de = cX_del + cX_der.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import data_harv as data
from harv_jax.aircraft.params import AircraftParams
from harv_jax.units import DEG_PER_RAD

_COL = {name: i for i, name in enumerate(data.AERO_COLUMNS)}
_N_SEGMENTS = len(data.ALPHA_DEG_GRID) - 1


class AeroCoeffs(NamedTuple):
    """Total aerodynamic coefficients (dimensionless). Lift/drag/side in wind axes."""

    CL: jnp.ndarray
    CD: jnp.ndarray
    CY: jnp.ndarray
    Cl: jnp.ndarray  # rolling moment, body axes
    Cm: jnp.ndarray
    Cn: jnp.ndarray


def wrap_angle_rad(a: jnp.ndarray) -> jnp.ndarray:
    """Wrap an angle to (-pi, pi]."""
    return jnp.pi - jnp.mod(jnp.pi - a, 2.0 * jnp.pi)


def segment(alpha_rad: jnp.ndarray, in_range: bool = False) -> tuple[jnp.ndarray, jnp.ndarray]:
    """(segment index as a float in 0..25, fraction in the segment) of alpha on the table grid.

    Args:
        alpha_rad: angle of attack, rad; wrapped to (-pi, pi], clamped to [-14, 90] deg.
        in_range: as in ``lookup``.
    """
    if in_range:
        a_deg = jnp.clip(alpha_rad * DEG_PER_RAD, data.ALPHA_MIN_DEG, data.ALPHA_MAX_DEG)
        a_deg = jnp.where(alpha_rad <= -jnp.pi, data.ALPHA_MAX_DEG, a_deg)
    else:
        a_deg = jnp.clip(wrap_angle_rad(alpha_rad) * DEG_PER_RAD, data.ALPHA_MIN_DEG, data.ALPHA_MAX_DEG)
    pos = (a_deg - data.ALPHA_MIN_DEG) / data.ALPHA_STEP_DEG
    idx = jnp.clip(jnp.floor(pos), 0, _N_SEGMENTS - 1)
    return idx, pos - idx


def lookup(
    alpha_rad: jnp.ndarray,
    aero_scale: jnp.ndarray | None = None,
    in_range: bool = False,
    table_per_rad: np.ndarray | None = None,
) -> jnp.ndarray:
    """Interpolated table row (per-radian derivatives), shape [33] in ``AERO_COLUMNS`` order.

    The two rows are a gather; gather-free forms (tent weights times the table, a chain of selects) were
    slower on the CPU, side by side in the plant and SMC steps (``benchmarks/bench_lookup.py``).

    Args:
        alpha_rad: angle of attack, rad (scalar); wrapped to (-pi, pi], clamped to [-14, 90] deg.
        aero_scale: optional [33] per-column multipliers.
        in_range: ``alpha_rad`` is known to lie in [-pi, pi] (an ``arctan2``): the wrap (a ``mod``) is
            skipped and -pi is taken as +pi, as the wrap maps it (same row up to the wrap's rounding).
        table_per_rad: the [27, 33] table (``AeroTable.per_rad``, a constant); None: the HARV table.
    """
    table_per_rad = data.AERO_TABLE_PER_RAD if table_per_rad is None else table_per_rad
    table = jnp.asarray(table_per_rad, dtype=jnp.result_type(alpha_rad, float))
    idx, frac = segment(alpha_rad, in_range)
    idx = idx.astype(jnp.int32)
    row = table[idx] * (1.0 - frac) + table[idx + 1] * frac
    if aero_scale is not None:
        row = row * aero_scale
    return row


def coefficients(
    alpha_rad: jnp.ndarray,
    beta_rad: jnp.ndarray,
    pqr_radps: jnp.ndarray,
    vt_fps: jnp.ndarray,
    u_rad: jnp.ndarray,
    params: AircraftParams,
    control_forces: bool = True,
    alpha_in_range: bool = False,
) -> AeroCoeffs:
    """Aerodynamic coefficients at one flight condition.

    Args:
        alpha_rad, beta_rad: aerodynamic angles, rad.
        pqr_radps: [3] body rates, rad/s.
        vt_fps: airspeed, ft/s (> 0; caller guards V -> 0).
        u_rad: [3] deflections [de, da, dr], rad.
        params: aircraft parameters (geometry, aero_table, aero_scale).
        control_forces: if False, drop the control-surface *force* terms (CL,de, CD,de, CY,d*):
            the SMC's controller model (relative degree 2). Moments always keep them.
        alpha_in_range: ``alpha_rad`` lies in [-pi, pi] (``lookup``'s ``in_range``).
    """
    c = lookup(alpha_rad, params.aero_scale, alpha_in_range, params.aero_table.per_rad)
    p, q, r = pqr_radps[0], pqr_radps[1], pqr_radps[2]
    de, da, dr = u_rad[0], u_rad[1], u_rad[2]
    ph = p * params.b / (2.0 * vt_fps)
    qh = q * params.cbar / (2.0 * vt_fps)
    rh = r * params.b / (2.0 * vt_fps)

    def k(name):
        return c[_COL[name]]

    CY = k("cy_b") * beta_rad + k("cy_p") * ph + k("cy_r") * rh
    Cl = (
        k("croll_b") * beta_rad
        + k("croll_p") * ph
        + k("croll_r") * rh
        + k("croll_da") * da
        + (k("croll_del") + k("croll_der")) * de
        + k("croll_dr") * dr
    )
    Cn = (
        k("cn_b") * beta_rad
        + k("cn_p") * ph
        + k("cn_r") * rh
        + k("cn_da") * da
        + (k("cn_del") + k("cn_der")) * de
        + k("cn_dr") * dr
    )
    CD = k("cd0") + k("cd_q") * qh
    CL = k("clift0") + k("clift_q") * qh
    if control_forces:  # (a Python branch: the controller model has no control terms to differentiate)
        CY = CY + (k("cy_da") * da + (k("cy_del") + k("cy_der")) * de + k("cy_dr") * dr)
        CD = CD + (k("cd_del") + k("cd_der")) * de
        CL = CL + (k("clift_del") + k("clift_der")) * de
    Cm = k("cm0") + k("cm_q") * qh + (k("cm_del") + k("cm_der")) * de
    return AeroCoeffs(CL=CL, CD=CD, CY=CY, Cl=Cl, Cm=Cm, Cn=Cn)
