"""Independent float64 numpy oracle of the F-18/HARV model, written in body axes.

Written from docs/model.md (data, atmosphere, thrust, force/moment definitions) and textbook
rigid-body mechanics (Stevens, Lewis & Johnson, *Aircraft Control and Simulation*, 3rd ed., sec. 1.3,
2.4-2.5), *not* from harv_jax's closed-form wind-axis equations. It shares no code with harv_jax: it reads
the aero CSV itself and uses the per-degree build-up of the table's README.

Route (one state at a time, plain numpy, float64):

1. Wind-axis state x = [V, alpha, beta, p, q, r, mu, gamma, chi, h] -> body velocity (u, v, w), the
   NED->wind rotation C_wn = R1(mu) R2(gamma) R3(chi), the body->wind rotation C_wb = R3(beta) R2(-alpha),
   and the 3-2-1 Euler angles (phi, theta, psi) of C_bn = C_wb^T C_wn.
2. Forces: aerodynamic (-D, Y, -L) rotated wind->body, thrust along body +x, gravity through the Euler
   angles; Stevens' u_dot = r v - q w - g sin(theta) + X/m, etc. Moments: J omega_dot = M - omega x J omega
   solved with the full inertia matrix J = [[Ixx, 0, -Ixz], [0, Iyy, 0], [-Ixz, 0, Izz]].
3. Back to wind-axis rates: V_dot, alpha_dot, beta_dot from (u, v, w) and their derivatives
   (alpha = atan2(w, u), beta = asin(v / V)); gamma_dot, chi_dot, h_dot from the NED velocity
   v_n = C_nb uvw and its derivative C_nb (uvw_dot + omega x uvw); mu_dot from the analytic derivative of
   C_wn = C_wb C_bn (C_bn_dot = -[omega x] C_bn, C_wb_dot from alpha_dot and beta_dot), with
   mu = atan2(C_wn[1, 2], C_wn[2, 2]).

Parameters are a plain dict (see ``params_from_values``) so the oracle never touches jax.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: The package's aero table (the data under test is shared; the code that reads it is not).
TABLE_PATH = Path(__file__).resolve().parents[1] / "harv_jax" / "aircraft" / "data" / "harv_aero_table.csv"

# docs/model.md constants, restated here on purpose (independent of harv_jax.units / atmosphere).
G_FPS2 = 32.174
RHO_SL_SLUGFT3 = 0.0023769
FT_TO_M = 0.3048
T0_K = 288.15
LAPSE_K_PER_M = 0.0065
G0_MPS2 = 9.80665
R_AIR = 8.31432 / 0.0289644
N_EXP = G0_MPS2 / (R_AIR * LAPSE_K_PER_M)
T11_K = 216.65
H11_M = 11000.0
ALPHA_CLAMP_DEG = (-14.0, 90.0)
DEG = 180.0 / math.pi  # degrees per radian

#: docs/model.md / IITM row defaults.
NOMINAL = {
    "mass_slug": 36100.0 / G_FPS2,
    "Ixx": 22789.0,
    "Iyy": 176809.0,
    "Izz": 191744.0,
    "Ixz": -2305.0,
    "S": 400.0,
    "b": 37.4,
    "cbar": 11.52,
    "T_max": 32000.0,
    "g": G_FPS2,
}


def _load_table() -> tuple[list[str], np.ndarray]:
    with TABLE_PATH.open() as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(TABLE_PATH, delimiter=",", skiprows=1, dtype=np.float64)
    return header[1:], data


COLUMNS, _DATA = _load_table()
ALPHA_GRID_DEG: np.ndarray = _DATA[:, 0]
#: Raw table [27, 33], per-degree columns as published (cd0, clift0, cm0 dimensionless).
TABLE_RAW: np.ndarray = _DATA[:, 1:]
_IDX = {name: j for j, name in enumerate(COLUMNS)}


def params_from_values(throttle: float, aero_scale: np.ndarray | None = None, **overrides: float) -> dict:
    """Oracle parameter dict: docs/model.md nominal values, overridden by keyword."""
    p = dict(NOMINAL)
    p.update({k: float(v) for k, v in overrides.items()})
    p["throttle"] = float(throttle)
    p["aero_scale"] = np.ones(len(COLUMNS)) if aero_scale is None else np.asarray(aero_scale, np.float64)
    return p


def density(h_ft: float) -> float:
    """1976 standard atmosphere density, slug/ft^3 (docs/model.md)."""
    h_m = FT_TO_M * h_ft
    if h_m < H11_M:
        theta = (T0_K - LAPSE_K_PER_M * h_m) / T0_K
        return RHO_SL_SLUGFT3 * theta ** (N_EXP - 1.0)
    theta11 = T11_K / T0_K
    return RHO_SL_SLUGFT3 * theta11 ** (N_EXP - 1.0) * math.exp(-G0_MPS2 * (h_m - H11_M) / (R_AIR * T11_K))


def table_row(alpha_rad: float, aero_scale: np.ndarray | None = None) -> dict[str, float]:
    """Table row at alpha (wrapped to (-pi, pi], clamped to [-14, 90] deg), per-degree as published."""
    a_wrapped = math.atan2(math.sin(alpha_rad), math.cos(alpha_rad))
    a_deg = min(max(a_wrapped * DEG, ALPHA_CLAMP_DEG[0]), ALPHA_CLAMP_DEG[1])
    scale = np.ones(len(COLUMNS)) if aero_scale is None else aero_scale
    return {n: float(np.interp(a_deg, ALPHA_GRID_DEG, TABLE_RAW[:, j])) * scale[j] for n, j in _IDX.items()}


def aero_coefficients(alpha, beta, p, q, r, V, u, prm) -> dict[str, float]:
    """CL, CD, CY, Cl, Cm, Cn by the README's per-degree formulas (del = der = de)."""
    c = table_row(alpha, prm["aero_scale"])
    b, cbar = prm["b"], prm["cbar"]
    beta_d = beta * DEG
    ph, qh, rh = (p * DEG) * b / (2 * V), (q * DEG) * cbar / (2 * V), (r * DEG) * b / (2 * V)
    de, da, dr = u[0] * DEG, u[1] * DEG, u[2] * DEG

    def lateral(pre):
        return (
            c[pre + "_b"] * beta_d
            + c[pre + "_p"] * ph
            + c[pre + "_r"] * rh
            + c[pre + "_da"] * da
            + c[pre + "_del"] * de
            + c[pre + "_der"] * de
            + c[pre + "_dr"] * dr
        )

    return {
        "CY": lateral("cy"),
        "Cl": lateral("croll"),
        "Cn": lateral("cn"),
        "CD": c["cd0"] + c["cd_q"] * qh + c["cd_del"] * de + c["cd_der"] * de,
        "CL": c["clift0"] + c["clift_q"] * qh + c["clift_del"] * de + c["clift_der"] * de,
        "Cm": c["cm0"] + c["cm_q"] * qh + c["cm_del"] * de + c["cm_der"] * de,
    }


