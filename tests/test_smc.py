"""Sliding-mode controller: reaching law (and the paper's sign typo), guard, anti-windup, vmap == loop."""

from __future__ import annotations

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from compile_options import FAST_COMPILE

from harv_jax.aircraft import harv
from harv_jax.control import SMCConfig, default_gains, guarded_solve, make_smc, output_lie_terms
from harv_jax.control.lie import smc_lie_terms
from harv_jax.units import RAD_PER_DEG

REF = jnp.array([0.349, 0.0, 0.0])
KEY = jax.random.key(0)
#: An ordinary state: V 500 ft/s, alpha 0.3, beta 0.05, p, q, r, mu 0.4, gamma 0.1, h 20,000 ft.
X_ORD = jnp.array([500.0, 0.30, 0.05, 0.1, -0.05, 0.02, 0.4, 0.1, 0.0, 20000.0])


@chex.assert_max_traces(n=1)
def _apply_plus(gains, state, x, ref):
    """One SMC step plus the controller-model Lie terms at x (one compile for the whole file)."""
    u, new_state, info = make_smc(SMCConfig(), gains).apply(state, x, ref, KEY)
    return u, new_state, info, (output_lie_terms(x, state.params), smc_lie_terms(x, state.params)[0])


_apply_jit = jax.jit(_apply_plus, compiler_options=FAST_COMPILE)


def _nominal():
    """harv() with strongly typed leaves (its scalars are weakly typed; mixing the two retraces)."""
    return jax.tree.map(lambda a: jnp.asarray(a, jnp.float32), harv())


def _init(params=None):
    return make_smc().init(_nominal() if params is None else params)


class GuardedSolveTest(chex.TestCase):
    @chex.variants(with_jit=True, without_jit=True)
    def test_well_conditioned_equals_solve(self):
        a = jnp.array([[2.0, 0.3, 0.0], [0.1, -1.5, 0.2], [0.0, 0.4, 0.8]])
        b = jnp.array([0.3, -0.2, 0.5])
        u, info = self.variant(guarded_solve)(a, b, jnp.asarray(1e3), jnp.asarray(1e-4))
        np.testing.assert_allclose(u, np.linalg.solve(np.asarray(a), np.asarray(b)), rtol=1e-5)
        assert not bool(info.guard_active)

    @chex.variants(with_jit=True, without_jit=True)
    def test_singular_and_nonfinite_give_finite_bounded_commands(self):
        b = jnp.array([1.0, -2.0, 0.5])
        solve = self.variant(guarded_solve)
        rank2 = jnp.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 0.0, 1.0]])
        for a in (
            rank2,
            jnp.zeros((3, 3)),
            rank2.at[0, 2].set(jnp.nan),
            rank2.at[1, 2].set(jnp.inf),
        ):  # non-finite -> 0
            u, info = solve(a, b, jnp.asarray(1e3), jnp.asarray(1e-4))
            chex.assert_tree_all_finite((u, info.rho2))
            assert bool(info.guard_active)
            # damped least squares: |u| <= |b| / (2 rho) with rho >= s_th; here s_th >= 1e-4
            assert float(jnp.linalg.norm(u)) <= float(jnp.linalg.norm(b)) / (2 * 1e-4 / 1e3) + 1e-3
        u0, _ = solve(jnp.zeros((3, 3)), b, jnp.asarray(1e3), jnp.asarray(1e-4))
        np.testing.assert_array_equal(u0, 0.0)

    def test_damping_is_continuous_at_threshold(self):
        # diag(1, 1, s) with cond_max = 100: damping starts at s = 0.01
        b = jnp.array([0.0, 0.0, 1.0])
        us = [
            guarded_solve(jnp.diag(jnp.array([1.0, 1.0, s])), b, jnp.asarray(100.0), jnp.asarray(1e-6))[0][2]
            for s in (0.0100001, 0.0099999)
        ]
        np.testing.assert_allclose(us[0], us[1], rtol=1e-3)


