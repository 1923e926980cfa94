"""Aerodynamic table lookup, coefficient build-up, atmosphere, thrust and nominal parameters.

References are computed independently with numpy from the CSV (``oracle_body_axis``), not from
``harv_jax.aircraft.data_harv``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import oracle_body_axis as oracle  # noqa: E402

from harv_jax.aircraft import harv  # noqa: E402
from harv_jax.aircraft.aero import coefficients, lookup  # noqa: E402
from harv_jax.aircraft.params import U_MAX_RAD, U_MIN_RAD, U_RATE_MAX_RADPS  # noqa: E402
from harv_jax.dynamics.atmosphere import density_slugft3, thrust_lbf  # noqa: E402

RAD = np.pi / 180.0
#: Per-radian table [27, 33] from the CSV: every column except cd0, clift0, cm0 times 180/pi.
PER_RAD = oracle.TABLE_RAW * np.array(
    [1.0 if c in ("cd0", "clift0", "cm0") else 180.0 / np.pi for c in oracle.COLUMNS]
)
GRID_DEG = oracle.ALPHA_GRID_DEG


def reference_row(alpha_rad: float) -> np.ndarray:
    """np.interp on the CSV (wrap to (-pi, pi], clamp to [-14, 90] deg), per radian."""
    a = np.degrees(np.arctan2(np.sin(alpha_rad), np.cos(alpha_rad)))
    a = np.clip(a, -14.0, 90.0)
    return np.array([np.interp(a, GRID_DEG, PER_RAD[:, j]) for j in range(PER_RAD.shape[1])])


N_PAD = 320  # every lookup batch is padded to this length: one shape, so eager mode compiles each op once


class LookupTest(chex.TestCase):
    """Table lookup properties, with and without jit, in float64."""

    def setUp(self):
        super().setUp()
        self._x64 = jax.enable_x64(True)
        self._x64.__enter__()

    def lookup_batch(self, alpha_rad) -> np.ndarray:
        """self.variant(vmap(lookup)) on [n <= N_PAD] angles, rad -> [n, 33]."""
        a = np.asarray(alpha_rad, dtype=np.float64)
        padded = np.zeros(N_PAD)
        padded[: len(a)] = a
        return np.asarray(self.variant(jax.vmap(lookup))(jnp.asarray(padded)))[: len(a)]

    def tearDown(self):
        self._x64.__exit__(None, None, None)
        super().tearDown()

    @chex.variants(with_jit=True, without_jit=True)
    def test_exact_at_breakpoints(self):
        got = self.lookup_batch(GRID_DEG * RAD)
        chex.assert_shape(got, PER_RAD.shape)
        np.testing.assert_allclose(got, PER_RAD, rtol=1e-12, atol=1e-15)

    @chex.variants(with_jit=True, without_jit=True)
    def test_linear_between_breakpoints(self):
        rng = np.random.default_rng(0)
        a = rng.uniform(-14.0, 90.0, 300) * RAD
        got = self.lookup_batch(a)
        ref = np.stack([reference_row(ai) for ai in a])
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-14)
        # three equally spaced points inside one 4-deg segment: zero second difference
        lo = GRID_DEG[:-1, None]
        r = self.lookup_batch((lo + np.array([[0.5, 2.0, 3.5]])).ravel() * RAD).reshape(len(lo), 3, 33)
        np.testing.assert_allclose(r[:, 0] + r[:, 2], 2.0 * r[:, 1], rtol=1e-12, atol=1e-14)

    @chex.variants(with_jit=True, without_jit=True)
    def test_clamped_outside_the_table_and_alpha_wrapped(self):
        f = self.variant(jax.vmap(lookup))
        below = np.array([-14.0, -20.0, -45.0, -90.0, -135.0, -179.9]) * RAD
        above = np.array([90.0, 95.0, 120.0, 150.0, 179.9, 180.0]) * RAD
        np.testing.assert_allclose(np.asarray(f(jnp.asarray(below))), np.tile(PER_RAD[0], (6, 1)), rtol=1e-12)
        np.testing.assert_allclose(
            np.asarray(f(jnp.asarray(above))), np.tile(PER_RAD[-1], (6, 1)), rtol=1e-12
        )
        # wrapping: alpha and alpha +- 2 pi k look up the same row
        a = np.array([-10.0, 5.0, 33.3, 61.0, 89.0]) * RAD
        base = np.asarray(f(jnp.asarray(a)))
        for k in (-2, -1, 1, 2):
            shifted = np.asarray(f(jnp.asarray(a + 2 * np.pi * k)))
            np.testing.assert_allclose(shifted, base, rtol=1e-9, atol=1e-12)
        # 200 deg wraps to -160 deg (clamped to the -14 deg row), -200 deg to +160 deg (the 90 deg row)
        np.testing.assert_allclose(np.asarray(f(jnp.asarray([200.0 * RAD]))[0]), PER_RAD[0], rtol=1e-12)
        np.testing.assert_allclose(np.asarray(f(jnp.asarray([-200.0 * RAD]))[0]), PER_RAD[-1], rtol=1e-12)

    def test_aero_scale_multiplies_columns(self):
        scale = np.linspace(0.5, 1.5, 33)
        a = 23.7 * RAD
        got = np.asarray(jax.jit(lookup)(jnp.asarray(a), jnp.asarray(scale)))
        np.testing.assert_allclose(got, reference_row(a) * scale, rtol=1e-12)


def test_lookup_gradient_matches_finite_differences(x64):
    """d lookup / d alpha: finite, equal to the segment slope (central differences away from breakpoints)."""
    w = np.random.default_rng(1).normal(size=33)
    f = jax.jit(lambda a: jnp.dot(lookup(a), jnp.asarray(w)))
    grad = jax.jit(jax.vmap(jax.grad(lambda a: jnp.dot(lookup(a), jnp.asarray(w)))))
    rng = np.random.default_rng(2)
    a_deg = rng.uniform(-13.9, 89.9, 200)
    a_deg = a_deg[np.min(np.abs(a_deg[:, None] - GRID_DEG[None, :]), axis=1) > 0.05]
    a = a_deg * RAD
    g = np.asarray(grad(jnp.asarray(a)))
    assert np.all(np.isfinite(g))
    h = 1e-6
    fd = np.array([(float(f(ai + h)) - float(f(ai - h))) / (2 * h) for ai in a[:40]])
    np.testing.assert_allclose(g[:40], fd, rtol=1e-6, atol=1e-8)
    # exactly the slope of the segment, (row[k+1] - row[k]) / 4 deg
    k = np.floor((a_deg + 14.0) / 4.0).astype(int)
    slope = (PER_RAD[k + 1] - PER_RAD[k]) @ w / (4.0 * RAD)
    np.testing.assert_allclose(g, slope, rtol=1e-10, atol=1e-10)
    # clamped region: zero gradient, finite (also at the wrap)
    g_out = np.asarray(grad(jnp.asarray(np.array([-30.0, 120.0, 179.0, -179.0, 200.0]) * RAD)))
    np.testing.assert_array_equal(g_out, 0.0)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_lookup_in_range_equals_the_wrapped_lookup(dtype):
    """``in_range=True`` (no wrap, for an arctan2's alpha) gives the wrapped lookup's row and slope on
    [-pi, pi], -pi included (the wrap maps it to +pi: the 90-deg end of the table, not the -14-deg one)."""
    with jax.enable_x64(dtype == np.float64):
        rng = np.random.default_rng(3)
        a = np.concatenate([
            GRID_DEG * RAD, rng.uniform(-np.pi, np.pi, 200), [-np.pi, np.pi, -np.pi / 2, 3.0, -3.0, 0.0],
            np.arctan2(np.array([-0.0, 0.0, -1e-30]), -1.0),
        ]).astype(dtype)  # fmt: skip
        scale = jnp.asarray(rng.uniform(0.9, 1.1, 33), dtype)
        wrapped = jax.jit(jax.vmap(lambda x: lookup(x, scale)))(jnp.asarray(a))
        direct = jax.jit(jax.vmap(lambda x: lookup(x, scale, in_range=True)))(jnp.asarray(a))
        tol = 1e-12 if dtype == np.float64 else 2e-5
        np.testing.assert_allclose(direct, wrapped, rtol=tol, atol=tol * np.max(np.abs(PER_RAD)))
        at_minus_pi = direct[len(GRID_DEG) + 200]
        np.testing.assert_allclose(at_minus_pi, PER_RAD[-1] * np.asarray(scale), rtol=tol)  # the 90-deg row
        # slopes away from the breakpoints (at a kink a 1-ulp rounding of the wrap picks the other side)
        off = np.min(np.abs(np.degrees(a.astype(np.float64))[:, None] - GRID_DEG[None, :]), axis=1) > 1e-3
        a_off = jnp.asarray(a[off])
        grads = [
            jax.jit(jax.vmap(jax.jacfwd(lambda x, r=r: lookup(x, scale, in_range=r))))(a_off)
            for r in (True, False)
        ]
        np.testing.assert_allclose(grads[0], grads[1], rtol=tol, atol=tol * np.max(np.abs(PER_RAD)))


def test_derivatives_are_differentiable(x64):
    """jax.jacfwd of the wind-axis derivatives is finite and matches central differences."""
    from harv_jax.dynamics import derivatives

    p = harv(throttle=0.4)
    x = jnp.asarray(
        [450.0, 0.31, 0.07, 0.2, -0.1, 0.05, 0.4, 0.1, 0.3, 22000.0]
    )  # alpha 17.8 deg: mid-segment
    u = jnp.asarray([-0.05, 0.03, -0.02])
    f = jax.jit(lambda xx, uu: derivatives(xx, uu, p))
    jx, ju = jax.jit(jax.jacfwd(lambda xx, uu: derivatives(xx, uu, p), argnums=(0, 1)))(x, u)
    jx, ju = np.asarray(jx), np.asarray(ju)
    assert np.all(np.isfinite(jx)) and np.all(np.isfinite(ju))
    x, u = np.asarray(x), np.asarray(u)
    for j in range(10):
        e = np.zeros(10)
        e[j] = h = 1e-6 * max(1.0, abs(x[j]))
        fd = (np.asarray(f(x + e, u)) - np.asarray(f(x - e, u))) / (2 * h)
        np.testing.assert_allclose(jx[:, j], fd, rtol=1e-5, atol=1e-7 * np.max(np.abs(fd)) + 1e-12)
    for j in range(3):
        e = np.zeros(3)
        e[j] = 1e-7
        fd = (np.asarray(f(x, u + e)) - np.asarray(f(x, u - e))) / 2e-7
        np.testing.assert_allclose(ju[:, j], fd, rtol=1e-5, atol=1e-7 * np.max(np.abs(fd)) + 1e-12)


def test_control_forces_flag_drops_only_force_terms(x64):
    p = harv()
    args = (jnp.asarray(0.3), jnp.asarray(0.1), jnp.asarray([0.2, -0.3, 0.1]), jnp.asarray(400.0))
    u = jnp.asarray([-0.2, 0.1, 0.3])
    both = jax.jit(lambda *a: (coefficients(*a, p), coefficients(*a, p, control_forces=False)))
    plant, ctrl = both(*args, u)
    row = reference_row(0.3)
    col = {n: i for i, n in enumerate(oracle.COLUMNS)}
    for name in ("Cl", "Cm", "Cn"):  # moments keep the control terms
        assert float(getattr(plant, name)) == float(getattr(ctrl, name))
    # CL differs by exactly (clift_del + clift_der) de; CY by the three surface side-force terms
    d_cl = (row[col["clift_del"]] + row[col["clift_der"]]) * -0.2
    assert float(plant.CL - ctrl.CL) == pytest.approx(d_cl, rel=1e-12)
    d_cy = (
        row[col["cy_da"]] * 0.1 + (row[col["cy_del"]] + row[col["cy_der"]]) * -0.2 + row[col["cy_dr"]] * 0.3
    )
    assert float(plant.CY - ctrl.CY) == pytest.approx(d_cy, rel=1e-12)


def test_coefficients_match_readme_per_degree_build_up(x64):
    """coefficients() (per-radian table x radians) equals the README's per-degree formulas (the oracle's)."""
    p = harv()
    rng = np.random.default_rng(4)
    prm = oracle.params_from_values(0.2)
    f = jax.jit(lambda a, b, pqr, v, u: coefficients(a, b, pqr, v, u, p))
    for _ in range(20):
        a, b = rng.uniform(-0.5, 2.0), rng.uniform(-0.5, 0.5)
        pqr, v = rng.uniform(-2, 2, 3), rng.uniform(100, 1500)
        u = rng.uniform(U_MIN_RAD, U_MAX_RAD)
        got = f(a, b, jnp.asarray(pqr), v, jnp.asarray(u))
        ref = oracle.aero_coefficients(a, b, *pqr, v, u, prm)
        for name in ("CL", "CD", "CY", "Cl", "Cm", "Cn"):
            assert float(getattr(got, name)) == pytest.approx(ref[name], rel=1e-10, abs=1e-13), name


def test_atmosphere(x64):
    rho = jax.jit(density_slugft3)
    # docs/model.md: rho(25,000 ft) = 1.06513e-3 slug/ft^3 (to the printed digits)
    assert round(float(rho(25000.0)), 8) == 1.06513e-3
    assert float(rho(0.0)) == pytest.approx(0.0023769, rel=1e-15)
    # continuity at the tropopause, 11 km = 36,089.24 ft (troposphere and stratosphere formulas meet)
    h11 = 11000.0 / 0.3048
    below, at, above = (float(rho(h)) for h in (h11 - 1e-7, h11, h11 + 1e-7))
    assert abs(above - below) / at < 1e-10
    # the independent numpy formulas over 0..70,000 ft (both branches)
    hs = np.linspace(0.0, 70000.0, 141)
    np.testing.assert_allclose(
        np.asarray(jax.vmap(rho)(jnp.asarray(hs))), [oracle.density(h) for h in hs], rtol=1e-13
    )
    # the stratosphere branch really is exponential: constant ratio over equal steps above 11 km
    r = np.asarray(jax.vmap(rho)(jnp.asarray([40000.0, 45000.0, 50000.0])))
    assert r[1] / r[0] == pytest.approx(r[2] / r[1], rel=1e-12)
    # and differs from extrapolating the troposphere formula
    theta = (288.15 - 0.0065 * 50000.0 * 0.3048) / 288.15
    assert abs(r[2] - 0.0023769 * theta ** (oracle.N_EXP - 1.0)) / r[2] > 0.05


def test_thrust_lapse(x64):
    t = jax.jit(thrust_lbf)
    assert float(t(1.0, 32000.0, 0.0)) == pytest.approx(32000.0, rel=1e-15)
    assert float(t(0.35, 32000.0, 25000.0)) == pytest.approx(
        0.35 * 32000.0 * (1.06513e-3 / 0.0023769) ** 0.7, rel=1e-5
    )
    assert float(t(0.0, 32000.0, 10000.0)) == 0.0


def test_nominal_parameters_are_the_iitm_row():
    p = harv()
    assert float(p.mass_slug) == pytest.approx(36100.0 / 32.174, rel=1e-6)
    expected = {"Ixx": 22789.0, "Iyy": 176809.0, "Izz": 191744.0, "Ixz": -2305.0, "S": 400.0, "b": 37.4,
                "cbar": 11.52, "T_max": 32000.0, "g": 32.174, "throttle": 0.2}  # fmt: skip
    for name, val in expected.items():
        assert float(getattr(p, name)) == pytest.approx(val, rel=1e-6), name
    np.testing.assert_allclose(U_MIN_RAD, [-0.436, -0.436, -0.524])
    np.testing.assert_allclose(U_MAX_RAD, [0.175, 0.436, 0.524])
    np.testing.assert_allclose(np.degrees(U_RATE_MAX_RADPS), [40.0, 100.0, 82.0])
    np.testing.assert_array_equal(np.asarray(p.aero_scale), 1.0)
    assert float(p.act_tau_s) == 0.0
    with pytest.raises(ValueError):
        harv(throttle=1.5)
