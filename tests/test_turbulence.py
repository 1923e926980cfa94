"""Dryden turbulence against its definition: MIL-F-8785C intensities and scale lengths, the spectra of a long
realization (Welch), the exact discretization, still air bit for bit, bad parameters."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import signal
from scipy.integrate import quad

from harv_jax.dynamics import turbulence as tb

SPAN_FT = 37.42


def test_intensities_and_scale_lengths_follow_mil_f_8785c_at_three_altitudes():
    # above 2000 ft: the probability-of-exceedance chart, L = 1750 ft
    for name, want in (("light", 2.7), ("moderate", 6.6), ("severe", 20.0)):
        s_u, s_w, l_u, l_w = map(float, tb.scales(tb.turbulence_params(name, SPAN_FT), jnp.asarray(25_000.0)))
        assert s_u == pytest.approx(want, abs=1e-5) and s_w == pytest.approx(want, abs=1e-5)
        assert l_u == l_w == tb.L_HIGH_FT
    s_u, s_w, *_ = map(float, tb.scales(tb.turbulence_params("moderate", SPAN_FT), jnp.asarray(11_250.0)))
    assert s_u == pytest.approx(10.1 + (8.0 - 10.1) * (11_250 - 7_500) / 7_500, rel=1e-5)
    # below 1000 ft: L_w = h, L_u = h / (0.177 + 0.000823 h)^1.2, sigma_w = 0.1 W20,
    # sigma_u = sigma_w / (0.177 + 0.000823 h)^0.4 (W20 = 30 kt for moderate)
    h = 500.0
    s_u, s_w, l_u, l_w = map(float, tb.scales(tb.turbulence_params("moderate", SPAN_FT), jnp.asarray(h)))
    r = 0.177 + 0.000823 * h
    assert l_w == pytest.approx(500.0) and l_u == pytest.approx(h / r**1.2, rel=1e-5)
    assert s_w == pytest.approx(5.064, rel=1e-4) and s_u == pytest.approx(5.064 / r**0.4, rel=1e-5)
    # between 1000 and 2000 ft: linear in altitude between the two models
    lo = tb.scales(tb.turbulence_params("severe", SPAN_FT), jnp.asarray(1000.0))
    hi = tb.scales(tb.turbulence_params("severe", SPAN_FT), jnp.asarray(2000.0))
    mid = tb.scales(tb.turbulence_params("severe", SPAN_FT), jnp.asarray(1500.0))
    for a, b, m in zip(lo, hi, mid, strict=True):
        assert float(m) == pytest.approx((float(a) + float(b)) / 2, rel=1e-5)


def test_the_noise_covariance_of_a_step_is_exact_for_small_and_large_steps():
    """Phi P Phi' + Q = P for the stationary P of each filter (float64): the discretization is exact."""
    with jax.enable_x64(True):
        p = np.array([[1.0, 0.5], [0.5, 0.5]])
        for a in (1e-4, 0.005, 0.3, 0.49, 0.51, 2.0, 30.0):
            a64 = jnp.asarray(a, jnp.float64)
            phi = math.exp(-a) * np.array([[1.0, 0.0], [a, 1.0]])
            i0, i1, i2 = map(float, tb._exp_moments(a64))
            q = 2 * np.array([[i0, i1], [i1, i2]])
            np.testing.assert_allclose(phi @ p @ phi.T + q, p, rtol=1e-12, atol=1e-15)
            # the step's own Cholesky factor reproduces q
            z0 = jnp.zeros(2, jnp.float64)
            cols = [np.asarray(tb.second_order_step(z0, a64, jnp.asarray(e, jnp.float64))) for e in np.eye(2)]
            chol = np.stack(cols, axis=1)
            np.testing.assert_allclose(chol @ chol.T, q, rtol=1e-9, atol=1e-18)


def _realization(n_steps: int, dt_s: float, airspeed_fps: float, seed: int) -> np.ndarray:
    """[n, 4] u, v, w (ft/s) and p (rad/s) of severe turbulence at 25,000 ft, flown at a constant airspeed."""
    params = tb.turbulence_params("severe", SPAN_FT)
    h, v = jnp.asarray(25_000.0), jnp.asarray(airspeed_fps)
    k0, k1 = jax.random.split(jax.random.PRNGKey(seed))
    state0 = tb.turbulence_init(jax.random.normal(k0, (tb.NUM_TURBULENCE_NORMALS,)))

    def step(state, n6):
        uvw, p = tb.turbulence_velocity(state, params, h)
        return tb.turbulence_step(state, params, h, v, dt_s, n6), jnp.concatenate([uvw, p[None]])

    normals = jax.random.normal(k1, (n_steps, tb.NUM_TURBULENCE_NORMALS))
    _, out = jax.lax.scan(step, state0, normals)
    return np.asarray(out, np.float64)