def _r1(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, s], [0, -s, c]], dtype=np.float64)


def _r2(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, -s], [0, 1, 0], [s, 0, c]], dtype=np.float64)


def _r3(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]], dtype=np.float64)


def _dr2(a):  # d R2(a) / da
    c, s = math.cos(a), math.sin(a)
    return np.array([[-s, 0, -c], [0, 0, 0], [c, 0, -s]], dtype=np.float64)


def _dr3(a):  # d R3(a) / da
    c, s = math.cos(a), math.sin(a)
    return np.array([[-s, c, 0], [-c, -s, 0], [0, 0, 0]], dtype=np.float64)


def _skew(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]], dtype=np.float64)


def body_rates_of_change(x: np.ndarray, u: np.ndarray, prm: dict) -> dict[str, np.ndarray]:
    """Body-axis quantities at wind-axis state x [10] with controls u [3].

    Returns:
        dict with uvw [3] ft/s, uvw_dot [3] ft/s^2, omega_dot [3] rad/s^2, C_bn [3,3] (NED -> body),
        euler [phi, theta, psi] rad, forces_body [3] lbf (aero + thrust, no gravity).
    """
    V, alpha, beta = x[0], x[1], x[2]
    omega = np.array(x[3:6], dtype=np.float64)
    mu, gamma, chi, h = x[6], x[7], x[8], x[9]
    m, g = prm["mass_slug"], prm["g"]

    uvw = V * np.array([math.cos(alpha) * math.cos(beta), math.sin(beta), math.sin(alpha) * math.cos(beta)])
    c_wb = _r3(beta) @ _r2(-alpha)
    c_wn = _r1(mu) @ _r2(gamma) @ _r3(chi)
    c_bn = c_wb.T @ c_wn
    # 3-2-1 Euler angles of C_bn = R1(phi) R2(theta) R3(psi)
    theta = math.atan2(-c_bn[0, 2], math.hypot(c_bn[0, 0], c_bn[0, 1]))
    phi = math.atan2(c_bn[1, 2], c_bn[2, 2])
    psi = math.atan2(c_bn[0, 1], c_bn[0, 0])

    rho = density(h)
    qbar = 0.5 * rho * V * V
    co = aero_coefficients(alpha, beta, omega[0], omega[1], omega[2], V, u, prm)
    S, b, cbar = prm["S"], prm["b"], prm["cbar"]
    lift, drag, side = qbar * S * co["CL"], qbar * S * co["CD"], qbar * S * co["CY"]
    thrust = prm["throttle"] * prm["T_max"] * (rho / RHO_SL_SLUGFT3) ** 0.7
    f_body = c_wb.T @ np.array([-drag, side, -lift]) + np.array([thrust, 0.0, 0.0])

    uu, vv, ww = uvw
    p, q, r = omega
    st, ct, sp, cp = math.sin(theta), math.cos(theta), math.sin(phi), math.cos(phi)
    uvw_dot = np.array(
        [
            r * vv - q * ww - g * st + f_body[0] / m,
            p * ww - r * uu + g * sp * ct + f_body[1] / m,
            q * uu - p * vv + g * cp * ct + f_body[2] / m,
        ]
    )
    moments = qbar * S * np.array([b * co["Cl"], cbar * co["Cm"], b * co["Cn"]])
    J = np.array([[prm["Ixx"], 0, -prm["Ixz"]], [0, prm["Iyy"], 0], [-prm["Ixz"], 0, prm["Izz"]]])
    omega_dot = np.linalg.solve(J, moments - np.cross(omega, J @ omega))
    return {
        "uvw": uvw,
        "uvw_dot": uvw_dot,
        "omega_dot": omega_dot,
        "C_bn": c_bn,
        "euler": np.array([phi, theta, psi]),
        "forces_body": f_body,
    }


