"""Slower reference implementations of the SMC step and the model, kept for the equality tests.

Copied verbatim from the commit before the change (only the names changed): the SMC's fused Lie
terms (one ``jax.linearize`` with 7 tangents), the LAPACK-SVD guarded solve, the aero table lookup
and coefficient build-up, the atmosphere (two powers and an exp), the force/moment build-up and
the wind-axis derivatives.
``use_reference`` swaps them into the package for the duration of a ``with`` block (tracing inside
the block uses them; the jax caches are cleared on entry and exit).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import jax
import jax.numpy as jnp
import pytest

from harv_jax.aircraft import aero
from harv_jax.aircraft import data_harv as data
from harv_jax.aircraft.aero import AeroCoeffs, wrap_angle_rad
from harv_jax.aircraft.params import AircraftParams
from harv_jax.control import lie, smc
from harv_jax.control.lie import Y_INDEX, LieTerms1, LieTerms2, controller_model, output_y
from harv_jax.control.smc import SolveInfo
from harv_jax.dynamics import eom
from harv_jax.dynamics.atmosphere import (
    G0_MPS2,
    H_TROPOPAUSE_M,
    LAPSE_KPM,
    N_EXP,
    R_JPKGK,
    RHO_SL_SLUGFT3,
    T0_K,
    T11_K,
    THETA11,
)
from harv_jax.dynamics.eom import V_FLOOR_FPS, ForcesMoments, body_rate_derivatives
from harv_jax.units import DEG_PER_RAD, M_PER_FT

_COL = {name: i for i, name in enumerate(data.AERO_COLUMNS)}
_N_SEGMENTS = len(data.ALPHA_DEG_GRID) - 1


def lookup_reference(alpha_rad: jnp.ndarray, aero_scale: jnp.ndarray | None = None) -> jnp.ndarray:
    """Interpolated table row (per-radian derivatives), shape [33] in ``AERO_COLUMNS`` order.

    Args:
        alpha_rad: angle of attack, rad (scalar); wrapped to (-pi, pi], clamped to [-14, 90] deg.
        aero_scale: optional [33] per-column multipliers.
    """
    table = jnp.asarray(data.AERO_TABLE_PER_RAD, dtype=jnp.result_type(alpha_rad, float))
    a_deg = jnp.clip(wrap_angle_rad(alpha_rad) * DEG_PER_RAD, data.ALPHA_MIN_DEG, data.ALPHA_MAX_DEG)
    pos = (a_deg - data.ALPHA_MIN_DEG) / data.ALPHA_STEP_DEG
    idx = jnp.clip(jnp.floor(pos), 0, _N_SEGMENTS - 1).astype(jnp.int32)
    frac = pos - idx
    row = table[idx] * (1.0 - frac) + table[idx + 1] * frac
    if aero_scale is not None:
        row = row * aero_scale
    return row


def coefficients_reference(
    alpha_rad: jnp.ndarray,
    beta_rad: jnp.ndarray,
    pqr_radps: jnp.ndarray,
    vt_fps: jnp.ndarray,
    u_rad: jnp.ndarray,
    params: AircraftParams,
    control_forces: bool = True,
    alpha_in_range: bool = False,  # (accepted for the current callers; the reference always wraps)
) -> AeroCoeffs:
    """Aerodynamic coefficients at one flight condition.

    Args:
        alpha_rad, beta_rad: aerodynamic angles, rad.
        pqr_radps: [3] body rates, rad/s.
        vt_fps: airspeed, ft/s (> 0; caller guards V -> 0).
        u_rad: [3] deflections [de, da, dr], rad.
        params: aircraft parameters (geometry, aero_scale).
        control_forces: if False, drop the control-surface *force* terms (CL,de, CD,de, CY,d*):
            the SMC's controller model (relative degree 2). Moments always keep them.
    """
    c = lookup_reference(alpha_rad, params.aero_scale)
    p, q, r = pqr_radps[0], pqr_radps[1], pqr_radps[2]
    de, da, dr = u_rad[0], u_rad[1], u_rad[2]
    ph = p * params.b / (2.0 * vt_fps)
    qh = q * params.cbar / (2.0 * vt_fps)
    rh = r * params.b / (2.0 * vt_fps)

    def k(name):
        return c[_COL[name]]

    kf = 1.0 if control_forces else 0.0
    CY = (
        k("cy_b") * beta_rad
        + k("cy_p") * ph
        + k("cy_r") * rh
        + kf * (k("cy_da") * da + (k("cy_del") + k("cy_der")) * de + k("cy_dr") * dr)
    )
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
    CD = k("cd0") + k("cd_q") * qh + kf * (k("cd_del") + k("cd_der")) * de
    CL = k("clift0") + k("clift_q") * qh + kf * (k("clift_del") + k("clift_der")) * de
    Cm = k("cm0") + k("cm_q") * qh + (k("cm_del") + k("cm_der")) * de
    return AeroCoeffs(CL=CL, CD=CD, CY=CY, Cl=Cl, Cm=Cm, Cn=Cn)


def guarded_solve_reference(
    a: jnp.ndarray, b: jnp.ndarray, cond_max: jnp.ndarray, sigma_floor: jnp.ndarray
) -> tuple[jnp.ndarray, SolveInfo]:
    """Solve a u = b [3x3] with damped least squares when a is ill-conditioned; always finite.

    Args:
        a: [3, 3] matrix (non-finite entries are treated as 0).
        b: [3] right-hand side (non-finite entries are treated as 0).
        cond_max: condition number above which damping is applied.
        sigma_floor: absolute floor of the singular-value threshold (so a = 0 gives u = 0).

    Returns:
        (u [3], SolveInfo). Equals ``solve(a, b)`` when cond(a) <= cond_max and s_min >= sigma_floor.
    """
    a = jnp.where(jnp.isfinite(a), a, 0.0)
    b = jnp.where(jnp.isfinite(b), b, 0.0)
    u_mat, sv, vt = jnp.linalg.svd(a, full_matrices=False)
    s_max, s_min = sv[0], sv[-1]
    s_th = jnp.maximum(s_max / cond_max, sigma_floor)
    ratio = jnp.minimum(s_min / s_th, 1.0)
    rho2 = (1.0 - ratio * ratio) * s_th * s_th
    inv = sv / (sv * sv + rho2)
    u = vt.T @ (inv * (u_mat.T @ b))
    cond = s_max / jnp.maximum(s_min, jnp.finfo(sv.dtype).tiny)
    return u, SolveInfo(cond=cond, rho2=rho2, guard_active=rho2 > 0)


def smc_lie_terms_reference(x: jnp.ndarray, params: AircraftParams) -> tuple[LieTerms2, LieTerms1]:
    """``output_lie_terms`` and ``roll_rate_lie_terms`` from one linearization of the model.

    With Z(x, u) = [F(x, u) (10), p_w(x) (1)] linearized once at (x, 0): f = F(x, 0),
    g_j = dZ(0, e_j)[:10], and since L_f y = F(x, 0)[Y_INDEX], L_f^2 y = dZ(f, 0)[Y_INDEX],
    L_g L_f y = dZ(g_j, 0)[Y_INDEX], L_f p_w = dZ(f, 0)[10], L_g p_w = dZ(g_j, 0)[10]. Same values
    as the separate functions (tested), with about half of their graph (compile time).

    Returns:
        (LieTerms2 of y = [alpha, beta, mu], LieTerms1 of p_w).
    """
    u0 = jnp.zeros((3,), dtype=x.dtype)
    idx = jnp.array(Y_INDEX)

    def z(xx: jnp.ndarray, uu: jnp.ndarray) -> jnp.ndarray:
        xd = controller_model(xx, uu, params)
        alpha, beta = xx[1], xx[2]
        p, q, r = xx[3], xx[4], xx[5]
        p_w = jnp.cos(beta) * (p * jnp.cos(alpha) + r * jnp.sin(alpha)) + jnp.sin(beta) * (q - xd[1])
        return jnp.concatenate([xd, p_w[None]])

    z_val, lin = jax.linearize(z, x, u0)
    f = z_val[:10]
    eye = jnp.eye(3, dtype=x.dtype)
    g = jax.vmap(lambda du: lin(jnp.zeros_like(x), du))(eye)[:, :10]  # [3, 10] = g^T
    dirs = jnp.concatenate([f[None], g], axis=0)  # [4, 10]: f, g_1, g_2, g_3
    dz = jax.vmap(lambda dx: lin(dx, u0))(dirs)  # [4, 11]
    y_terms = LieTerms2(y=output_y(x), lf_y=f[idx], lf2_y=dz[0, idx], lglf_y=dz[1:, idx].T)
    pw_terms = LieTerms1(h=z_val[10:], lf_h=dz[0, 10:], lg_h=dz[1:, 10:].T)
    return y_terms, pw_terms


def density_slugft3_reference(h_ft: jnp.ndarray) -> jnp.ndarray:
    """Air density, slug/ft^3, at altitude h_ft (rho(25,000 ft) = 1.06513e-3)."""
    h_m = h_ft * M_PER_FT
    theta = (T0_K - LAPSE_KPM * jnp.minimum(h_m, H_TROPOPAUSE_M)) / T0_K
    rho_tropo = RHO_SL_SLUGFT3 * theta ** (N_EXP - 1.0)
    rho_strato = (
        RHO_SL_SLUGFT3
        * THETA11 ** (N_EXP - 1.0)
        * jnp.exp(-G0_MPS2 * (jnp.maximum(h_m, H_TROPOPAUSE_M) - H_TROPOPAUSE_M) / (R_JPKGK * T11_K))
    )
    return jnp.where(h_m < H_TROPOPAUSE_M, rho_tropo, rho_strato)


def forces_moments_reference(
    vt_fps: jnp.ndarray,
    alpha_rad: jnp.ndarray,
    beta_rad: jnp.ndarray,
    pqr_radps: jnp.ndarray,
    h_ft: jnp.ndarray,
    u_rad: jnp.ndarray,
    params: AircraftParams,
    control_forces: bool = True,
    alpha_in_range: bool = False,  # (accepted for the current callers; the reference always wraps)
) -> ForcesMoments:
    """Aerodynamic forces and moments plus thrust at one flight condition."""
    rho = density_slugft3_reference(h_ft)
    qbar = 0.5 * rho * vt_fps * vt_fps
    thrust = params.throttle * params.T_max * (rho / RHO_SL_SLUGFT3) ** 0.7
    c = coefficients_reference(
        alpha_rad, beta_rad, pqr_radps, jnp.maximum(vt_fps, V_FLOOR_FPS), u_rad, params,
        control_forces,
    )  # fmt: skip
    qs = qbar * params.S
    return ForcesMoments(
        L=qs * c.CL,
        D=qs * c.CD,
        Y=qs * c.CY,
        Lroll=qs * params.b * c.Cl,
        M=qs * params.cbar * c.Cm,
        N=qs * params.b * c.Cn,
        T=thrust,
    )


def derivatives_reference(
    x: jnp.ndarray, u: jnp.ndarray, params: AircraftParams, control_forces: bool = True
) -> jnp.ndarray:
    """Wind-axis state derivative x_dot [10] of the paper's model (docs/model.md forms).

    Args:
        x: [10] state [V, alpha, beta, p, q, r, mu, gamma, chi, h] (ft/s, rad, rad/s, ft).
        u: [3] deflections [de, da, dr], rad (used as given; limits are the actuator model's job).
        params: aircraft parameters (pytree; vmap it together with x and u).
        control_forces: False gives the SMC's controller model (no control-surface forces).

    Returns:
        [10] time derivative. Singular at V = 0, cos(beta) = 0, cos(gamma) = 0.
    """
    vt, alpha, beta = x[0], x[1], x[2]
    pqr = x[3:6]
    p, r = pqr[0], pqr[2]
    q = pqr[1]
    mu, gamma, h = x[6], x[7], x[9]
    fm = forces_moments_reference(vt, alpha, beta, pqr, h, u, params, control_forces)
    m, g = params.mass_slug, params.g
    sa, ca = jnp.sin(alpha), jnp.cos(alpha)
    sb, cb, tb = jnp.sin(beta), jnp.cos(beta), jnp.tan(beta)
    smu, cmu = jnp.sin(mu), jnp.cos(mu)
    sg, cg, tg = jnp.sin(gamma), jnp.cos(gamma), jnp.tan(gamma)
    L, D, Y, T = fm.L, fm.D, fm.Y, fm.T
    mv = m * vt

    v_dot = (T * ca * cb - D - m * g * sg) / m
    q_w = (L + T * sa - m * g * cmu * cg) / mv  # = -F_z,wind / (m V)
    r_w = (Y - T * ca * sb + m * g * smu * cg) / mv  # = F_y,wind / (m V)
    alpha_dot = q - tb * (p * ca + r * sa) - q_w / cb
    beta_dot = r_w + p * sa - r * ca
    p_w = (p * ca + r * sa) / cb + tb * q_w
    mu_dot = p_w + tg * (q_w * smu + r_w * cmu)
    gamma_dot = q_w * cmu - r_w * smu
    chi_dot = (q_w * smu + r_w * cmu) / cg
    h_dot = vt * sg
    pqr_dot = body_rate_derivatives(pqr, fm.Lroll, fm.M, fm.N, params)
    return jnp.stack(
        [v_dot, alpha_dot, beta_dot, pqr_dot[0], pqr_dot[1], pqr_dot[2],
         mu_dot, gamma_dot, chi_dot, h_dot]
    )  # fmt: skip


@contextlib.contextmanager
def use_reference() -> Iterator[None]:
    """Swap the reference implementations into the package (SMC Lie terms and solve, aero, forces)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(smc, "smc_lie_terms", smc_lie_terms_reference)
        mp.setattr(smc, "guarded_solve", guarded_solve_reference)
        mp.setattr(eom, "coefficients", coefficients_reference)
        mp.setattr(eom, "forces_moments", forces_moments_reference)
        mp.setattr(lie, "derivatives", derivatives_reference)
        mp.setattr(aero, "lookup", lookup_reference)
        jax.clear_caches()  # jax caches traces per Python function: trace again with the references
        try:
            yield
        finally:
            jax.clear_caches()