def test_reaching_law_and_paper_sign_typo():
    """On the controller model the law gives s_dot = -(K |s|^1/2 + eps) sat(s/phi) exactly.

    s_dot = y_ddot + l1 e_dot + l2 e with y_ddot = L_f^2 y + L_g L_f y u. The paper's printed
    u_r (+ l2 e) would instead give s_dot = reaching law + 2 l2 e.
    """
    g = default_gains()
    state = _init().replace(integral_rad_s=jnp.array([0.02, -0.01, 0.03]))
    u, _, info, (lt, lt_smc) = jax.device_get(_apply_jit(g, state, X_ORD, REF))
    chex.assert_trees_all_close(lt_smc, lt, rtol=1e-5, atol=1e-6)  # the law's fused Lie terms
    assert float(info["w_mu"]) == 1.0 and not bool(info["guard_active"])
    u_raw = info["u_unsat_rad"]
    e, e_dot, s = info["e"], info["e_dot"], info["s"]
    np.testing.assert_allclose(s, e_dot + g.lambda1_ps * e + g.lambda2_ps2 * state.integral_rad_s, rtol=1e-6)
    y_ddot = lt.lf2_y + lt.lglf_y @ u_raw
    s_dot = y_ddot + g.lambda1_ps * e_dot + g.lambda2_ps2 * e
    reach = -(g.k_reach * np.sqrt(np.abs(s)) + g.eps_radps2) * np.clip(s / g.phi_radps, -1, 1)
    np.testing.assert_allclose(s_dot, reach, rtol=1e-3, atol=1e-4)
    assert np.all(s * s_dot < 0)
    # with the typeset +l2 e the reaching law would be off by 2 l2 e (not small here)
    assert np.max(np.abs(2 * g.lambda2_ps2 * e)) > 100 * 1e-4
    np.testing.assert_allclose(u, np.clip(u_raw, harv().u_min_rad, harv().u_max_rad))


@pytest.mark.parametrize(
    "x",
    [
        X_ORD.at[0].set(1e-3),  # V -> 0
        X_ORD.at[0].set(0.0),  # V = 0
        X_ORD.at[2].set(np.pi / 2 - 1e-5),  # beta -> 90 deg
        X_ORD.at[2].set(-np.pi / 2),  # beta = -90 deg
        X_ORD.at[7].set(np.pi / 2),  # gamma = 90 deg
        X_ORD.at[7].set(-np.pi / 2 + 1e-6),  # gamma -> -90 deg
        X_ORD.at[1].set(np.pi),  # alpha = 180 deg (tail first)
    ],
    ids=["V1e-3", "V0", "beta90-", "beta-90", "gamma90", "gamma-90+", "alpha180"],
)
def test_finite_controls_near_singular_states(x):
    u, new_state, info, _ = jax.device_get(_apply_jit(default_gains(), _init(), x, REF))
    chex.assert_tree_all_finite((u, new_state.integral_rad_s, info["u_unsat_rad"]))
    assert np.all(u >= harv().u_min_rad - 1e-7) and np.all(u <= harv().u_max_rad + 1e-7)


def test_guard_engages_at_vanishing_airspeed_and_mu_blend_near_vertical():
    g = default_gains()
    _, _, info_v, _ = jax.device_get(_apply_jit(g, _init(), X_ORD.at[0].set(1e-3), REF))
    assert bool(info_v["guard_active"])  # all singular values below sigma_floor (qbar ~ 0)
    _, _, info_g, _ = jax.device_get(_apply_jit(g, _init(), X_ORD.at[7].set(np.pi / 2), REF))
    assert float(info_g["w_mu"]) == 0.0  # mu row replaced by wind roll-rate damping ...
    assert not bool(info_g["guard_active"])  # ... which keeps the system well conditioned
    _, _, info_0, _ = jax.device_get(_apply_jit(g, _init(), X_ORD, REF))
    assert float(info_0["w_mu"]) == 1.0 and not bool(info_0["guard_active"])


