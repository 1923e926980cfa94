"""The recovery criterion in turbulence (``harv_jax.task.turbulent_criterion``): its margins against the
Dryden spectra integrated through the filters, the filter against its difference equation, and a set of
flights that are visibly not recovered, rejected at every intensity while their turbulent but recovered
twin is accepted."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import integrate

from harv_jax.aircraft import harv
from harv_jax.dynamics import turbulence as turb
from harv_jax.dynamics.state import omega_radps
from harv_jax.evaluation.metrics import compute_metrics
from harv_jax.task.criteria import default_criterion, tracking_errors
from harv_jax.task.spec import ALPHA_TARGET_RAD
from harv_jax.task.turbulent_criterion import (
    ANGLE_FILTER_TAU_S,
    RATE_FILTER_TAU_S,
    TurbulentCriterion,
    dryden_fraction,
    filter_step,
    inside_bands,
    lowpass,
    margins,
    turbulent_verdict,
)

DEG = math.pi / 180.0
DT = 0.01
N = 6001  # 60 s
V_FPS, H_FT = 400.0, 24_000.0
REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])


def _crit(level: str) -> TurbulentCriterion:
    return TurbulentCriterion(turb.turbulence_params(level, float(harv().b), jnp.float32))


@pytest.mark.parametrize("a", [0.05, 0.3, 1.0, 3.0, 20.0])
def test_dryden_fraction_is_the_spectrum_through_the_filter(a):
    """(1 / pi) int (1 + 3 x^2) / ((1 + x^2)^2 (1 + a^2 x^2)) dx, by quadrature."""
    f = lambda x: (1 + 3 * x**2) / ((1 + x**2) ** 2 * (1 + a**2 * x**2)) / math.pi  # noqa: E731
    assert float(dryden_fraction(a)) == pytest.approx(integrate.quad(f, 0, np.inf)[0], rel=1e-8)


def test_margins_follow_the_dryden_rms_of_each_filtered_channel():
    """At 24,000 ft and 400 ft/s in severe turbulence: alpha and beta sigma / V sqrt(fraction), mu and
    omega from the air's roll rate through the filters (k = 1); zero sigma: zero margins."""
    crit = _crit("severe")
    m = np.asarray(margins(crit, jnp.asarray(H_FT), jnp.asarray(V_FPS)))
    sigma_u, sigma_w, l_u, l_w = (float(x) for x in turb.scales(crit.turbulence, jnp.asarray(H_FT)))
    b = float(harv().b)
    want_beta = sigma_u / V_FPS * math.sqrt(dryden_fraction(ANGLE_FILTER_TAU_S * V_FPS / l_u))
    assert m[1] == pytest.approx(want_beta, rel=1e-5)
    assert 2.0 * DEG < m[1] < 3.0 * DEG  # ~2.5 deg: sigma 20 ft/s is 2.9 deg of beta at 400 ft/s
    tau_p = 4 * b / (math.pi * V_FPS)
    s_p = float(turb.sigma_p(jnp.asarray(sigma_w), jnp.asarray(l_w), jnp.asarray(b)))

    # the air's roll rate through the rate filter, by quadrature of its first-order spectrum
    def spec(w):
        return s_p**2 * 2 * tau_p / math.pi / (1 + (tau_p * w) ** 2) / (1 + (RATE_FILTER_TAU_S * w) ** 2)

    assert m[3] == pytest.approx(math.sqrt(integrate.quad(spec, 0, np.inf)[0]), rel=1e-5)
    still = TurbulentCriterion(turb.turbulence_params(0.0, b, jnp.float32))
    assert np.all(np.asarray(margins(still, jnp.asarray(H_FT), jnp.asarray(V_FPS))) == 0.0)


def test_lowpass_is_the_first_order_difference_equation():
    y = jnp.asarray(np.random.default_rng(0).normal(size=(500, 2)), jnp.float32)
    got = np.asarray(lowpass(y, 0.5, DT))
    a = math.exp(-DT / 0.5)
    want = np.empty_like(got)
    c = np.asarray(y[0])
    for k in range(500):
        c = a * c + (1 - a) * np.asarray(y[k])
        want[k] = c
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-6)


