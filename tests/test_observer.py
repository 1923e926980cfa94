"""The model-based observer (``harv_jax.control.observer``): exact with an exact model and clean sensors, the
designed attenuation of sensor noise, and its suffix in the registry."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.aircraft import harv
from harv_jax.control.base import Controller
from harv_jax.control.observer import correction_gain, noise_gain, with_state_observer
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


def test_with_an_exact_model_and_clean_sensors_the_estimate_is_the_state():
    delta0 = jnp.array([-0.1, 0.05, 0.02])
    ctrl = with_state_observer(_recorder(), 0.1)
    res = closed_loop(ctrl, harv(), X0, REF, jax.random.key(0), 300, delta0_rad=delta0)
    x_seen, x_true = np.asarray(res.traj.info["x_seen"]), np.asarray(res.traj.x_wind)
    np.testing.assert_allclose(x_seen, x_true, rtol=1e-4, atol=1e-4)
    assert np.abs(x_true[-1] - x_true[0]).max() > 0.05  # the state moved: the prediction carried it


CASES = [(ch, amp, f) for ch, amp in (("p", 0.01), ("alpha", 0.005)) for f in (1.0, 2.0, 8.0)]
BANDWIDTH_HZ = 1.0


@pytest.fixture(scope="module")
def measured_gains() -> list[float]:
    """Gain from a sinusoid on one measured channel to the estimate error on it, for each of CASES."""
    params = harv()
    ctrl = with_state_observer(_recorder(), BANDWIDTH_HZ)
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

    amps = jnp.stack([jnp.zeros(10).at[WIND_INDEX[ch]].set(a) for ch, a, _ in CASES])
    freqs = jnp.array([f for _, _, f in CASES])
    err_all = np.asarray(jax.jit(jax.vmap(errors))(amps, freqs), np.float64)
    t = np.arange(n_skip, n_steps) * DT_S
    gains = []
    for (ch, amp, f_hz), err in zip(CASES, err_all, strict=True):
        w = 2 * np.pi * f_hz
        # amplitude of the error's component at f (least squares on sin, cos and a slow drift)
        basis = np.stack([np.sin(w * t), np.cos(w * t), np.ones_like(t), t - t.mean()], axis=1)
        coef = np.linalg.lstsq(basis, err[n_skip:, WIND_INDEX[ch]], rcond=None)[0]
        gains.append(float(np.hypot(coef[0], coef[1]) / amp))
    return gains


@pytest.mark.parametrize("case", range(len(CASES)), ids=[f"{c}-{f:g}Hz" for c, _, f in CASES])
def test_sensor_noise_reaches_the_estimate_with_the_designed_gain(measured_gains, case):
    _, _, f_hz = CASES[case]
    assert measured_gains[case] == pytest.approx(noise_gain(BANDWIDTH_HZ, f_hz), rel=0.15)


def test_design_gain_of_the_observer():
    assert correction_gain(1.0) == pytest.approx(1 - np.exp(-2 * np.pi * DT_S))
    assert noise_gain(1.0, 0.0) == pytest.approx(1.0)
    assert noise_gain(1.0, 1.0) == pytest.approx(2**-0.5, abs=0.01)  # -3 dB near the bandwidth
    assert noise_gain(0.1, 10.0) < 0.02
    for bad in (0.0, -1.0, float("nan"), float("inf"), 50.0):
        with pytest.raises(ValueError, match="observer bandwidth"):
            correction_gain(bad)


def test_observer_suffix_in_the_registry():
    assert parse_controllers("smc+obs0.1,rl+obs0.5") == ["smc+obs0.1", "rl+obs0.5"]
    for bad in ("smc+obs", "smc+obsx", "smc+obs0", "smc+obs60", "smc+obsnan", "smc+kf2", "bogus+obs1"):
        with pytest.raises(UsageError, match="controller"):
            parse_controllers(bad)
    state = build_controller("hybrid+obs0.2", ControllerOptions()).init(harv())
    assert state.u_prev_rad.shape == (3,) and state.x_est.shape == (10,)