def _sampled(phi, omega: np.ndarray, dt_s: float, folds: int = 4000) -> np.ndarray:
    """The spectrum ``phi`` as a sequence sampled every ``dt_s`` has it: folded at the sampling frequency
    (aliasing; it matters for p, whose correlation time is near the step)."""
    k = np.arange(-folds, folds + 1)[:, None] * (2 * math.pi / dt_s)
    return phi(np.abs(omega[None, :] + k)).sum(axis=0)


def test_a_long_realization_has_the_dryden_variance_and_spectrum():
    """Welch (Hann, 8192-sample segments, 50% overlap, 400 segments) of a long realization of each channel
    at V/L = 0.5 rad/s: the variance within 5% and the PSD within 10% (averaged over bands a tenth of a
    decade wide, or 8 bins at the lowest frequencies) from 0.1 to 10 V/L, below a tenth of the Nyquist
    frequency. The Dryden spectra are compared as sampled (folded at the sampling frequency): u, v and w
    are unchanged by it, p's correlation time (4 b / (pi V) = 0.054 s) is near the 0.05 s step."""
    dt, v = 0.05, 875.0
    nper = 8192
    n = nper * (400 + 1) // 2
    x = _realization(n, dt, v, seed=3)
    sigma, length = 20.0, tb.L_HIGH_FT
    tau = length / v
    tau_p = 4 * SPAN_FT / (math.pi * v)
    s_p = float(tb.sigma_p(jnp.asarray(sigma), jnp.asarray(length), jnp.asarray(SPAN_FT)))
    first = lambda s, t: lambda w: s**2 * 2 * t / math.pi / (1 + (t * w) ** 2)  # noqa: E731
    second = lambda s, t: lambda w: s**2 * t / math.pi * (1 + 3 * (t * w) ** 2) / (1 + (t * w) ** 2) ** 2  # noqa: E731
    channels = {"u": (sigma, first(sigma, tau)), "v": (sigma, second(sigma, tau)),
                "w": (sigma, second(sigma, tau)), "p": (s_p, first(s_p, tau_p))}  # fmt: skip
    f_hz, psd = signal.welch(x, fs=1 / dt, window="hann", nperseg=nper, noverlap=nper // 2, axis=0)
    omega = 2 * math.pi * f_hz
    lo, hi = 0.1 / tau, 10 / tau
    assert hi < 0.1 * math.pi / dt  # a tenth of the Nyquist frequency
    d_omega = omega[1] - omega[0]
    edges = [lo]
    while edges[-1] < hi:  # a tenth of a decade, or 8 frequency bins where that is wider
        edges.append(min(max(edges[-1] * 10**0.1, edges[-1] + 8 * d_omega), hi))
    for i, (name, (s, phi)) in enumerate(channels.items()):
        assert x[:, i].var() == pytest.approx(s**2, rel=0.05), name
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            band = (omega >= a) & (omega < b)
            if not band.any():
                continue
            got = psd[band, i].mean() / (2 * math.pi)  # one-sided per Hz -> per rad/s
            want = _sampled(phi, omega[band], dt).mean()
            assert got == pytest.approx(want, rel=0.10), (name, a, b)


def test_still_air_is_exactly_zero_and_sigma_scales_the_same_noise():
    state = tb.turbulence_init(jax.random.normal(jax.random.PRNGKey(0), (6,)))
    for h in (300.0, 1500.0, 25_000.0):
        uvw, p = tb.turbulence_velocity(state, tb.turbulence_params(0.0, SPAN_FT), jnp.asarray(h))
        assert np.all(np.asarray(uvw) == 0.0) and float(p) == 0.0
    one = tb.turbulence_velocity(state, tb.turbulence_params(1.0, SPAN_FT), jnp.asarray(25_000.0))[0]
    five = tb.turbulence_velocity(state, tb.turbulence_params(5.0, SPAN_FT), jnp.asarray(25_000.0))[0]
    np.testing.assert_allclose(np.asarray(five), 5 * np.asarray(one), rtol=1e-6)


def test_below_the_airspeed_floor_the_correlation_time_is_held():
    params = tb.turbulence_params("moderate", SPAN_FT)
    state = tb.turbulence_init(jnp.ones(6))
    n6 = jnp.full(6, 0.3)
    slow = tb.turbulence_step(state, params, jnp.asarray(20_000.0), jnp.asarray(20.0), 0.01, n6)
    floor = tb.turbulence_step(
        state, params, jnp.asarray(20_000.0), jnp.asarray(tb.AIRSPEED_FLOOR_FPS), 0.01, n6
    )
    for a, b in zip(jax.tree.leaves(slow), jax.tree.leaves(floor), strict=True):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert all(np.all(np.isfinite(np.asarray(a))) for a in jax.tree.leaves(slow))


def test_pitch_and_yaw_components_left_out_are_as_large_as_documented():
    """q and r of MIL-F-8785C, from the spectra: the figures the module docstring quotes."""
    length = 1750.0
    for v in (130.0, 300.0, 1000.0):
        tau = length / v
        phi = lambda w, t=tau: t / math.pi * (1 + 3 * (t * w) ** 2) / (1 + (t * w) ** 2) ** 2  # noqa: E731
        rms = {}
        for name, k in (("q", 4), ("r", 3)):
            lag = k * SPAN_FT / (math.pi * v)

            def psd(w, lag=lag, v=v, phi=phi):
                return phi(w) * (w / v) ** 2 / (1 + (lag * w) ** 2)

            rms[name] = math.degrees(math.sqrt(quad(psd, 0, np.inf, limit=500)[0]))
        assert rms["q"] == pytest.approx(0.24, abs=0.005) and rms["r"] == pytest.approx(0.28, abs=0.005)


@pytest.mark.parametrize(
    "intensity, span, needle",
    [("gale", SPAN_FT, "turbulence 'gale' is unknown; allowed: light, moderate, severe"),
     (-1.0, SPAN_FT, "turbulence sigma -1.0 ft/s: allowed: a finite number >= 0"),
     (float("nan"), SPAN_FT, "turbulence sigma nan"),
     (float("inf"), SPAN_FT, "turbulence sigma inf"),
     ("light", 0.0, "wing span 0.0 ft: allowed: a finite number > 0")],
)  # fmt: skip
def test_bad_parameters_name_the_value_and_what_is_allowed(intensity, span, needle):
    with pytest.raises(ValueError, match=None) as e:
        tb.turbulence_params(intensity, span)
    assert needle in str(e.value)


def _fly(turbulence, seed: int = 5):
    """A rate damper's closed loop from a fixed upset with sensor noise, with the given turbulence (the
    SMC's compile would add nothing to what is checked)."""
    from cheap_controller import make_damper

    from harv_jax.aircraft import harv
    from harv_jax.dynamics.disturbances import DEFAULT_NOISE_STD_MAX, DisturbanceParams
    from harv_jax.evaluation.closed_loop import closed_loop

    params = harv()
    x0 = jnp.array([400.0, 0.6, 0.05, 0.3, 0.1, 0.2, 0.0, -0.3, 0.0, 25_000.0])
    dist = DisturbanceParams(
        noise_std=jnp.asarray(DEFAULT_NOISE_STD_MAX, jnp.float32),
        delay_steps=jnp.asarray(0, jnp.int32),
        gust_std_fps=jnp.asarray(0.0),
        gust_tau_s=jnp.asarray(1.0),
        turbulence=turbulence,
    )
    run = jax.jit(
        lambda d: closed_loop(
            make_damper(),
            params,
            x0,
            jnp.array([0.35, 0.0, 0.0]),
            jax.random.PRNGKey(0),
            300,
            disturbance=d,
            disturbance_key=jax.random.PRNGKey(seed),
        )  # fmt: skip
    )
    return run(dist)


@pytest.mark.slow  # two compiles of the plant (~20 s); the CLI test flies turbulence in the default suite
def test_in_the_loop_turbulence_draws_apart_and_moves_the_air_mass():
    """Turbulence on changes no other draw: the sensor noise of a run is the same with and without it; with
    sigma 0 the flight equals the one without turbulence to float rounding; moderate turbulence moves it."""
    off = _fly(None)
    zero = _fly(tb.turbulence_params(0.0, SPAN_FT))
    moderate = _fly(tb.turbulence_params("moderate", SPAN_FT))
    np.testing.assert_allclose(
        np.asarray(zero.traj.x_wind), np.asarray(off.traj.x_wind), rtol=1e-5, atol=1e-5
    )
    x_off, x_mod = np.asarray(off.traj.x_wind), np.asarray(moderate.traj.x_wind)
    assert np.all(np.isfinite(x_mod))
    beta_diff_deg = np.degrees(np.abs(x_mod[:, 2] - x_off[:, 2])).max()
    assert 0.05 < beta_diff_deg < 10.0  # 6.6 ft/s at ~400 ft/s is about 1 deg of sideslip
    # the same disturbance key gives the same turbulence whatever else changes: a second flight agrees
    again = _fly(tb.turbulence_params("moderate", SPAN_FT))
    np.testing.assert_array_equal(np.asarray(again.traj.x_wind), x_mod)
