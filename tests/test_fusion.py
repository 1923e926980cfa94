"""harv_jax.dynamics.fusion: the float32 arctan2, the one-trip loop and what they do to the plant step."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.aircraft import harv
from harv_jax.dynamics import body_derivatives, from_wind, rk4_body_step, to_wind
from harv_jax.dynamics.fusion import airflow_angles, atan2_f32, evaluated_once

X0_WIND = jnp.array([600.0, 0.5, -0.1, 0.7, -0.3, 0.2, 0.4, -0.2, 1.0, 25000.0])
U_RAD = jnp.array([-0.1, 0.05, 0.02])


def test_atan2_f32_within_3_ulp() -> None:
    rng = np.random.default_rng(0)
    n = 500_000
    y = (rng.standard_normal(n) * 10.0 ** rng.uniform(-6, 6, n)).astype(np.float32)
    x = (rng.standard_normal(n) * 10.0 ** rng.uniform(-6, 6, n)).astype(np.float32)
    exact = np.arctan2(y.astype(np.float64), x.astype(np.float64))
    got = np.asarray(jax.jit(atan2_f32)(y, x)).astype(np.float64)
    ulp = np.spacing(np.abs(exact).astype(np.float32)).astype(np.float64)
    assert np.max(np.abs(got - exact) / ulp) <= 3.5


def test_atan2_f32_special_values() -> None:
    special = np.array([0.0, -0.0, 1.0, -1.0, 1e-30, -1e30, np.inf, -np.inf, np.nan], np.float32)
    y, x = (a.ravel() for a in np.meshgrid(special, special))
    got = np.asarray(jax.jit(atan2_f32)(y, x))
    expected = np.arctan2(y, x)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(expected))
    ok = ~np.isnan(expected)
    np.testing.assert_allclose(got[ok], expected[ok], rtol=4e-7, atol=0)
    np.testing.assert_array_equal(np.signbit(got[ok]), np.signbit(expected[ok]))  # signed zeros


def test_airflow_angles_exact_in_float64(x64) -> None:
    w, u, v = jnp.array([0.3, -2.0]), jnp.array([-1.0, 5.0]), jnp.array([0.7, 0.1])
    uw = jnp.sqrt(u * u + w * w)
    alpha, beta = airflow_angles(w, u, v, uw)
    np.testing.assert_array_equal(np.asarray(alpha), np.arctan2(np.asarray(w), np.asarray(u)))
    np.testing.assert_array_equal(np.asarray(beta), np.arctan2(np.asarray(v), np.asarray(uw)))


def test_evaluated_once_value_and_derivatives() -> None:
    def fn(x: jax.Array) -> jax.Array:
        return jnp.stack([jnp.sin(x[0]) * x[1], jnp.exp(x[1]) - x[0] ** 2])

    x = jnp.array([0.3, -0.8])
    np.testing.assert_allclose(jax.jit(lambda v: evaluated_once(fn, v))(x), fn(x), rtol=1e-6)
    batch = jnp.stack([x, -x, 2 * x])
    np.testing.assert_allclose(jax.jit(jax.vmap(lambda v: evaluated_once(fn, v)))(batch), jax.vmap(fn)(batch),
                               rtol=1e-6)  # fmt: skip
    np.testing.assert_allclose(jax.jacfwd(lambda v: evaluated_once(fn, v))(x), jax.jacfwd(fn)(x), rtol=1e-6)
    np.testing.assert_allclose(jax.jacrev(lambda v: evaluated_once(fn, v))(x), jax.jacrev(fn)(x), rtol=1e-6)


@pytest.mark.slow
def test_plant_derivatives_through_the_loops() -> None:
    """Reverse mode through the RK4 step (a plain while_loop would refuse it) agrees with forward mode."""
    params = harv()
    state = from_wind(X0_WIND)

    def loss(u: jax.Array) -> jax.Array:
        new = rk4_body_step(state, u, params, 0.01)
        return jnp.sum(new.pqr_radps**2) + 1e-3 * jnp.sum(body_derivatives(new, u, params).uvw_fps)

    grad = jax.grad(loss)(U_RAD)  # op by op: the same reverse-mode trace as under jit, without its compile
    direction = jnp.array([0.3, -0.5, 0.8])
    _, along = jax.jvp(loss, (U_RAD,), (direction,))
    assert np.all(np.isfinite(np.asarray(grad)))
    np.testing.assert_allclose(float(jnp.dot(grad, direction)), float(along), rtol=1e-4)


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the loops exist on the CPU only")
def test_plant_step_keeps_its_loops_on_cpu() -> None:
    params = harv()
    state = from_wind(X0_WIND)
    hlo = jax.jit(lambda s: rk4_body_step(s, U_RAD, params, 0.01)).lower(state).compile().as_text()
    assert hlo.count(" while(") >= 4  # the four stages' arctan2 pairs


@pytest.mark.slow
@pytest.mark.skipif(jax.default_backend() != "cpu", reason="a layout of XLA's CPU backend")
def test_vmapped_plant_step_adds_stages_without_transposes() -> None:
    """The stages' inputs are formed in the derivatives' layout: transposes only where the step's result
    is written back (one per state leaf), where the unstacked state needed one in every stage."""
    params = harv()
    states = jax.vmap(from_wind)(jnp.tile(X0_WIND, (512, 1)))
    step = jax.jit(jax.vmap(lambda s: rk4_body_step(s, U_RAD, params, 0.01)))
    hlo = step.lower(states).compile().as_text()
    assert hlo.count(" transpose(") <= 4


@pytest.mark.slow
@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the loops exist on the CPU only")
def test_sharded_plant_step_needs_no_collectives() -> None:
    """Over two host devices, the loops' trip count is a constant: no all-reduce per loop."""
    code = textwrap.dedent(
        """
        import jax, jax.numpy as jnp, numpy as np
        from jax.sharding import Mesh, NamedSharding, PartitionSpec
        from harv_jax.aircraft import harv
        from harv_jax.dynamics import from_wind, rk4_body_step
        x0 = jnp.tile(jnp.array([600.0, 0.5, -0.1, 0.7, -0.3, 0.2, 0.4, -0.2, 1.0, 25000.0]), (8, 1))
        states = jax.vmap(from_wind)(x0)
        sharding = NamedSharding(Mesh(np.array(jax.devices()), ("a",)), PartitionSpec("a"))
        states = jax.device_put(states, sharding)
        step = jax.jit(jax.vmap(lambda s: rk4_body_step(s, jnp.zeros(3), harv(), 0.01)))
        hlo = step.lower(states).compile().as_text()
        print(len(jax.devices()), hlo.count(" while("), hlo.count("all-reduce("))
        """
    )
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2", JAX_PLATFORMS="cpu")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    devices, loops, all_reduces = (int(v) for v in out.stdout.split())
    assert devices == 2 and loops >= 4
    assert all_reduces == 0


