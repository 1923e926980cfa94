"""Aircraft parameters as a pytree argument (vmappable: one aircraft per batch row).

The aerodynamic table is a static field (``aero_table``, an ``AeroTable``: a compile-time constant, the
same for every batch row); per-run aerodynamic uncertainty enters through ``aero_scale``, a traced
multiplier per table column.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.aircraft.aero_table import HARV_AERO_TABLE, AeroTable
from harv_jax.aircraft.data_harv import AERO_COLUMNS, IITM_MASS_GEOMETRY
from harv_jax.units import G_FPS2, RAD_PER_DEG

#: Actuator position limits (paper Table), rad: [de, da, dr].
U_MIN_RAD = np.array([-0.436, -0.436, -0.524])
U_MAX_RAD = np.array([0.175, 0.436, 0.524])
#: Actuator rate limits (NASA TP-1999-206573): stabilator 40, aileron 100, rudder 82 deg/s.
U_RATE_MAX_RADPS = np.array([40.0, 100.0, 82.0]) * RAD_PER_DEG
#: Default fixed throttle (the paper holds eta fixed and does not give its value).
DEFAULT_THROTTLE = 0.2


@struct.dataclass
class AircraftParams:
    """Per-aircraft parameters (traced leaves, batch them for domain randomization; ``aero_table`` static).

    Attributes:
        mass_slug: mass, slug.
        Ixx, Iyy, Izz, Ixz: inertia, slug ft^2 (Stevens & Lewis sign: Ixz = int x z dm).
        S: wing reference area, ft^2.  b: span, ft.  cbar: mean aerodynamic chord, ft.
        T_max: sea-level static maximum thrust, lbf.
        throttle: fixed throttle setting in [0, 1].
        g: gravity, ft/s^2.
        aero_scale: [33] multiplier per aero-table column (order ``AERO_COLUMNS``); ones = nominal.
        u_min_rad, u_max_rad: [3] deflection limits for [de, da, dr], rad.
        u_rate_max_radps: [3] deflection rate limits, rad/s.
        act_tau_s: first-order actuator lag time constant, s; 0 disables the lag (default).
        aero_table: the aerodynamic table (static: not a leaf; another table compiles anew).
    """

    mass_slug: jnp.ndarray
    Ixx: jnp.ndarray
    Iyy: jnp.ndarray
    Izz: jnp.ndarray
    Ixz: jnp.ndarray
    S: jnp.ndarray
    b: jnp.ndarray
    cbar: jnp.ndarray
    T_max: jnp.ndarray
    throttle: jnp.ndarray
    g: jnp.ndarray
    aero_scale: jnp.ndarray
    u_min_rad: jnp.ndarray
    u_max_rad: jnp.ndarray
    u_rate_max_radps: jnp.ndarray
    act_tau_s: jnp.ndarray
    aero_table: AeroTable = struct.field(pytree_node=False)


def harv(throttle: float = DEFAULT_THROTTLE, dtype=None) -> AircraftParams:
    """Nominal F-18/HARV parameters (IITM row of ``harv_mass_geometry.csv``).

    Args:
        throttle: fixed throttle in [0, 1].
        dtype: array dtype (default: jax's default float, float32 unless x64 is enabled).

    Returns:
        AircraftParams with scalar leaves (and [33]/[3] vectors).
    """
    if not 0.0 <= throttle <= 1.0:
        raise ValueError(f"throttle={throttle!r} is outside [0, 1]")
    mg = IITM_MASS_GEOMETRY
    dtype = jnp.result_type(float) if dtype is None else dtype  # strong type: no retrace on mixing

    def f(v):
        return jnp.asarray(v, dtype=dtype)

    return AircraftParams(
        mass_slug=f(mg["weight"] / G_FPS2),
        Ixx=f(mg["Ixx"]),
        Iyy=f(mg["Iyy"]),
        Izz=f(mg["Izz"]),
        Ixz=f(mg["Ixz"]),
        S=f(mg["S"]),
        b=f(mg["b"]),
        cbar=f(mg["cbar"]),
        T_max=f(mg["max_thrust_SL_static"]),
        throttle=f(throttle),
        g=f(G_FPS2),
        aero_scale=f(np.ones(len(AERO_COLUMNS))),
        u_min_rad=f(U_MIN_RAD),
        u_max_rad=f(U_MAX_RAD),
        u_rate_max_radps=f(U_RATE_MAX_RADPS),
        act_tau_s=f(0.0),
        aero_table=HARV_AERO_TABLE,
    )
