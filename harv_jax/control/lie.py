"""Lie derivatives of controlled outputs, by JAX autodiff of the SMC's controller model.

The controller model is the flight model with the control-surface *force* terms dropped
(``derivatives(..., control_forces=False)``, docs/model.md "The controller's model"): it is control
affine, x_dot = f(x) + g(x) u, with f(x) = F(x, 0) and g(x) = dF/du (exact: F is linear in u),
and the deflections enter only the moment equations, so y = [alpha, beta, mu] has relative degree
2 per channel (L_g y = 0). Everything below is forward-mode autodiff (``jax.linearize``/``jvp``,
``jacfwd``) of that model; there are no hand-derived Jacobians.

    L_f h      = dh/dx f(x)
    L_f^2 h    = d(L_f h)/dx f(x)
    L_g L_f h  = d(L_f h)/dx g(x)          [n_out, 3]

Shapes: x is the wind-axis state [10] (see ``harv_jax.dynamics.state``), u is [3] rad.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics.eom import derivatives, wind_derivatives, wind_trig
from harv_jax.dynamics.state import (
    TRACKED_INDEX,
    WIND_INDEX,
    alpha_rad,
    beta_rad,
    gamma_rad,
    h_ft,
    mu_rad,
    omega_radps,
    vt_fps,
)

#: Indices of the controlled outputs y = [alpha, beta, mu] in the wind-axis state.
Y_INDEX = TRACKED_INDEX

OutputFn = Callable[[jnp.ndarray], jnp.ndarray]


class LieTerms2(NamedTuple):
    """Terms of an output of relative degree 2: y_ddot = lf2_y + lglf_y @ u (controller model).

    Attributes:
        y: [n] output values.
        lf_y: [n] L_f y (= y_dot, which does not depend on u).
        lf2_y: [n] L_f^2 y.
        lglf_y: [n, 3] L_g L_f y (the decoupling matrix for n = 3).
    """

    y: jnp.ndarray
    lf_y: jnp.ndarray
    lf2_y: jnp.ndarray
    lglf_y: jnp.ndarray


class LieTerms1(NamedTuple):
    """Terms of an output of relative degree 1: h_dot = lf_h + lg_h @ u (controller model).

    Attributes:
        h: [n] output values.
        lf_h: [n] L_f h.
        lg_h: [n, 3] L_g h.
    """

    h: jnp.ndarray
    lf_h: jnp.ndarray
    lg_h: jnp.ndarray


def controller_model(x: jnp.ndarray, u_rad: jnp.ndarray, params: AircraftParams) -> jnp.ndarray:
    """x_dot [10] of the controller model (no control-surface forces; moments keep the controls)."""
    return derivatives(x, u_rad, params, control_forces=False)


def drift_and_input(x: jnp.ndarray, params: AircraftParams) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Drift f(x) [10] and input matrix g(x) [10, 3] of the control-affine controller model."""
    u0 = jnp.zeros((3,), dtype=x.dtype)
    f = controller_model(x, u0, params)
    g = jax.jacfwd(controller_model, argnums=1)(x, u0, params)
    return f, g


def output_y(x: jnp.ndarray) -> jnp.ndarray:
    """y = [alpha, beta, mu] [3], rad."""
    return jnp.stack([x[i] for i in Y_INDEX])


def lie_derivatives_rd1(output_fn: OutputFn, x: jnp.ndarray, params: AircraftParams) -> LieTerms1:
    """L_f h and L_g h of an output h(x) [n] of the controller model.

    Args:
        output_fn: h, a differentiable function of the wind state [10] -> [n].
        x: wind-axis state [10].
        params: aircraft parameters of the controller model.
    """
    f, g = drift_and_input(x, params)
    h, lin = jax.linearize(output_fn, x)
    return LieTerms1(h=h, lf_h=lin(f), lg_h=jax.vmap(lin, in_axes=1, out_axes=1)(g))


def lie_derivatives_rd2(output_fn: OutputFn, x: jnp.ndarray, params: AircraftParams) -> LieTerms2:
    """L_f h, L_f^2 h and L_g L_f h of an output h(x) [n] of the controller model.

    The caller asserts relative degree >= 2 (L_g h = 0); for y = [alpha, beta, mu] this holds by
    construction of the controller model (tested).

    Args:
        output_fn: h, a differentiable function of the wind state [10] -> [n].
        x: wind-axis state [10].
        params: aircraft parameters of the controller model.
    """
    u0 = jnp.zeros((3,), dtype=x.dtype)

    def lf(xx: jnp.ndarray) -> jnp.ndarray:
        return jax.jvp(output_fn, (xx,), (controller_model(xx, u0, params),))[1]

    f, g = drift_and_input(x, params)
    lf_val, lin = jax.linearize(lf, x)
    return LieTerms2(
        y=output_fn(x),
        lf_y=lf_val,
        lf2_y=lin(f),
        lglf_y=jax.vmap(lin, in_axes=1, out_axes=1)(g),
    )


def output_lie_terms(x: jnp.ndarray, params: AircraftParams) -> LieTerms2:
    """Lie terms of the SMC outputs y = [alpha, beta, mu] (y_ddot = lf2_y + lglf_y u)."""
    return lie_derivatives_rd2(output_y, x, params)


