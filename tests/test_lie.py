"""Lie derivatives of y = [alpha, beta, mu] (autodiff) against finite differences of the controller model.

All quantities of one state come from a single jitted float64 function (one compile for the file).
"""

from __future__ import annotations

import functools

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from compile_options import FAST_COMPILE

from harv_jax.aircraft import harv
from harv_jax.control.lie import (
    Y_INDEX,
    controller_model,
    drift_and_input,
    output_lie_terms,
    roll_rate_lie_terms,
    wind_roll_rate_radps,
)
from harv_jax.dynamics.eom import derivatives

# Wind states [V, alpha, beta, p, q, r, mu, gamma, chi, h]. alpha values sit inside table segments
# (breakpoints every 4 deg from -14 deg), so central differences do not straddle a kink.
STATES = np.array(
    [
        [600.0, 0.10, 0.05, 0.2, -0.1, 0.05, 0.3, 0.1, 0.0, 25000.0],  # alpha 5.7 deg
        [350.0, 0.45, -0.15, -0.8, 0.3, 0.4, -2.0, -0.6, 1.0, 18000.0],  # alpha 25.8 deg
        [250.0, 1.00, 0.20, 1.0, -0.5, -0.3, 2.5, 1.2, -0.5, 30000.0],  # alpha 57.3, gamma 68.8 deg
        [1200.0, 0.30, 0.10, 1.5, 0.8, -0.4, 0.9, -0.9, 0.3, 22000.0],  # alpha 17.2 deg
    ]
)

U_TEST = np.array([-0.05, 0.1, -0.08])  # rad
FD_H = 1e-5  # central-difference step along a direction of state space
FD_H_TIME = 1e-4  # time step of the trajectory check, s


def _ydot(x, params):
    """y_dot of the controller model (u does not enter: relative degree >= 2)."""
    return controller_model(x, jnp.zeros(3), params)[jnp.array(Y_INDEX)]


@functools.partial(jax.jit, compiler_options=FAST_COMPILE)
def _checks(x, u, params):
    """Autodiff terms and their finite-difference counterparts at one state.

    The model evaluations are batched with vmap (and the RK4 stages scanned) to keep compile time low.
    """
    lt = output_lie_terms(x, params)
    f, g = drift_and_input(x, params)
    n = x.shape[0]

    def model(z, uu):
        return controller_model(z, uu, params)

    # g_j as the finite difference F(x, e_j) - F(x, 0) of the (control-affine) controller model
    u_batch = jnp.concatenate([jnp.zeros((1, 3)), jnp.eye(3)], axis=0)
    f_u = jax.vmap(model, in_axes=(None, 0))(x, u_batch)
    g_fd = (f_u[1:] - f_u[:1]).T  # [10, 3]
    # central differences of y_dot along f and along each g_j
    dirs = jnp.concatenate([f[None], g_fd.T], axis=0)  # [4, 10]
    pert = jnp.concatenate([x[None] + FD_H * dirs, x[None] - FD_H * dirs], axis=0)  # [8, 10]
    yd = jax.vmap(lambda z: _ydot(z, params))(pert)
    cd = (yd[:4] - yd[4:]) / (2 * FD_H)  # [4, 3]

    # y_ddot along a short RK4 trajectory of the controller model with u held (dt = +-h)
    def rk4(dt):
        def stage(k_prev, c):
            k = model(x + c * dt * k_prev, u)
            return k, k

        _, ks = jax.lax.scan(stage, jnp.zeros(n), jnp.array([0.0, 0.5, 0.5, 1.0]))
        return x + dt / 6 * (ks[0] + 2 * ks[1] + 2 * ks[2] + ks[3])

    traj_ends = jax.vmap(rk4)(jnp.array([FD_H_TIME, -FD_H_TIME]))
    yd_t = jax.vmap(lambda z: _ydot(z, params))(traj_ends)

    # wind-axis roll rate: docs/model.md form (p ca + r sa)/cb + tb q_w, mu_dot at gamma = 0, FD along f
    a, b = x[1], x[2]
    q_w = jnp.cos(b) * (x[4] - jnp.tan(b) * (x[3] * jnp.cos(a) + x[5] * jnp.sin(a)) - f[1])
    x_level = x.at[7].set(0.0)
    pw = jax.vmap(lambda z: wind_roll_rate_radps(z, params))(
        jnp.stack([x, x_level, x + FD_H * f, x - FD_H * f])
    )
    return {
        "lt": lt,
        "lf_y_model": f[jnp.array(Y_INDEX)],
        "lf2_fd": cd[0],
        "g": g,
        "g_fd": g_fd,
        "lglf_fd": cd[1:].T,
        "ydd": lt.lf2_y + lt.lglf_y @ u,
        "ydd_fd": (yd_t[0] - yd_t[1]) / (2 * FD_H_TIME),
        "g_plant": jax.jacfwd(derivatives, argnums=1)(x, jnp.zeros(3), params),
        "pw": pw[0],
        "pw_model": (x[3] * jnp.cos(a) + x[5] * jnp.sin(a)) / jnp.cos(b) + jnp.tan(b) * q_w,
        "pw_level": pw[1],
        "mu_dot_level": model(x_level, jnp.zeros(3))[6],
        "pw_lie": roll_rate_lie_terms(x, params),
        "pw_lf_fd": (pw[2] - pw[3]) / (2 * FD_H),
    }


