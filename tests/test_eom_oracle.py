"""The wind-axis derivatives against an independent body-axis float64 oracle.

``oracle_body_axis.py`` derives x_dot through rigid-body u, v, w / Euler-angle equations and converts back
to wind-axis rates; it shares no code with harv_jax. Error metric, per component k of x_dot:

    rel_k = |jax_k - oracle_k| / max(|oracle_k|, FLOOR)

with FLOOR = 1e-6 in the component's own unit (ft/s^2, rad/s, rad/s^2, ft/s). The floor only matters
where a component happens to be near zero (smallest |oracle_k| over the 1200 default samples: 1.3e-5;
over the 10,000 slow-test samples: 6e-7), where the absolute float64 round-off of terms of size ~1..1e3
would otherwise read as a large relative error. Measured with varied aircraft: max rel 4.2e-11 (1200
states, seeds 0/1), 1.5e-10 (10,002 states, seeds 10/11, ``-m slow``); tolerance 1e-8.
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
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import oracle_body_axis as oracle  # noqa: E402

from benchmarks import numpy_harv  # noqa: E402
from harv_jax.aircraft import AircraftParams, harv  # noqa: E402
from harv_jax.dynamics import body_derivatives, derivatives, from_wind, to_wind  # noqa: E402

REL_TOL = 1e-8
FLOOR = 1e-6
N_PER_GROUP = 400  # 3 groups -> 1200 states
U_LO = np.array([-0.436, -0.436, -0.524])
U_HI = np.array([0.175, 0.436, 0.524])

# Sampling boxes, [V, alpha, beta, p, q, r, mu, gamma, chi, h].
PI = np.pi
#: The paper's reset bounds (docs/model.md), h over 0..45,000 ft so the stratosphere (> 36,089 ft) is hit.
RESET_LO = np.array([100, -0.175, -0.262, -2.094, -1.047, -0.524, -PI, -1.047, -PI, 0.0])
RESET_HI = np.array([1500, 1.047, 0.262, 2.094, 1.047, 0.524, PI, 1.047, PI, 45000.0])
#: The observation envelope and beyond: V to 2000, beta +-1.2, gamma +-1.4, rates to +-10 pi.
ENVELOPE_LO = np.array([100, -0.244, -1.2, -10 * PI, -10 * PI, -10 * PI, -PI, -1.4, -PI, 0.0])
ENVELOPE_HI = np.array([2000, 1.571, 1.2, 10 * PI, 10 * PI, 10 * PI, PI, 1.4, PI, 45000.0])
#: Alpha over the whole circle: through the [-14, 90] deg clamp and the wrap at +-pi.
WRAP_LO = np.array([100, -PI, -1.2, -5.0, -5.0, -5.0, -PI, -1.4, -PI, 0.0])
WRAP_HI = np.array([2000, PI, 1.2, 5.0, 5.0, 5.0, PI, 1.4, PI, 45000.0])


def sample_states(seed: int, n_per_group: int = N_PER_GROUP) -> tuple[np.ndarray, np.ndarray]:
    """[N, 10] states and [N, 3] controls (uniform within the limits) from the three boxes."""
    rng = np.random.default_rng(seed)
    xs = [rng.uniform(lo, hi, (n_per_group, 10)) for lo, hi in
          ((RESET_LO, RESET_HI), (ENVELOPE_LO, ENVELOPE_HI), (WRAP_LO, WRAP_HI))]  # fmt: skip
    x = np.concatenate(xs)
    u = rng.uniform(U_LO, U_HI, (len(x), 3))
    return x, u


def sample_param_values(seed: int, n: int) -> dict[str, np.ndarray]:
    """n varied aircraft (mass, inertia incl. both signs of Ixz, geometry, thrust, throttle, aero_scale)."""
    rng = np.random.default_rng(seed)
    nom = oracle.NOMINAL
    return {
        "mass_slug": nom["mass_slug"] * rng.uniform(0.8, 1.2, n),
        "Ixx": nom["Ixx"] * rng.uniform(0.8, 1.2, n),
        "Iyy": nom["Iyy"] * rng.uniform(0.8, 1.2, n),
        "Izz": nom["Izz"] * rng.uniform(0.8, 1.2, n),
        "Ixz": rng.uniform(-5000.0, 5000.0, n),
        "S": nom["S"] * rng.uniform(0.9, 1.1, n),
        "b": nom["b"] * rng.uniform(0.9, 1.1, n),
        "cbar": nom["cbar"] * rng.uniform(0.9, 1.1, n),
        "T_max": nom["T_max"] * rng.uniform(0.8, 1.2, n),
        "throttle": rng.uniform(0.0, 1.0, n),
        "aero_scale": rng.uniform(0.7, 1.3, (n, len(oracle.COLUMNS))),
    }


def oracle_params(vals: dict[str, np.ndarray]) -> list[dict]:
    """The oracle's parameter dicts for sample_param_values output."""
    scalar = [k for k in vals if k not in ("throttle", "aero_scale")]
    return [
        oracle.params_from_values(
            vals["throttle"][i], vals["aero_scale"][i], **{k: vals[k][i] for k in scalar}
        )
        for i in range(len(vals["throttle"]))
    ]