def wind_roll_rate_radps(x: jnp.ndarray, params: AircraftParams) -> jnp.ndarray:
    """Wind-axis roll rate p_w, rad/s (x-component of the wind frame's inertial angular velocity).

    p_w = cos(beta) (p cos(alpha) + r sin(alpha)) + sin(beta) (q - alpha_dot), with alpha_dot of the
    controller model; equal to docs/model.md's (p ca + r sa)/cb + tb q_w but free of 1/cos(beta). Unlike
    mu_dot = p_w + tan(gamma) (q_w smu + r_w cmu) it stays defined at gamma = +-90 deg.
    """
    alpha, beta = alpha_rad(x), beta_rad(x)
    p, q, r = (x[WIND_INDEX[n]] for n in ("p", "q", "r"))
    u0 = jnp.zeros((3,), dtype=x.dtype)
    alpha_dot = controller_model(x, u0, params)[1]
    return jnp.cos(beta) * (p * jnp.cos(alpha) + r * jnp.sin(alpha)) + jnp.sin(beta) * (q - alpha_dot)


def roll_rate_lie_terms(x: jnp.ndarray, params: AircraftParams) -> LieTerms1:
    """Lie terms of the wind-axis roll rate p_w (relative degree 1): p_w_dot = lf_h + lg_h u."""
    return lie_derivatives_rd1(lambda xx: wind_roll_rate_radps(xx, params)[None], x, params)


def _z_parts(
    vt: jnp.ndarray,
    alpha: jnp.ndarray,
    beta: jnp.ndarray,
    pqr: jnp.ndarray,
    mu: jnp.ndarray,
    gamma: jnp.ndarray,
    h: jnp.ndarray,
    u: jnp.ndarray,
    params: AircraftParams,
    trig: tuple[jnp.ndarray, ...] | None = None,
) -> jnp.ndarray:
    """Z = [F(x, u) (10), p_w(x) (1)] of the controller model, the state passed by component.

    ``trig``: ``wind_trig`` of the angles where they are constants of a derivative pass (else None).
    """
    trig = wind_trig(alpha, beta, mu, gamma) if trig is None else trig
    xd = wind_derivatives(vt, alpha, beta, pqr, mu, gamma, h, u, params, False, trig)
    p, q, r = pqr[0], pqr[1], pqr[2]
    sa, ca, sb, cb = trig[:4]
    p_w = cb * (p * ca + r * sa) + sb * (q - xd[1])
    return jnp.concatenate([xd, p_w[None]])


def smc_lie_terms(x: jnp.ndarray, params: AircraftParams) -> tuple[LieTerms2, LieTerms1]:
    """``output_lie_terms`` and ``roll_rate_lie_terms`` from one model evaluation and cheap tangents.

    With Z(x, u) = [F(x, u) (10), p_w(x) (1)] and f = F(x, 0): L_f y = f[Y_INDEX], L_f^2 y =
    dZ/dx f [Y_INDEX], L_g L_f y = dZ/dx g [Y_INDEX], L_f p_w = dZ/dx f [10], L_g p_w = dZ/dx g [10].
    The structure of the controller model keeps the passes small:

    - g = dF/du (F is affine in u) is a forward-mode pass in u only: the deflections enter only the
      moments, so g is zero outside the body-rate rows 3..5 (the controller model has no control
      forces: relative degree 2) and this pass touches only the moment equations.
    - dZ/dx g therefore needs the tangent of Z in the body rates p, q, r only (3 directions), which
      leaves the table lookup, the atmosphere and the trigonometry of alpha, beta, mu, gamma out.
    - one full tangent along f gives L_f^2 y and L_f p_w.

    The primal (table lookup included) is shared by the passes. Same values as ``output_lie_terms``
    and ``roll_rate_lie_terms`` to float rounding (tested); chi does not enter the model.

    Returns:
        (LieTerms2 of y = [alpha, beta, mu], LieTerms1 of p_w).
    """
    u0 = jnp.zeros((3,), dtype=x.dtype)
    idx = jnp.array(Y_INDEX)
    vt, alpha, beta, pqr = vt_fps(x), alpha_rad(x), beta_rad(x), omega_radps(x)
    mu, gamma, h = mu_rad(x), gamma_rad(x), h_ft(x)

    def z_state(vt_, alpha_, beta_, pqr_, mu_, gamma_, h_):
        return _z_parts(vt_, alpha_, beta_, pqr_, mu_, gamma_, h_, u0, params)

    primals = (vt, alpha, beta, pqr, mu, gamma, h)
    trig = wind_trig(alpha, beta, mu, gamma)  # shared by the primal and the passes in u and in p, q, r
    z_val = _z_parts(*primals, u0, params, trig)
    f = z_val[:10]
    # L_f: one tangent through the whole model along f (chi, f[8], does not enter)
    _, dz_f = jax.jvp(z_state, primals, (f[0], f[1], f[2], f[3:6], f[6], f[7], f[9]))

    # g: the input columns, a tangent in u only (nonzero rows: p_dot, q_dot, r_dot)
    def z_u(uu: jnp.ndarray) -> jnp.ndarray:
        return _z_parts(vt, alpha, beta, pqr, mu, gamma, h, uu, params, trig)

    eye = jnp.eye(3, dtype=x.dtype)
    g_pqr = jax.vmap(lambda du: jax.jvp(z_u, (u0,), (du,))[1][3:6])(eye)  # [3 (u_j), 3 (pqr)] = g^T

    # L_g: tangents in the body rates only, along each g_j
    def z_pqr(pqr_: jnp.ndarray) -> jnp.ndarray:
        return _z_parts(vt, alpha, beta, pqr_, mu, gamma, h, u0, params, trig)

    dz_g = jax.vmap(lambda dp: jax.jvp(z_pqr, (pqr,), (dp,))[1])(g_pqr)  # [3, 11]
    y_terms = LieTerms2(y=output_y(x), lf_y=f[idx], lf2_y=dz_f[idx], lglf_y=dz_g[:, idx].T)
    pw_terms = LieTerms1(h=z_val[10:], lf_h=dz_f[10:], lg_h=dz_g[:, 10:].T)
    return y_terms, pw_terms