@pytest.fixture
def checks(x64):
    params = harv(dtype=jnp.float64)
    return lambda i: jax.device_get(_checks(jnp.asarray(STATES[i]), jnp.asarray(U_TEST), params))


@pytest.mark.parametrize("i", range(len(STATES)))
def test_lie_terms_match_finite_differences(checks, i):
    c = checks(i)
    lt = c["lt"]
    chex.assert_shape((lt.y, lt.lf_y, lt.lf2_y, lt.lglf_y), ((3,), (3,), (3,), (3, 3)))
    chex.assert_tree_all_finite(lt)
    np.testing.assert_allclose(lt.lf_y, c["lf_y_model"], rtol=1e-12)  # L_f y is y_dot of the model
    np.testing.assert_allclose(lt.lf2_y, c["lf2_fd"], rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(c["g"], c["g_fd"], rtol=1e-10, atol=1e-12)  # jacfwd over u vs F(x,e_j)-F(x,0)
    np.testing.assert_allclose(lt.lglf_y, c["lglf_fd"], rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("i", range(len(STATES)))
def test_y_ddot_along_model_trajectory(checks, i):
    """y_ddot = L_f^2 y + L_g L_f y u, checked on short trajectories of the controller model."""
    c = checks(i)
    np.testing.assert_allclose(c["ydd"], c["ydd_fd"], rtol=1e-5, atol=1e-7)


def test_relative_degree_two(checks):
    """L_g y = 0 in the controller model, but not in the plant (control forces act on alpha, beta)."""
    c = checks(1)
    np.testing.assert_array_equal(c["g"][np.array(Y_INDEX)], 0.0)
    assert np.abs(c["g_plant"][1]).max() > 1e-4  # the plant's alpha_dot sees de through C_L,de
    assert np.linalg.cond(c["lt"].lglf_y) < 1e3  # invertible at an ordinary state


def test_wind_roll_rate(checks):
    """p_w equals docs/model.md's (p ca + r sa)/cb + tb q_w; equals mu_dot at gamma = 0; Lie terms vs FD."""
    c = checks(2)
    np.testing.assert_allclose(c["pw"], c["pw_model"], rtol=1e-12)
    np.testing.assert_allclose(c["pw_level"], c["mu_dot_level"], rtol=1e-10)
    np.testing.assert_allclose(c["pw_lie"].lf_h[0], c["pw_lf_fd"], rtol=1e-6)
    assert np.abs(c["pw_lie"].lg_h).max() > 1e-3  # the input enters p_w_dot directly (relative degree 1)
