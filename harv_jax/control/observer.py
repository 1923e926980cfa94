"""A model-based state observer in front of a controller: predict with the flight model, correct slowly.

``with_state_observer(controller, bandwidth_hz)`` feeds ``controller`` an estimate of the wind state instead
of the raw measurement. Each step k, with the measurement y_k of the 8 measured states [V, alpha, beta, p,
q, r, mu, gamma]:

    x_pred  = plant_step(x_est_{k-1}, delta_est, u_{k-1})      (the controller's own aircraft model, RK4,
                                                              its actuator model, the last command)
    x_est_k = x_pred + L * (y_k - x_pred)                     (measured states; mu's innovation wrapped)

and chi, h are taken as measured. ``L = 1 - exp(-2 pi bandwidth_hz dt)``: where the model predicts the
motion exactly, the estimate error e obeys e_k = (1 - L) e_{k-1} + L n_k per channel (to first order in dt
of the coupling), a first-order low-pass of the sensor noise n with its -3 dB point near ``bandwidth_hz``
(``noise_gain``), while the motion itself passes without the lag a plain low-pass would add: the prediction
carries it. What the model does not predict (model error, gusts, a command delay) is corrected with the same
bandwidth, and is the price of a low ``bandwidth_hz``.

``with_state_observer(controller, bandwidth_hz, estimate_bias=True)`` is the extended-state observer: it
also estimates a constant rate bias d per measured channel (the acceleration the model misses), predicts
with it and corrects it from the same innovation,

    x_pred  = plant_step(...) + d_{k-1} dt
    x_est_k = x_pred + L1 * (y_k - x_pred),    d_k = d_{k-1} + (L2 / dt) * (y_k - x_pred)

with ``L1 = 1 - r^2``, ``L2 = (1 - r)^2``, ``r = exp(-2 pi bandwidth_hz dt)``: the estimate error has a
double pole at r (``bias_gains``). A constant unpredicted rate then leaves no lag in the estimate (the plain
observer lags it by about d / (2 pi bandwidth_hz)), for a noise gain that falls off like the plain
observer's of twice the bandwidth (``noise_gain(..., estimate_bias=True)``).

The observer starts at the first measurement (its bias estimate at zero); its deflection estimate starts at
the controller state's ``u_prev_rad`` (``closed_loop`` sets it to the plant's initial deflections).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.aircraft.aero import wrap_angle_rad
from harv_jax.control.base import Controller
from harv_jax.control.filters import initial_command, inner_at_start
from harv_jax.dynamics.plant import plant_step
from harv_jax.dynamics.state import WIND_INDEX, from_wind
from harv_jax.task.spec import DT_S

#: Number of measured states corrected (the first components of the wind state).
NUM_MEASURED = 8


def correction_gain(bandwidth_hz: float, dt_s: float = DT_S) -> float:
    """The per-step correction gain L of an observer of ``bandwidth_hz``; ValueError outside (0, Nyquist)."""
    nyquist_hz = 0.5 / dt_s
    if not (math.isfinite(bandwidth_hz) and 0 < bandwidth_hz < nyquist_hz):
        raise ValueError(
            f"observer bandwidth {bandwidth_hz!r} Hz; allowed: above 0 and below {nyquist_hz:g} Hz (Nyquist)"
        )
    return 1.0 - math.exp(-2.0 * math.pi * bandwidth_hz * dt_s)


def bias_gains(bandwidth_hz: float, dt_s: float = DT_S) -> tuple[float, float]:
    """(L1, L2) of the extended-state observer of ``bandwidth_hz``: double pole at exp(-2 pi bandwidth dt)."""
    r = 1.0 - correction_gain(bandwidth_hz, dt_s)
    return 1.0 - r * r, (1.0 - r) ** 2


def noise_gain(bandwidth_hz: float, f_hz: float, dt_s: float = DT_S, estimate_bias: bool = False) -> float:
    """|E/N| at ``f_hz``: the design gain from sensor noise to estimate error, exact model."""
    z1 = np.exp(-1j * 2 * np.pi * f_hz * dt_s)  # z^-1
    if not estimate_bias:
        gain = correction_gain(bandwidth_hz, dt_s)
        return float(abs(gain / (1 - (1 - gain) * z1)))
    l1, l2 = bias_gains(bandwidth_hz, dt_s)
    # error state s = [e, eta dt] (estimate error, bias error times dt): s_k = A s_{k-1} - [L1, L2] n_k
    a = np.array([[1 - l1, 1 - l1], [-l2, 1 - l2]])
    h = np.linalg.solve(np.eye(2) - a * z1, np.array([l1, l2]))
    return float(abs(h[0]))


@struct.dataclass
class ObserverState:
    """The wrapped controller's state, the estimate [10], the rate-bias estimate [8] (units of the measured
    states per s; zero without ``estimate_bias``), the deflection estimate [3], whether the first
    measurement was seen, and ``u_prev_rad`` [3], the last command (the deflections at the start)."""

    inner: object
    x_est: jnp.ndarray
    bias_per_s: jnp.ndarray
    delta_est_rad: jnp.ndarray
    started: jnp.ndarray
    u_prev_rad: jnp.ndarray
    model: object = struct.field(default=None)


def with_state_observer(
    controller: Controller, bandwidth_hz: float, estimate_bias: bool = False
) -> Controller:
    """``controller`` fed the observer's estimate of the wind state (see the module docstring); with
    ``estimate_bias`` the extended-state observer."""
    if estimate_bias:
        gain, bias_gain = bias_gains(bandwidth_hz)
    else:
        gain, bias_gain = correction_gain(bandwidth_hz), 0.0
    mu = WIND_INDEX["mu"]

    def init(params):
        inner = controller.init(params)
        dtype = params.mass_slug.dtype
        u_prev = initial_command(inner, dtype)
        return ObserverState(
            inner=inner,
            x_est=jnp.zeros((10,), dtype),
            bias_per_s=jnp.zeros((NUM_MEASURED,), dtype),
            delta_est_rad=u_prev,
            started=jnp.asarray(False),
            u_prev_rad=u_prev,
            model=params,
        )

    def apply(state, x_wind, reference_rad, key):
        dtype = x_wind.dtype
        first = jnp.logical_not(state.started)
        delta_est = jnp.where(first, state.u_prev_rad, state.delta_est_rad)
        _, delta_next, x_pred = plant_step(
            from_wind(state.x_est), delta_est, state.u_prev_rad, state.model, DT_S
        )
        bias = state.bias_per_s
        if estimate_bias:
            x_pred = x_pred.at[:NUM_MEASURED].add(bias * DT_S)
        innovation = (x_wind - x_pred)[:NUM_MEASURED]
        innovation = innovation.at[mu].set(wrap_angle_rad(innovation[mu]))
        x_corr = x_wind.at[:NUM_MEASURED].set(x_pred[:NUM_MEASURED] + gain * innovation)
        x_corr = x_corr.at[mu].set(wrap_angle_rad(x_corr[mu]))
        x_est = jnp.where(first, x_wind, x_corr)
        if estimate_bias:
            bias = jnp.where(first, bias, bias + (bias_gain / DT_S) * innovation)
        delta_est = jnp.where(first, delta_est, delta_next)
        inner = inner_at_start(state.inner, first, state.u_prev_rad)
        u, inner, info = controller.apply(inner, x_est, reference_rad, key)
        new = state.replace(
            inner=inner,
            x_est=x_est,
            bias_per_s=bias.astype(dtype),
            delta_est_rad=delta_est.astype(dtype),
            started=jnp.asarray(True),
            u_prev_rad=u.astype(dtype),
        )
        return u, new, info

    return Controller(init, apply)