def jax_params(vals: dict[str, np.ndarray]) -> AircraftParams:
    """Batched AircraftParams (nominal limits/gravity broadcast); float64 under x64."""
    n = len(vals["throttle"])
    # np.asarray strips jax's weak types so every batch built here hits the same compiled function
    batched = jax.tree.map(lambda leaf: jnp.asarray(np.broadcast_to(leaf, (n,) + leaf.shape)), harv())
    return batched.replace(**{k: jnp.asarray(v) for k, v in vals.items()})


def rel_error(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-component relative error of a against reference b, with the documented FLOOR."""
    return np.abs(a - b) / np.maximum(np.abs(b), FLOOR)


_derivs_batched = jax.jit(jax.vmap(derivatives))


@pytest.fixture(scope="module")
def oracle_samples():
    """1200 states and controls (seed 0), aircraft (seed 1), the oracle's x_dot and body uvw_dot (numpy)."""
    x, u = sample_states(seed=0)
    dicts = oracle_params(sample_param_values(seed=1, n=len(x)))
    ref = np.stack([oracle.wind_derivatives(x[i], u[i], dicts[i]) for i in range(len(x))])
    uvw_dot = np.stack([oracle.body_rates_of_change(x[i], u[i], dicts[i])["uvw_dot"] for i in range(len(x))])
    return x, u, ref, uvw_dot


@pytest.fixture
def samples(x64, oracle_samples):
    """The module's samples with the batched float64 AircraftParams."""
    x, u, ref, uvw_dot = oracle_samples
    params = jax_params(sample_param_values(seed=1, n=len(x)))
    return x, u, params, uvw_dot, ref


def test_samples_cover_the_envelope(samples):
    x, _, _, _, _ = samples
    assert len(x) >= 1000
    alpha_deg = np.degrees(x[:, 1])
    assert np.any(alpha_deg < -14.0) and np.any(alpha_deg > 90.0) and np.any(np.abs(alpha_deg) > 170.0)
    assert np.any(x[:, 9] * 0.3048 > 11000.0) and np.any(
        x[:, 9] * 0.3048 < 11000.0
    )  # both atmosphere branches
    assert np.max(np.abs(x[:, 7])) > 1.35 and np.max(np.abs(x[:, 2])) > 1.15


def test_derivatives_match_body_axis_oracle(samples):
    x, u, params, _, ref = samples
    got = np.asarray(_derivs_batched(jnp.asarray(x), jnp.asarray(u), params))
    assert got.dtype == np.float64
    chex.assert_shape(got, (len(x), 10))
    assert np.all(np.isfinite(got)) and np.all(np.isfinite(ref))
    err = rel_error(got, ref)
    worst = np.unravel_index(np.argmax(err), err.shape)
    assert err.max() <= REL_TOL, f"max rel error {err.max():.3e} at state {worst[0]}, component {worst[1]}"


def test_oracle_comparison_can_fail(samples):
    """The metric is sensitive: plausible model errors are caught by orders of magnitude."""
    x, u, params, _, ref = samples
    # 1) product of inertia with the wrong sign convention (p_dot, r_dot components)
    flipped = params.replace(Ixz=-params.Ixz)
    err = rel_error(np.asarray(_derivs_batched(jnp.asarray(x), jnp.asarray(u), flipped)), ref)
    assert np.median(err[:, 5]) > 1e-3
    # 2) the SMC controller model (no control-surface forces) differs from the plant
    no_cf = jax.jit(jax.vmap(lambda xi, ui, pi: derivatives(xi, ui, pi, control_forces=False)))
    err = rel_error(np.asarray(no_cf(jnp.asarray(x), jnp.asarray(u), params)), ref)
    assert np.median(err[:, 0]) > 1e-4 and np.median(err[:, 1]) > 1e-4
    # 3) a per-degree column used as per-radian (aero_scale of one column off by 180/pi)
    col = oracle.COLUMNS.index("cn_r")
    wrong = params.replace(aero_scale=params.aero_scale.at[:, col].multiply(np.pi / 180.0))
    err = rel_error(np.asarray(_derivs_batched(jnp.asarray(x), jnp.asarray(u), wrong)), ref)
    assert np.max(err[:, 5]) > 1e-2


def _body_route(xi, ui, pi):
    """(to_wind(from_wind(x)), its time derivative by jax.jvp along body_derivatives, body_derivatives)."""
    s = from_wind(xi)
    s_dot = body_derivatives(s, ui, pi)
    xw, xw_dot = jax.jvp(to_wind, (s,), (s_dot,))
    return xw, xw_dot, s_dot


_body_route_batched = jax.jit(jax.vmap(_body_route))


def test_body_derivatives_match_oracle(samples):
    """body_derivatives at from_wind(x): uvw_dot, pqr_dot and h_dot against the oracle's body quantities."""
    x, u, params, uvw_dot_ref, ref = samples
    got = _body_route_batched(jnp.asarray(x), jnp.asarray(u), params)[2]
    assert rel_error(np.asarray(got.uvw_fps), uvw_dot_ref).max() <= REL_TOL
    assert rel_error(np.asarray(got.pqr_radps), ref[:, 3:6]).max() <= REL_TOL
    assert rel_error(np.asarray(got.pos_ft[:, 2]), ref[:, 9]).max() <= REL_TOL


def test_body_form_mapped_through_to_wind_equals_derivatives(samples):
    """d/dt to_wind(s) = J_to_wind(s) . body_derivatives(s) (jax.jvp) equals derivatives(to_wind(s))."""
    x, u, params, _, ref = samples
    xw, xdot, _ = _body_route_batched(jnp.asarray(x), jnp.asarray(u), params)
    xw, xdot = np.asarray(xw), np.asarray(xdot)
    # the coordinate change round-trips (angles modulo 2 pi)
    d = xw - x
    d[:, [1, 6, 8]] = np.angle(np.exp(1j * d[:, [1, 6, 8]]))
    assert np.max(np.abs(d) / np.maximum(np.abs(x), 1.0)) < 1e-12
    direct = np.asarray(_derivs_batched(jnp.asarray(x), jnp.asarray(u), params))
    assert rel_error(xdot, direct).max() <= REL_TOL
    assert rel_error(xdot, ref).max() <= REL_TOL


def test_numpy_baseline_matches_derivatives(samples):
    """benchmarks/numpy_harv.py (the benchmark's per-aircraft baseline) is the same model."""
    x, u, _, _, _ = samples
    n = len(x)
    nominal = {k: np.full(n, v) for k, v in oracle.NOMINAL.items() if k != "g"}
    params = jax_params(dict(nominal, throttle=np.full(n, 0.6), aero_scale=np.ones((n, len(oracle.COLUMNS)))))
    got = np.asarray(_derivs_batched(jnp.asarray(x), jnp.asarray(u), params))
    prm = numpy_harv.NumpyParams(throttle=0.6)
    ref = np.stack([numpy_harv.derivatives(x[i], u[i], prm) for i in range(n)])
    assert rel_error(got, ref).max() <= REL_TOL


def test_free_fall_without_aerodynamics_or_thrust(samples):
    """aero_scale = 0, throttle = 0: the velocity's NED derivative is exactly [0, 0, g] in both forms."""
    x, u, _, _, _ = samples
    n = len(x)
    nominal = {k: np.full(n, v) for k, v in oracle.NOMINAL.items() if k != "g"}
    params = jax_params(dict(nominal, throttle=np.zeros(n), aero_scale=np.zeros((n, len(oracle.COLUMNS)))))
    _, xw_dot, _ = _body_route_batched(jnp.asarray(x), jnp.asarray(u), params)
    direct = np.asarray(_derivs_batched(jnp.asarray(x), jnp.asarray(u), params))
    g = oracle.G_FPS2
    for xd in (np.asarray(xw_dot), direct):  # body form (through to_wind) and wind form
        V, gam, chi = x[:, 0], x[:, 7], x[:, 8]
        Vd, gd, cd = xd[:, 0], xd[:, 7], xd[:, 8]
        # v_NED = V [cos(gamma) cos(chi), cos(gamma) sin(chi), -sin(gamma)]; differentiate by the chain rule
        a_n = (
            Vd * np.cos(gam) * np.cos(chi)
            - V * np.sin(gam) * gd * np.cos(chi)
            - V * np.cos(gam) * np.sin(chi) * cd
        )
        a_e = (
            Vd * np.cos(gam) * np.sin(chi)
            - V * np.sin(gam) * gd * np.sin(chi)
            + V * np.cos(gam) * np.cos(chi) * cd
        )
        a_d = -Vd * np.sin(gam) - V * np.cos(gam) * gd
        np.testing.assert_allclose(
            np.stack([a_n, a_e, a_d], 1), np.broadcast_to([0, 0, g], (n, 3)), atol=1e-9
        )
        np.testing.assert_allclose(Vd, -g * np.sin(gam), rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(cd, 0.0, atol=1e-10)


def test_vmap_equals_python_loop(samples):
    """derivatives vmapped over (x, u, params) together equals calling it aircraft by aircraft."""
    x, u, params, _, _ = samples
    n = 64
    batched = np.asarray(_derivs_batched(jnp.asarray(x), jnp.asarray(u), params))[:n]
    single = jax.jit(derivatives)
    looped = np.stack(
        [np.asarray(single(jnp.asarray(x[i]), jnp.asarray(u[i]), jax.tree.map(lambda a, i=i: a[i], params)))
         for i in range(n)]
    )  # fmt: skip
    np.testing.assert_allclose(batched, looped, rtol=1e-13, atol=1e-13)


def test_non_finite_state_gives_non_finite_derivative(x64):
    """No exception inside jit: NaN/inf in gives non-finite out (flagged downstream by is_finite)."""
    single = jax.jit(derivatives)
    p = jax_params({k: np.full(1, v) for k, v in oracle.NOMINAL.items() if k != "g"} | {
        "throttle": np.full(1, 0.2), "aero_scale": np.ones((1, 33))})  # fmt: skip
    p = jax.tree.map(lambda a: a[0], p)
    for bad in (np.nan, np.inf):
        x = np.array([500.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25000.0])
        x[0] = bad
        xd = np.asarray(single(jnp.asarray(x), jnp.zeros(3), p))
        assert not np.all(np.isfinite(xd)), (bad, xd)


@pytest.mark.slow
def test_derivatives_match_oracle_10000_states(x64):
    """The same comparison at 10,000 states (seeds 10, 11): run with ``pytest -m slow``."""
    x, u = sample_states(seed=10, n_per_group=3334)
    vals = sample_param_values(seed=11, n=len(x))
    dicts = oracle_params(vals)
    ref = np.stack([oracle.wind_derivatives(x[i], u[i], dicts[i]) for i in range(len(x))])
    got = np.asarray(_derivs_batched(jnp.asarray(x), jnp.asarray(u), jax_params(vals)))
    assert len(x) >= 10_000
    assert rel_error(got, ref).max() <= REL_TOL
