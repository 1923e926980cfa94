"""Equations of motion of the F-18/HARV: the paper's wind-axis form and the body-axis form.

| symbol        | meaning                                   | unit        |
|---------------|-------------------------------------------|-------------|
| L, D, Y       | lift, drag, side force (wind axes)        | lbf         |
| Lroll, M, N   | rolling, pitching, yawing moment (body)   | ft lbf      |
| T             | thrust along body +x                      | lbf         |
| qbar          | dynamic pressure 0.5 rho V^2              | lbf/ft^2    |
| m, g          | mass, gravity                             | slug, ft/s^2|
| J             | inertia [[Ixx,0,-Ixz],[0,Iyy,0],[-Ixz,0,Izz]] | slug ft^2 |

Forms exactly as ``../shared/MODEL.md`` (the verified forms, not the paper's typeset equations):
wind-axis translational equations, body-axis rotational equations with the full Gamma = Ixx Izz -
Ixz^2 form. Reference: Stevens, Lewis & Johnson (2016), eqs. 2.5-x; MODEL.md "Typos".
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from harv_jax.aircraft.aero import coefficients
from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics.atmosphere import density_slugft3, thrust_lbf
from harv_jax.dynamics.state import BodyState, air_data, dcm_wind_from_body, quat_to_dcm

#: Airspeed floor for the non-dimensional rates p b / (2V) etc., ft/s (guards V -> 0 only).
V_FLOOR_FPS = 1.0


class ForcesMoments(NamedTuple):
    """Aerodynamic forces (wind axes), moments (body axes) and thrust."""

    L: jnp.ndarray
    D: jnp.ndarray
    Y: jnp.ndarray
    Lroll: jnp.ndarray
    M: jnp.ndarray
    N: jnp.ndarray
    T: jnp.ndarray


def forces_moments(
    vt_fps: jnp.ndarray,
    alpha_rad: jnp.ndarray,
    beta_rad: jnp.ndarray,
    pqr_radps: jnp.ndarray,
    h_ft: jnp.ndarray,
    u_rad: jnp.ndarray,
    params: AircraftParams,
    control_forces: bool = True,
) -> ForcesMoments:
    """Aerodynamic forces and moments plus thrust at one flight condition."""
    rho = density_slugft3(h_ft)
    qbar = 0.5 * rho * vt_fps * vt_fps
    c = coefficients(
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
        T=thrust_lbf(params.throttle, params.T_max, h_ft),
    )


def body_rate_derivatives(
    pqr_radps: jnp.ndarray, Lroll: jnp.ndarray, M: jnp.ndarray, N: jnp.ndarray,
    params: AircraftParams,
) -> jnp.ndarray:  # fmt: skip
    """[p_dot, q_dot, r_dot], rad/s^2: rigid body with x-z symmetry and product of inertia Ixz."""
    p, q, r = pqr_radps[0], pqr_radps[1], pqr_radps[2]
    Ixx, Iyy, Izz, Ixz = params.Ixx, params.Iyy, params.Izz, params.Ixz
    gam = Ixx * Izz - Ixz * Ixz
    p_dot = (
        Izz * Lroll + Ixz * N + Ixz * (Ixx - Iyy + Izz) * p * q - (Izz * (Izz - Iyy) + Ixz**2) * q * r
    ) / gam
    q_dot = (M + (Izz - Ixx) * p * r - Ixz * (p * p - r * r)) / Iyy
    r_dot = (
        Ixz * Lroll + Ixx * N + (Ixx * (Ixx - Iyy) + Ixz**2) * p * q - Ixz * (Ixx - Iyy + Izz) * q * r
    ) / gam
    return jnp.stack([p_dot, q_dot, r_dot])


def derivatives(
    x: jnp.ndarray, u: jnp.ndarray, params: AircraftParams, control_forces: bool = True
) -> jnp.ndarray:
    """Wind-axis state derivative x_dot [10] of the paper's model (MODEL.md verified forms).

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
    fm = forces_moments(vt, alpha, beta, pqr, h, u, params, control_forces)
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


def body_derivatives(
    state: BodyState,
    u: jnp.ndarray,
    params: AircraftParams,
    wind_body_fps: jnp.ndarray | None = None,
) -> BodyState:
    """Time derivative of the singularity-free integration state.

    Args:
        state: BodyState (uvw inertial velocity in body axes, rates, quaternion, position).
        u: [3] deflections [de, da, dr], rad.
        params: aircraft parameters.
        wind_body_fps: optional [3] wind velocity in body axes; aerodynamics see uvw - wind.

    Returns:
        BodyState of derivatives (the quaternion derivative is not renormalized).
    """
    uvw, pqr, quat = state.uvw_fps, state.pqr_radps, state.quat
    h = state.pos_ft[2]
    air = uvw if wind_body_fps is None else uvw - wind_body_fps
    vt, alpha, beta = air_data(air)
    fm = forces_moments(vt, alpha, beta, pqr, h, u, params)
    c_wb = dcm_wind_from_body(alpha, beta)
    f_aero_body = c_wb.T @ jnp.stack([-fm.D, fm.Y, -fm.L])
    c_nb = quat_to_dcm(quat)
    gravity_body = c_nb.T @ jnp.stack([0.0 * h, 0.0 * h, params.g])
    thrust_body = jnp.stack([fm.T, 0.0 * h, 0.0 * h])
    uvw_dot = (f_aero_body + thrust_body) / params.mass_slug + gravity_body - jnp.cross(pqr, uvw)
    p, q, r = pqr[0], pqr[1], pqr[2]
    q0, q1, q2, q3 = quat[0], quat[1], quat[2], quat[3]
    quat_dot = 0.5 * jnp.stack(
        [
            -q1 * p - q2 * q - q3 * r,
            q0 * p + q2 * r - q3 * q,
            q0 * q - q1 * r + q3 * p,
            q0 * r + q1 * q - q2 * p,
        ]
    )
    v_ned = c_nb @ uvw
    pos_dot = jnp.stack([v_ned[0], v_ned[1], -v_ned[2]])
    return BodyState(
        uvw_fps=uvw_dot,
        pqr_radps=body_rate_derivatives(pqr, fm.Lroll, fm.M, fm.N, params),
        quat=quat_dot,
        pos_ft=pos_dot,
    )