def _air_mass(level: str, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A Dryden realization at 24,000 ft and 400 ft/s: (v / V, w / V rad, p rad/s) [N]."""
    tp = turb.turbulence_params(level, float(harv().b), jnp.float32)
    normals = jax.random.normal(jax.random.key(seed), (N, turb.NUM_TURBULENCE_NORMALS), jnp.float32)

    def step(s, n6):
        s = turb.turbulence_step(s, tp, jnp.asarray(H_FT), jnp.asarray(V_FPS), DT, n6)
        uvw, p = turb.turbulence_velocity(s, tp, jnp.asarray(H_FT))
        return s, (uvw, p)

    _, (uvw, p) = jax.lax.scan(step, turb.turbulence_init(normals[0]), normals)
    uvw, p = np.asarray(uvw), np.asarray(p)
    return uvw[:, 1] / V_FPS, uvw[:, 2] / V_FPS, p


#: What a controller that holds its target leaves of the air mass's angles and rates (the Monte Carlo's SMC
#: leaves about a third of the open-loop angles: ``experiments/turbulence/README.md``).
HELD_FRACTION = 0.3


def _flight(kind: str, level: str) -> np.ndarray:
    """A 60 s flight [N, 10] at 400 ft/s and 24,000 ft: on target with the turbulence a held flight keeps,
    plus what makes ``kind`` not recovered."""
    t = np.arange(N) * DT
    v_rad, w_rad, p_air = (HELD_FRACTION * x for x in _air_mass(level))
    x = np.zeros((N, 10))
    x[:, 0], x[:, 9] = V_FPS, H_FT
    x[:, 1] = ALPHA_TARGET_RAD + w_rad
    x[:, 2] = v_rad
    x[:, 3] = p_air
    late = t < t[-1] - 5.0
    if kind == "beta_2deg_off":
        x[:, 2] += 2.0 * DEG
    elif kind == "mu_5deg_off":
        x[:, 6] += 5.0 * DEG
    elif kind == "rudder_limit_cycle":  # beta +-5 deg at 1 Hz, r = -d beta / dt (0.55 rad/s)
        x[:, 2] += 5.0 * DEG * np.sin(2 * np.pi * t)
        x[:, 5] += -5.0 * DEG * 2 * np.pi * np.cos(2 * np.pi * t)
    elif kind == "spin_neutral_controls":  # a developed spin: alpha 50 deg, r 1 rad/s, rolling
        x[:, 1] = 50.0 * DEG
        x[:, 3] += 0.4
        x[:, 5] += 1.0
        x[:, 6] = np.angle(np.exp(1j * 0.4 * t))
    elif kind == "rate_drift_0.2":  # a steady 0.2 rad/s yaw on target angles (a flat turn)
        x[:, 5] += 0.2
    elif kind == "settles_in_last_5s":  # the recovery transient until 5 s before the end
        x[late, 1] += 10.0 * DEG
        x[late, 2] += 3.0 * DEG
        x[late, 3] += 0.3
    elif kind != "held":
        raise ValueError(kind)
    return x


BAD = (
    "beta_2deg_off",
    "mu_5deg_off",
    "rudder_limit_cycle",
    "spin_neutral_controls",
    "rate_drift_0.2",
    "settles_in_last_5s",
)


@pytest.mark.parametrize("level", turb.INTENSITIES)
def test_visibly_unrecovered_flights_are_rejected_and_the_held_one_accepted(level):
    crit = _crit(level)
    verdict = jax.jit(lambda x: turbulent_verdict(x, REF, default_criterion(), crit, DT).recovered)
    assert bool(verdict(jnp.asarray(_flight("held", level)))), level
    for kind in BAD:
        assert not bool(verdict(jnp.asarray(_flight(kind, level)))), (kind, level)


def test_without_turbulence_the_metrics_are_the_still_air_criterions():
    """compute_metrics without a turbulence criterion is the raw criterion: a held flight with a 1.2 deg
    beta excursion fails it, and the same flight passes the criterion in light turbulence."""
    x = _flight("held", "light")
    x[3000, 2] = 1.2 * DEG  # one sample, 30 s before the end: outside the hold, recovered
    x[5500:5510, 2] = 1.2 * DEG  # ten samples inside the hold: not recovered in still air
    m = compute_metrics(jnp.asarray(x), jnp.zeros((N - 1, 3)), REF, harv(), DT)
    assert not bool(m.recovered)
    m_t = compute_metrics(jnp.asarray(x), jnp.zeros((N - 1, 3)), REF, harv(), DT, turbulence=_crit("light"))
    assert bool(m_t.recovered) and float(m_t.t_recover_s) < 50.0


def test_the_per_step_filter_is_the_criterions_lowpass():
    """``filter_step`` stepped over a run gives ``lowpass``'s filtered channels, and ``inside_bands`` the
    verdict's per-sample ``ok`` (the env's recovered reward judges each step as the Monte Carlo does)."""
    from harv_jax.task.turbulent_criterion import (
        TurbulentCriterion,
        lowpass,
        turbulent_verdict,
    )

    rng = np.random.default_rng(0)
    n = 1500
    x = np.zeros((n, 10), np.float32)
    x[:, 0] = 400.0
    x[:, 1] = 0.349 + 0.06 * np.sin(np.arange(n) * 0.005) + 0.01 * rng.standard_normal(n)
    x[:, 2] = 0.01 * rng.standard_normal(n)
    x[:, 3:6] = 0.1 * rng.standard_normal((n, 3))
    x[:, 9] = 20000.0
    x = jnp.asarray(x)
    ref = jnp.array([0.349, 0.0, 0.0])
    crit = TurbulentCriterion(turb.turbulence_params("moderate", 37.4))
    e, pqr = tracking_errors(x, ref), omega_radps(x)
    f0 = jnp.concatenate([e[0], pqr[0]])

    def step(f, sample):
        f = filter_step(f, sample[0], sample[1], crit, 0.01)
        return f, f

    _, fs = jax.lax.scan(step, f0, (e[1:], pqr[1:]))
    fs = jnp.concatenate([f0[None], fs])
    np.testing.assert_allclose(np.asarray(fs[:, :3]), np.asarray(lowpass(e, 1.0, 0.01)), atol=1e-6)
    np.testing.assert_allclose(np.asarray(fs[:, 3:]), np.asarray(lowpass(pqr, 0.25, 0.01)), atol=1e-6)
    c = default_criterion()
    v = turbulent_verdict(x, ref, c, crit, 0.01)
    tol = jnp.stack([c.alpha_tol_rad, c.beta_tol_rad, c.mu_tol_rad, c.omega_tol_radps])
    ok = jax.vmap(lambda f: inside_bands(f, tol, v.margins))(fs)
    assert 0 < int(np.sum(np.asarray(ok))) < n  # both verdicts occur in this run
    np.testing.assert_array_equal(np.asarray(ok), np.asarray(v.ok))