def _wind_state_reference(uvw: np.ndarray, pqr: np.ndarray, quat: np.ndarray, h: np.ndarray) -> np.ndarray:
    """float64 wind-axis state by the textbook route: asin for beta, DCMs from sines and cosines."""
    q0, q1, q2, q3 = quat.T
    c_nb = np.stack(
        [
            np.stack([1 - 2 * (q2**2 + q3**2), 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)], -1),
            np.stack([2 * (q1 * q2 + q0 * q3), 1 - 2 * (q1**2 + q3**2), 2 * (q2 * q3 - q0 * q1)], -1),
            np.stack([2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), 1 - 2 * (q1**2 + q2**2)], -1),
        ],
        -2,
    )
    vt = np.linalg.norm(uvw, axis=-1)
    alpha, beta = np.arctan2(uvw[:, 2], uvw[:, 0]), np.arcsin(uvw[:, 1] / vt)
    ca, sa, cb, sb = np.cos(alpha), np.sin(alpha), np.cos(beta), np.sin(beta)
    zero = np.zeros_like(ca)
    c_wb = np.stack(
        [np.stack(r, -1) for r in ([ca * cb, sb, sa * cb], [-ca * sb, cb, -sa * sb], [-sa, zero, ca])], -2
    )
    c_wn = c_wb @ np.swapaxes(c_nb, -1, -2)
    v_ned = np.einsum("nij,nj->ni", c_nb, uvw)
    gamma = np.arctan2(-v_ned[:, 2], np.hypot(v_ned[:, 0], v_ned[:, 1]))
    chi = np.arctan2(v_ned[:, 1], v_ned[:, 0])
    mu = np.arctan2(c_wn[:, 1, 2], c_wn[:, 2, 2])
    return np.stack([vt, alpha, beta, *pqr.T, mu, gamma, chi, h], -1)


@pytest.mark.parametrize("dtype, atol_rad", [(np.float32, 2e-6), (np.float64, 1e-12)])
def test_to_wind_equals_the_textbook_form(dtype, atol_rad, request) -> None:
    """The vectorized ``to_wind`` (ratios for alpha's and beta's cosines, the float32 arctan2) against the
    float64 asin-and-DCM form, over tumbling states (every alpha, |beta| < 80 deg, |gamma| < 85 deg)."""
    if dtype == np.float64:
        request.getfixturevalue("x64")
    rng = np.random.default_rng(3)
    n = 20_000
    x = np.stack(
        [rng.uniform(50, 1500, n), rng.uniform(-np.pi, np.pi, n), rng.uniform(-1.4, 1.4, n),
         *rng.uniform(-2, 2, (3, n)), rng.uniform(-np.pi, np.pi, n), rng.uniform(-1.48, 1.48, n),
         rng.uniform(-np.pi, np.pi, n), rng.uniform(0, 40000, n)],
        -1,
    ).astype(dtype)  # fmt: skip
    states = jax.jit(jax.vmap(from_wind))(jnp.asarray(x))
    got = np.asarray(jax.jit(jax.vmap(to_wind))(states), np.float64)
    as64 = [
        np.asarray(a, np.float64)
        for a in (states.uvw_fps, states.pqr_radps, states.quat, states.pos_ft[:, 2])
    ]
    ref = _wind_state_reference(*as64)
    assert np.asarray(states.uvw_fps).dtype == dtype
    np.testing.assert_allclose(got[:, 0], ref[:, 0], rtol=4 * np.finfo(dtype).eps)
    angles = [1, 2, 6, 7, 8]
    wrapped = np.angle(np.exp(1j * (got[:, angles] - ref[:, angles])))  # (+-pi are the same angle)
    assert np.max(np.abs(wrapped)) <= atol_rad
    np.testing.assert_array_equal(got[:, 3:6], ref[:, 3:6])
