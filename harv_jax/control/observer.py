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

The observer starts at the first measurement; its deflection estimate starts at the controller state's
``u_prev_rad`` (``closed_loop`` sets it to the plant's initial deflections).
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


def noise_gain(bandwidth_hz: float, f_hz: float, dt_s: float = DT_S) -> float:
    """|E/N| at ``f_hz``: the design gain from sensor noise to estimate error, exact model (first order)."""
    gain = correction_gain(bandwidth_hz, dt_s)
    z = np.exp(-1j * 2 * np.pi * f_hz * dt_s)
    return float(abs(gain / (1 - (1 - gain) * z)))


@struct.dataclass
class ObserverState:
    """The wrapped controller's state, the estimate [10], the deflection estimate [3], whether the first
    measurement was seen, and ``u_prev_rad`` [3], the last command (the deflections at the start)."""

    inner: object
    x_est: jnp.ndarray
    delta_est_rad: jnp.ndarray
    started: jnp.ndarray
    u_prev_rad: jnp.ndarray
    model: object = struct.field(default=None)


def with_state_observer(controller: Controller, bandwidth_hz: float) -> Controller:
    """``controller`` fed the observer's estimate of the wind state (see the module docstring)."""
    gain = correction_gain(bandwidth_hz)
    mu = WIND_INDEX["mu"]

    def init(params):
        inner = controller.init(params)
        dtype = params.mass_slug.dtype
        u_prev = initial_command(inner, dtype)
        return ObserverState(
            inner=inner,
            x_est=jnp.zeros((10,), dtype),
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
        innovation = (x_wind - x_pred)[:NUM_MEASURED]
        innovation = innovation.at[mu].set(wrap_angle_rad(innovation[mu]))
        x_corr = x_wind.at[:NUM_MEASURED].set(x_pred[:NUM_MEASURED] + gain * innovation)
        x_corr = x_corr.at[mu].set(wrap_angle_rad(x_corr[mu]))
        x_est = jnp.where(first, x_wind, x_corr)
        delta_est = jnp.where(first, delta_est, delta_next)
        inner = inner_at_start(state.inner, first, state.u_prev_rad)
        u, inner, info = controller.apply(inner, x_est, reference_rad, key)
        new = state.replace(
            inner=inner,
            x_est=x_est,
            delta_est_rad=delta_est.astype(dtype),
            started=jnp.asarray(True),
            u_prev_rad=u.astype(dtype),
        )
        return u, new, info

    return Controller(init, apply)
