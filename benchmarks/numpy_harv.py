"""Plain-numpy F-18/HARV wind-axis model: the per-aircraft baseline of ``bench_dynamics.py``.

This is what a Gym-style environment does: one aircraft, numpy/math on scalars, RK4 on the paper's
wind-axis state x = [V, alpha, beta, p, q, r, mu, gamma, chi, h] (ft/s, rad, rad/s, ft) with controls
u = [de, da, dr] (rad) held over the step, and a rate- and position-limited actuator in front of it.

The equations are the verified forms of docs/model.md (wind-axis translational equations,
full-inertia body-rate equations, 1976 atmosphere, thrust ~ rho^0.7). Only the data (aero table, mass
properties) come from ``harv_jax.aircraft.data_harv``; no jax code is used. It is written to be a fair,
reasonably fast numpy implementation (table row by one vectorized interpolation, scalar trig via
``math``), not a deliberately slow one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from harv_jax.aircraft.data_harv import (
    AERO_COLUMNS,
    AERO_TABLE_PER_RAD,
    ALPHA_MAX_DEG,
    ALPHA_MIN_DEG,
    ALPHA_STEP_DEG,
    IITM_MASS_GEOMETRY,
)

G_FPS2 = 32.174
RHO_SL_SLUGFT3 = 0.0023769
M_PER_FT = 0.3048
_T0_K, _LAPSE_KPM, _G0_MPS2 = 288.15, 0.0065, 9.80665
_R_AIR = 8.31432 / 0.0289644
_N_EXP = _G0_MPS2 / (_R_AIR * _LAPSE_KPM)
_T11_K, _H11_M = 216.65, 11000.0
_RHO11 = RHO_SL_SLUGFT3 * (_T11_K / _T0_K) ** (_N_EXP - 1.0)
_DEG_PER_RAD = 180.0 / math.pi
_C = {n: i for i, n in enumerate(AERO_COLUMNS)}
_CY_B, _CY_P, _CY_R, _CY_DA, _CY_DEL, _CY_DER, _CY_DR = (
    _C["cy_" + k] for k in ("b", "p", "r", "da", "del", "der", "dr")
)
_CL_B, _CL_P, _CL_R, _CL_DA, _CL_DEL, _CL_DER, _CL_DR = (
    _C["croll_" + k] for k in ("b", "p", "r", "da", "del", "der", "dr")
)
_CN_B, _CN_P, _CN_R, _CN_DA, _CN_DEL, _CN_DER, _CN_DR = (
    _C["cn_" + k] for k in ("b", "p", "r", "da", "del", "der", "dr")
)
_CD0, _CD_Q, _CD_DEL, _CD_DER = (_C[k] for k in ("cd0", "cd_q", "cd_del", "cd_der"))
_CLIFT0, _CLIFT_Q, _CLIFT_DEL, _CLIFT_DER = (_C[k] for k in ("clift0", "clift_q", "clift_del", "clift_der"))
_CM0, _CM_Q, _CM_DEL, _CM_DER = (_C[k] for k in ("cm0", "cm_q", "cm_del", "cm_der"))
_N_SEG = AERO_TABLE_PER_RAD.shape[0] - 1


@dataclass
class NumpyParams:
    """Aircraft parameters (nominal HARV by default); units as ``harv_jax.aircraft.AircraftParams``."""

    mass_slug: float = IITM_MASS_GEOMETRY["weight"] / G_FPS2
    Ixx: float = IITM_MASS_GEOMETRY["Ixx"]
    Iyy: float = IITM_MASS_GEOMETRY["Iyy"]
    Izz: float = IITM_MASS_GEOMETRY["Izz"]
    Ixz: float = IITM_MASS_GEOMETRY["Ixz"]
    S: float = IITM_MASS_GEOMETRY["S"]
    b: float = IITM_MASS_GEOMETRY["b"]
    cbar: float = IITM_MASS_GEOMETRY["cbar"]
    T_max: float = IITM_MASS_GEOMETRY["max_thrust_SL_static"]
    throttle: float = 0.2
    g: float = G_FPS2
    aero_scale: np.ndarray = field(default_factory=lambda: np.ones(len(AERO_COLUMNS)))
    u_min_rad: np.ndarray = field(default_factory=lambda: np.array([-0.436, -0.436, -0.524]))
    u_max_rad: np.ndarray = field(default_factory=lambda: np.array([0.175, 0.436, 0.524]))
    u_rate_max_radps: np.ndarray = field(default_factory=lambda: np.radians([40.0, 100.0, 82.0]))


def density_slugft3(h_ft: float) -> float:
    """1976 standard atmosphere density, slug/ft^3."""
    h_m = h_ft * M_PER_FT
    if h_m < _H11_M:
        return RHO_SL_SLUGFT3 * ((_T0_K - _LAPSE_KPM * h_m) / _T0_K) ** (_N_EXP - 1.0)
    return _RHO11 * math.exp(-_G0_MPS2 * (h_m - _H11_M) / (_R_AIR * _T11_K))


def table_row(alpha_rad: float, aero_scale: np.ndarray) -> np.ndarray:
    """Per-radian table row [33] at alpha (wrapped to (-pi, pi], clamped to [-14, 90] deg)."""
    a = math.pi - (math.pi - alpha_rad) % (2.0 * math.pi)  # Python's % is >= 0 here: a in (-pi, pi]
    a_deg = min(max(a * _DEG_PER_RAD, ALPHA_MIN_DEG), ALPHA_MAX_DEG)
    pos = (a_deg - ALPHA_MIN_DEG) / ALPHA_STEP_DEG
    i = min(int(pos), _N_SEG - 1)
    f = pos - i
    return (AERO_TABLE_PER_RAD[i] * (1.0 - f) + AERO_TABLE_PER_RAD[i + 1] * f) * aero_scale


def derivatives(x: np.ndarray, u: np.ndarray, prm: NumpyParams) -> np.ndarray:
    """Wind-axis state derivative [10] (docs/model.md forms).

    Args:
        x: [10] state [V, alpha, beta, p, q, r, mu, gamma, chi, h] (ft/s, rad, rad/s, ft).
        u: [3] deflections [de, da, dr], rad.
        prm: aircraft parameters.

    Returns:
        [10] time derivative (float64).
    """
    V, alpha, beta, p, q, r, mu, gamma, _, h = x.tolist()
    de, da, dr = u.tolist()
    c = table_row(alpha, prm.aero_scale).tolist()  # Python floats: faster scalar math than numpy scalars
    ph, qh, rh = p * prm.b / (2 * V), q * prm.cbar / (2 * V), r * prm.b / (2 * V)
    cy = (c[_CY_B] * beta + c[_CY_P] * ph + c[_CY_R] * rh + c[_CY_DA] * da
          + (c[_CY_DEL] + c[_CY_DER]) * de + c[_CY_DR] * dr)  # fmt: skip
    cl = (c[_CL_B] * beta + c[_CL_P] * ph + c[_CL_R] * rh + c[_CL_DA] * da
          + (c[_CL_DEL] + c[_CL_DER]) * de + c[_CL_DR] * dr)  # fmt: skip
    cn = (c[_CN_B] * beta + c[_CN_P] * ph + c[_CN_R] * rh + c[_CN_DA] * da
          + (c[_CN_DEL] + c[_CN_DER]) * de + c[_CN_DR] * dr)  # fmt: skip
    cd = c[_CD0] + c[_CD_Q] * qh + (c[_CD_DEL] + c[_CD_DER]) * de
    cL = c[_CLIFT0] + c[_CLIFT_Q] * qh + (c[_CLIFT_DEL] + c[_CLIFT_DER]) * de
    cm = c[_CM0] + c[_CM_Q] * qh + (c[_CM_DEL] + c[_CM_DER]) * de

    rho = density_slugft3(h)
    qs = 0.5 * rho * V * V * prm.S
    L, D, Y = qs * cL, qs * cd, qs * cy
    Lr, M, N = qs * prm.b * cl, qs * prm.cbar * cm, qs * prm.b * cn
    T = prm.throttle * prm.T_max * (rho / RHO_SL_SLUGFT3) ** 0.7
    m, g = prm.mass_slug, prm.g
    sa, ca = math.sin(alpha), math.cos(alpha)
    sb, cb = math.sin(beta), math.cos(beta)
    tb = sb / cb
    smu, cmu = math.sin(mu), math.cos(mu)
    sg, cg = math.sin(gamma), math.cos(gamma)
    tg = sg / cg

    q_w = (L + T * sa - m * g * cmu * cg) / (m * V)
    r_w = (Y - T * ca * sb + m * g * smu * cg) / (m * V)
    Ixx, Iyy, Izz, Ixz = prm.Ixx, prm.Iyy, prm.Izz, prm.Ixz
    gam = Ixx * Izz - Ixz * Ixz
    c_pq, c_qr = Ixz * (Ixx - Iyy + Izz), Izz * (Izz - Iyy) + Ixz**2
    c_rpq = Ixx * (Ixx - Iyy) + Ixz**2
    return np.array(
        [
            (T * ca * cb - D - m * g * sg) / m,
            q - tb * (p * ca + r * sa) - q_w / cb,
            r_w + p * sa - r * ca,
            (Izz * Lr + Ixz * N + c_pq * p * q - c_qr * q * r) / gam,
            (M + (Izz - Ixx) * p * r - Ixz * (p * p - r * r)) / Iyy,
            (Ixz * Lr + Ixx * N + c_rpq * p * q - c_pq * q * r) / gam,
            (p * ca + r * sa) / cb + tb * q_w + tg * (q_w * smu + r_w * cmu),
            q_w * cmu - r_w * smu,
            (q_w * smu + r_w * cmu) / cg,
            V * sg,
        ]
    )


def rk4_step(x: np.ndarray, u: np.ndarray, prm: NumpyParams, dt_s: float) -> np.ndarray:
    """One RK4 step of the wind-axis state [10], controls [3] held over the step."""
    k1 = derivatives(x, u, prm)
    k2 = derivatives(x + 0.5 * dt_s * k1, u, prm)
    k3 = derivatives(x + 0.5 * dt_s * k2, u, prm)
    k4 = derivatives(x + dt_s * k3, u, prm)
    return x + (dt_s / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def actuator_step(delta_rad: np.ndarray, cmd_rad: np.ndarray, prm: NumpyParams, dt_s: float) -> np.ndarray:
    """Rate- and position-limited surfaces [3] (no lag), as ``harv_jax.dynamics.actuator_step``."""
    target = np.clip(cmd_rad, prm.u_min_rad, prm.u_max_rad)
    max_step = prm.u_rate_max_radps * dt_s
    return np.clip(delta_rad + np.clip(target - delta_rad, -max_step, max_step), prm.u_min_rad, prm.u_max_rad)


def simulate(x0: np.ndarray, cmd_rad: np.ndarray, prm: NumpyParams, dt_s: float, n_steps: int) -> np.ndarray:
    """Step one aircraft ``n_steps`` times in a Python loop (the Gym-env pattern); returns the last state."""
    x = np.asarray(x0, dtype=np.float64).copy()
    delta = np.zeros(3)
    for _ in range(n_steps):
        delta = actuator_step(delta, cmd_rad, prm, dt_s)
        x = rk4_step(x, delta, prm, dt_s)
    return x