def test_integral_reset_on_reference_step_and_anti_windup():
    g = default_gains()
    dt = SMCConfig().dt_s
    i0 = jnp.array([0.05, -0.02, 0.01])
    # near the reference: small errors (inside the integration band), no saturation
    x_near = (
        X_ORD.at[1].set(0.349 + 1.0 * RAD_PER_DEG).at[2].set(0.5 * RAD_PER_DEG).at[6].set(1.0 * RAD_PER_DEG)
    )
    x_near = x_near.at[3:6].set(0.0)
    st = _init().replace(integral_rad_s=i0, reference_prev_rad=REF, has_reference=jnp.asarray(True))
    _, new, info, _ = jax.device_get(_apply_jit(g, st, x_near, REF))
    assert not bool(info["saturated"])
    np.testing.assert_allclose(new.integral_rad_s, i0 + dt * info["e"], rtol=1e-5)  # integrates
    ref2 = REF.at[0].set(0.349 + 0.5 * RAD_PER_DEG)  # a reference step: the integral restarts from 0
    _, new2, info2, _ = jax.device_get(_apply_jit(g, st, x_near, ref2))
    np.testing.assert_allclose(new2.integral_rad_s, dt * info2["e"], rtol=1e-5)
    # far from the reference with large rates: saturated and outside the band -> frozen
    x_far = X_ORD.at[1].set(1.0).at[3].set(2.0)
    _, new3, info3, _ = jax.device_get(_apply_jit(g, st, x_far, REF))
    assert bool(info3["saturated"])
    np.testing.assert_allclose(new3.integral_rad_s, i0)


def test_gain_sweep_does_not_retrace():
    st = _init()
    g = default_gains()
    for scale in (0.5, 2.0):
        g2 = g.replace(k_reach=g.k_reach * scale, lambda1_ps=g.lambda1_ps * scale)
        u, _, _, _ = _apply_jit(g2, st, X_ORD, REF)  # assert_max_traces(n=1) raises on a retrace
        chex.assert_tree_all_finite(u)


def test_vmapped_smc_over_64_aircraft_equals_loop():
    n = 64
    k_a, k_m, k_x, k_r = jax.random.split(jax.random.key(42), 4)
    nominal = _nominal()
    params = jax.tree.map(lambda a: jnp.broadcast_to(a, (n, *jnp.shape(a))), nominal)
    params = params.replace(
        aero_scale=jax.random.uniform(k_a, (n, nominal.aero_scale.shape[0]), minval=0.8, maxval=1.2),
        mass_slug=params.mass_slug * jax.random.uniform(k_m, (n,), minval=0.9, maxval=1.1),
    )
    lo = jnp.array([200.0, -0.1, -0.2, -1.0, -0.5, -0.3, -3.0, -1.0, 0.0, 15000.0])
    hi = jnp.array([1200.0, 1.0, 0.2, 1.0, 0.5, 0.3, 3.0, 1.0, 0.0, 30000.0])
    xs = lo[None] + jax.random.uniform(k_x, (n, 10)) * (hi - lo)[None]
    refs = jnp.stack(
        [jax.random.uniform(k_r, (n,), minval=-0.085, maxval=0.68), jnp.zeros(n), jnp.zeros(n)], 1
    )
    ctrl = make_smc()
    states = jax.vmap(ctrl.init)(params)
    states = states.replace(integral_rad_s=jnp.tile(jnp.array([[0.01, -0.02, 0.005]]), (n, 1)))
    u_v, st_v, info_v = jax.jit(jax.vmap(ctrl.apply, in_axes=(0, 0, 0, None)), compiler_options=FAST_COMPILE)(
        states, xs, refs, KEY
    )
    chex.assert_shape(u_v, (n, 3))
    chex.assert_tree_all_finite((u_v, st_v.integral_rad_s))
    g = default_gains()
    states_np, xs_np, refs_np = jax.device_get((states, xs, refs))
    for i in range(n):
        st_i = jax.tree.map(lambda a, i=i: a[i], states_np)
        u_i, new_i, info_i, _ = _apply_jit(g, st_i, xs_np[i], refs_np[i])
        chex.assert_trees_all_close(
            (u_i, new_i.integral_rad_s, info_i["s"]),
            (u_v[i], st_v.integral_rad_s[i], info_v["s"][i]),
            rtol=1e-4,
            atol=1e-5,
        )
    assert float(jnp.std(u_v[:, 0])) > 1e-3  # the 64 aircraft/states really differ
