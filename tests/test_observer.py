"""The model-based observer (``harv_jax.control.observer``): exact with an exact model and clean sensors, the
designed attenuation of sensor noise, and its suffix in the registry."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.aircraft import harv
from harv_jax.control.base import Controller
from harv_jax.control.observer import bias_gains, correction_gain, noise_gain, with_state_observer
from harv_jax.control.registry import ControllerOptions, build_controller, parse_controllers
from harv_jax.dynamics.plant import plant_step
from harv_jax.dynamics.state import WIND_INDEX, from_wind, to_wind
from harv_jax.errors import UsageError
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.task.spec import DT_S

X0 = jnp.array([600.0, 0.1, 0.02, 0.05, 0.0, -0.03, 0.1, 0.0, 0.0, 25_000.0])
REF = jnp.array([0.349, 0.0, 0.0])
U_RAD = jnp.array([-0.05, 0.01, 0.0])


def _recorder() -> Controller:
    """Commands U_RAD and records the state it is given (info["x_seen"])."""

    def init(params):
        return {"u_prev_rad": jnp.zeros((3,), params.mass_slug.dtype)}

    def apply(state, x, ref, key):
        return U_RAD.astype(x.dtype), {"u_prev_rad": U_RAD.astype(x.dtype)}, {"x_seen": x}

    return Controller(init, apply)


@pytest.mark.parametrize("estimate_bias", [False, True], ids=["observer", "eso"])
def test_with_an_exact_model_and_clean_sensors_the_estimate_is_the_state(estimate_bias):
    delta0 = jnp.array([-0.1, 0.05, 0.02])
    ctrl = with_state_observer(_recorder(), 0.1, estimate_bias=estimate_bias)
    res = closed_loop(ctrl, harv(), X0, REF, jax.random.key(0), 300, delta0_rad=delta0)
    x_seen, x_true = np.asarray(res.traj.info["x_seen"]), np.asarray(res.traj.x_wind)
    np.testing.assert_allclose(x_seen, x_true, rtol=1e-4, atol=1e-4)
    assert np.abs(x_true[-1] - x_true[0]).max() > 0.05  # the state moved: the prediction carried it


CASES = [
    (ch, amp, f, eso)
    for eso in (False, True)
    for ch, amp in (("p", 0.01), ("alpha", 0.005))
    for f in (1.0, 2.0, 8.0)
]
BANDWIDTH_HZ = 1.0


@pytest.fixture(scope="module", params=[False, True], ids=["observer", "eso"])
def measured_gains(request) -> dict[tuple, float]:
    """Gain from a sinusoid on one measured channel to the estimate error on it, for CASES of one observer."""
    eso = request.param
    cases = [c for c in CASES if c[3] == eso]
    params = harv()
    ctrl = with_state_observer(_recorder(), BANDWIDTH_HZ, estimate_bias=eso)
    n_steps, n_skip = 1500, 1000  # 15 s: 10 s of start-up, then an integer number of periods

    def errors(amp_vec, f_hz):
        def step(carry, k):
            body, delta, cstate = carry
            x_true = to_wind(body)
            y = x_true + amp_vec * jnp.sin(2 * jnp.pi * f_hz * k * DT_S)
            u, cstate, info = ctrl.apply(cstate, y, REF, jax.random.key(0))
            body, delta, _ = plant_step(body, delta, u, params, DT_S)
            return (body, delta, cstate), info["x_seen"] - x_true

        carry0 = (from_wind(X0), jnp.zeros(3), ctrl.init(params))
        return jax.lax.scan(step, carry0, jnp.arange(n_steps))[1]

    amps = jnp.stack([jnp.zeros(10).at[WIND_INDEX[ch]].set(a) for ch, a, _, _ in cases])
    freqs = jnp.array([f for _, _, f, _ in cases])
    err_all = np.asarray(jax.jit(jax.vmap(errors))(amps, freqs), np.float64)
    t = np.arange(n_skip, n_steps) * DT_S
    gains = {}
    for case, err in zip(cases, err_all, strict=True):
        ch, amp, f_hz, _ = case
        w = 2 * np.pi * f_hz
        # amplitude of the error's component at f (least squares on sin, cos and a slow drift)
        basis = np.stack([np.sin(w * t), np.cos(w * t), np.ones_like(t), t - t.mean()], axis=1)
        coef = np.linalg.lstsq(basis, err[n_skip:, WIND_INDEX[ch]], rcond=None)[0]
        gains[case] = float(np.hypot(coef[0], coef[1]) / amp)
    return gains


def test_sensor_noise_reaches_the_estimate_with_the_designed_gain(measured_gains):
    for (ch, _, f_hz, eso), gain in measured_gains.items():
        design = noise_gain(BANDWIDTH_HZ, f_hz, estimate_bias=eso)
        assert gain == pytest.approx(design, rel=0.15), (ch, f_hz, eso)


@pytest.mark.slow
def test_an_unpredicted_constant_rate_leaves_a_lag_only_without_the_bias_estimate():
    """A ramp on the measured p (a rate the model does not predict): the plain observer lags it by at least
    rate / (2 pi bandwidth) (more: the model's roll damping pulls the estimate back), the extended-state
    observer follows it to a small fraction of that."""
    params = harv()
    bandwidth_hz, rate = 0.5, 0.02  # rad/s per s on p
    i_p = WIND_INDEX["p"]

    def final_lag(estimate_bias):
        ctrl = with_state_observer(_recorder(), bandwidth_hz, estimate_bias=estimate_bias)

        def step(carry, k):
            body, delta, cstate = carry
            x_true = to_wind(body)
            y = x_true.at[i_p].add(rate * k * DT_S)
            u, cstate, info = ctrl.apply(cstate, y, REF, jax.random.key(0))
            body, delta, _ = plant_step(body, delta, u, params, DT_S)
            return (body, delta, cstate), (y - info["x_seen"])[i_p]

        carry0 = (from_wind(X0), jnp.zeros(3), ctrl.init(params))
        return float(jax.jit(lambda c: jax.lax.scan(step, c, jnp.arange(1500))[1][-1])(carry0))

    plain, eso = final_lag(False), final_lag(True)
    assert plain > rate / (2 * np.pi * bandwidth_hz)
    assert abs(eso) < 0.05 * plain


def test_design_gain_of_the_observer():
    assert correction_gain(1.0) == pytest.approx(1 - np.exp(-2 * np.pi * DT_S))
    assert noise_gain(1.0, 0.0) == pytest.approx(1.0)
    assert noise_gain(1.0, 1.0) == pytest.approx(2**-0.5, abs=0.01)  # -3 dB near the bandwidth
    assert noise_gain(0.1, 10.0) < 0.02
    l1, l2 = bias_gains(1.0)
    r = np.exp(-2 * np.pi * DT_S)
    assert (l1, l2) == pytest.approx((1 - r**2, (1 - r) ** 2))
    assert noise_gain(1.0, 0.0, estimate_bias=True) == pytest.approx(1.0)
    # the extended-state observer's noise gain falls off like the plain observer's of twice the bandwidth
    assert noise_gain(1.0, 20.0, estimate_bias=True) == pytest.approx(noise_gain(2.0, 20.0), rel=0.05)
    for bad in (0.0, -1.0, float("nan"), float("inf"), 50.0):
        with pytest.raises(ValueError, match="observer bandwidth"):
            correction_gain(bad)


def test_observer_suffix_in_the_registry():
    assert parse_controllers("smc+obs0.1,rl+obs0.5,rl+eso0.1") == ["smc+obs0.1", "rl+obs0.5", "rl+eso0.1"]
    bad_names = ("smc+obs", "smc+obsx", "smc+obs0", "smc+obs60", "smc+obsnan", "smc+kf2", "bogus+obs1")
    bad_names += ("smc+eso", "smc+eso0")
    for bad in bad_names:
        with pytest.raises(UsageError, match="controller"):
            parse_controllers(bad)
    teacher = ControllerOptions(policy="shipped:teacher")  # a policy without a path of its own
    state = build_controller("hybrid+obs0.2", teacher).init(harv())
    assert state.u_prev_rad.shape == (3,) and state.x_est.shape == (10,)
    state = build_controller("smc+eso0.1", ControllerOptions()).init(harv())
    assert state.bias_per_s.shape == (8,)
