"""Equations of motion of the F-18/HARV: the paper's wind-axis form and the body-axis form.

| symbol        | meaning                                   | unit        |
|---------------|-------------------------------------------|-------------|
| L, D, Y       | lift, drag, side force (wind axes)        | lbf         |
| Lroll, M, N   | rolling, pitching, yawing moment (body)   | ft lbf      |
| T             | thrust along body +x                      | lbf         |
| qbar          | dynamic pressure 0.5 rho V^2              | lbf/ft^2    |
| m, g          | mass, gravity                             | slug, ft/s^2|
| J             | inertia [[Ixx,0,-Ixz],[0,Iyy,0],[-Ixz,0,Izz]] | slug ft^2 |

Forms exactly as docs/model.md (the verified forms, not the paper's typeset equations):
wind-axis translational equations, body-axis rotational equations with the full Gamma = Ixx Izz -
Ixz^2 form. Reference: Stevens, Lewis & Johnson (2016), eqs. 2.5-x; docs/model.md,
"Typos in the paper's typeset equations".
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from harv_jax.aircraft.aero import coefficients
from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics.atmosphere import density_and_thrust_lapse
from harv_jax.dynamics.fusion import airflow_angles, evaluated_once
from harv_jax.dynamics.state import RATES, WIND_INDEX, BodyState, airflow_direction, check_shape

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
    alpha_in_range: bool = False,
) -> ForcesMoments:
    """Aerodynamic forces and moments plus thrust at one flight condition.

    ``alpha_in_range``: ``alpha_rad`` lies in [-pi, pi] (an ``arctan2``), so the table lookup skips the wrap.
    """
    rho, lapse = density_and_thrust_lapse(h_ft)
    qbar = 0.5 * rho * vt_fps * vt_fps
    thrust = params.throttle * params.T_max * lapse
    c = coefficients(
        alpha_rad,
        beta_rad,
        pqr_radps,
        jnp.maximum(vt_fps, V_FLOOR_FPS),
        u_rad,
        params,
        control_forces,
        alpha_in_range,
    )
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


def body_rate_derivatives(
    pqr_radps: jnp.ndarray,
    Lroll: jnp.ndarray,
    M: jnp.ndarray,
    N: jnp.ndarray,
    params: AircraftParams,
) -> jnp.ndarray:
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
    """Wind-axis state derivative x_dot [10] of the paper's model (docs/model.md forms).

    Args:
        x: [10] state [V, alpha, beta, p, q, r, mu, gamma, chi, h] (ft/s, rad, rad/s, ft).
        u: [3] deflections [de, da, dr], rad (used as given; limits are the actuator model's job).
        params: aircraft parameters (pytree; vmap it together with x and u).
        control_forces: False gives the SMC's controller model (no control-surface forces).

    Returns:
        [10] time derivative. Singular at V = 0, cos(beta) = 0, cos(gamma) = 0.

    Raises:
        ValueError: ``x`` is not [10] or ``u`` not [3].
    """
    check_shape(x, (10,), "state x [V, alpha, beta, p, q, r, mu, gamma, chi, h]")
    check_shape(u, (3,), "control u [de, da, dr]")
    vt, alpha, beta, mu, gamma, h = (x[WIND_INDEX[n]] for n in ("V", "alpha", "beta", "mu", "gamma", "h"))
    return wind_derivatives(vt, alpha, beta, x[RATES], mu, gamma, h, u, params, control_forces)


@jax.custom_jvp
def wind_trig(
    alpha: jnp.ndarray, beta: jnp.ndarray, mu: jnp.ndarray, gamma: jnp.ndarray
) -> tuple[jnp.ndarray, ...]:
    """(sin, cos) of alpha, beta, mu, gamma, in that order (8 values), each evaluated once.

    XLA's CPU fusion otherwise copies a sine or cosine into every fusion that reads it (the SMC's Lie
    terms evaluated ~130 sines and cosines per aircraft instead of 8): they are computed in a one-trip loop
    (`harv_jax.dynamics.fusion.evaluated_once`). The derivative rule reuses the values instead of
    creating new trigonometric ops.
    """
    angles = jnp.stack([alpha, beta, mu, gamma])
    sc = evaluated_once(lambda a: jnp.stack([jnp.sin(a), jnp.cos(a)], axis=-1), angles)
    return tuple(sc[k, j] for k in range(4) for j in range(2))


@wind_trig.defjvp
def _wind_trig_jvp(primals, tangents):
    values = wind_trig(*primals)
    d = []
    for k, dt in enumerate(tangents):
        s, c = values[2 * k], values[2 * k + 1]
        d += [c * dt, -s * dt]
    return values, tuple(d)


def wind_derivatives(
    vt: jnp.ndarray,
    alpha: jnp.ndarray,
    beta: jnp.ndarray,
    pqr: jnp.ndarray,
    mu: jnp.ndarray,
    gamma: jnp.ndarray,
    h: jnp.ndarray,
    u: jnp.ndarray,
    params: AircraftParams,
    control_forces: bool = True,
    trig: tuple[jnp.ndarray, ...] | None = None,
) -> jnp.ndarray:
    """``derivatives`` with the state passed by component (chi does not enter).

    V ft/s, alpha/beta/mu/gamma rad, pqr [3] rad/s, h ft. Separate arguments let forward-mode
    autodiff push a tangent through some components only (e.g. the body rates) without
    differentiating the rest of the model (``harv_jax.control.lie``).

    Args:
        trig: optional ``wind_trig(alpha, beta, mu, gamma)``, computed by the caller; pass it only
            where the angles are constants (a derivative pass in the rates or the controls), so that
            such passes share one evaluation of the sines and cosines.
    """
    p, q, r = pqr[0], pqr[1], pqr[2]
    fm = forces_moments(vt, alpha, beta, pqr, h, u, params, control_forces)
    m, g = params.mass_slug, params.g
    trig = wind_trig(alpha, beta, mu, gamma) if trig is None else trig
    sa, ca, sb, cb, smu, cmu, sg, cg = trig
    tb, tg = sb / cb, sg / cg  # (not jnp.tan: the sines and cosines are needed anyway)
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
        [v_dot, alpha_dot, beta_dot, pqr_dot[0], pqr_dot[1], pqr_dot[2], mu_dot, gamma_dot, chi_dot, h_dot]
    )


def body_derivatives(
    state: BodyState,
    u: jnp.ndarray,
    params: AircraftParams,
    wind_body_fps: jnp.ndarray | None = None,
    wind_pqr_radps: jnp.ndarray | None = None,
) -> BodyState:
    """Time derivative of the singularity-free integration state.

    Rigid-body equations in body axes: u_dot = F/m + C_bn g - omega x v, the Gamma-form rate
    equations, quaternion kinematics q_dot = q (x) [0, omega] / 2 and NED position kinematics.
    Written out component by component (no 3x3 matrices, trig-free direction cosines of alpha and
    beta): this is the simulator's hot path.

    Args:
        state: BodyState (uvw inertial velocity in body axes, rates, quaternion, position).
        u: [3] deflections [de, da, dr], rad.
        params: aircraft parameters.
        wind_body_fps: optional [3] wind velocity in body axes; aerodynamics see uvw - wind.
        wind_pqr_radps: optional [3] rotation rate of the air in body axes (turbulence); the aerodynamic
            damping sees pqr - wind_pqr, the rigid body pqr.

    Returns:
        BodyState of derivatives (the quaternion derivative is not renormalized).
    """
    uvw, pqr, quat = state.uvw_fps, state.pqr_radps, state.quat
    h = state.pos_ft[2]
    air = uvw if wind_body_fps is None else uvw - wind_body_fps
    ua, va, wa = air[0], air[1], air[2]
    uw, vt, ca, sa, cb, sb = airflow_direction(ua, va, wa)  # (cos, sin alpha; cos, sin beta)
    alpha, beta = airflow_angles(wa, ua, va, uw)  # arctan2 of both (vectorized on the CPU in float32)
    pqr_air = pqr if wind_pqr_radps is None else pqr - wind_pqr_radps
    fm = forces_moments(vt, alpha, beta, pqr_air, h, u, params, alpha_in_range=True)  # (an arctan2)
    m, g = params.mass_slug, params.g
    L, D, Y = fm.L, fm.D, fm.Y
    q0, q1, q2, q3 = quat[0], quat[1], quat[2], quat[3]
    # third row of C_nb (body -> NED): gravity direction in body axes and the sink rate
    c31, c32, c33 = 2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), 1 - 2 * (q1 * q1 + q2 * q2)
    p, q, r = pqr[0], pqr[1], pqr[2]
    ub, vb, wb = uvw[0], uvw[1], uvw[2]
    # aerodynamic force (-D, Y, -L) rotated wind -> body (C_wb^T), plus thrust along body x
    u_dot = (-D * ca * cb - Y * ca * sb + L * sa + fm.T) / m + g * c31 - (q * wb - r * vb)
    v_dot = (-D * sb + Y * cb) / m + g * c32 - (r * ub - p * wb)
    w_dot = (-D * sa * cb - Y * sa * sb - L * ca) / m + g * c33 - (p * vb - q * ub)
    quat_dot = 0.5 * jnp.stack(
        [
            -q1 * p - q2 * q - q3 * r,
            q0 * p + q2 * r - q3 * q,
            q0 * q - q1 * r + q3 * p,
            q0 * r + q1 * q - q2 * p,
        ]
    )
    x_n_dot = (1 - 2 * (q2 * q2 + q3 * q3)) * ub + 2 * (q1 * q2 - q0 * q3) * vb + 2 * (q1 * q3 + q0 * q2) * wb
    y_e_dot = 2 * (q1 * q2 + q0 * q3) * ub + (1 - 2 * (q1 * q1 + q3 * q3)) * vb + 2 * (q2 * q3 - q0 * q1) * wb
    h_dot = -(c31 * ub + c32 * vb + c33 * wb)
    return BodyState(
        uvw_fps=jnp.stack([u_dot, v_dot, w_dot]),
        pqr_radps=body_rate_derivatives(pqr, fm.Lroll, fm.M, fm.N, params),
        quat=quat_dot,
        pos_ft=jnp.stack([x_n_dot, y_e_dot, h_dot]),
    )