def wind_derivatives(x: np.ndarray, u: np.ndarray, prm: dict) -> np.ndarray:
    """Wind-axis x_dot [10] computed through the body-axis equations (see module docstring)."""
    x = np.asarray(x, dtype=np.float64)
    u = np.asarray(u, dtype=np.float64)
    alpha, beta = x[1], x[2]
    omega = x[3:6]
    bq = body_rates_of_change(x, u, prm)
    uvw, uvw_dot, c_bn = bq["uvw"], bq["uvw_dot"], bq["C_bn"]
    uu, vv, ww = uvw
    ud, vd, wd = uvw_dot

    V = math.sqrt(uu * uu + vv * vv + ww * ww)
    V_dot = (uu * ud + vv * vd + ww * wd) / V
    alpha_dot = (uu * wd - ww * ud) / (uu * uu + ww * ww)
    beta_dot = (V * vd - vv * V_dot) / (V * math.hypot(uu, ww))

    c_nb = c_bn.T
    v_n = c_nb @ uvw
    v_n_dot = c_nb @ (uvw_dot + np.cross(omega, uvw))
    s = math.hypot(v_n[0], v_n[1])
    s_dot = (v_n[0] * v_n_dot[0] + v_n[1] * v_n_dot[1]) / s
    gamma_dot = (-s * v_n_dot[2] + v_n[2] * s_dot) / (s * s + v_n[2] ** 2)
    chi_dot = (v_n[0] * v_n_dot[1] - v_n[1] * v_n_dot[0]) / (s * s)
    h_dot = -v_n[2]

    c_wb = _r3(beta) @ _r2(-alpha)
    c_wb_dot = _dr3(beta) @ _r2(-alpha) * beta_dot - _r3(beta) @ _dr2(-alpha) * alpha_dot
    c_bn_dot = -_skew(omega) @ c_bn
    c_wn = c_wb @ c_bn
    c_wn_dot = c_wb_dot @ c_bn + c_wb @ c_bn_dot
    a, bb = c_wn[1, 2], c_wn[2, 2]
    mu_dot = (bb * c_wn_dot[1, 2] - a * c_wn_dot[2, 2]) / (a * a + bb * bb)

    return np.array(
        [V_dot, alpha_dot, beta_dot, *bq["omega_dot"], mu_dot, gamma_dot, chi_dot, h_dot],
        dtype=np.float64,
    )
