"""Measurement filters in front of a controller: a discrete low-pass per measured state.

``with_measurement_filter(controller, cutoff_hz, order)`` feeds ``controller`` the filtered wind state:
each of the 8 measured states [V, alpha, beta, p, q, r, mu, gamma] passes through a Butterworth low-pass of
``order`` 1 or 2 with the -3 dB frequency ``cutoff_hz``, discretized by the bilinear transform with the
cutoff prewarped (so the discrete filter's gain at ``cutoff_hz`` is exactly 1/sqrt(2) and at 0 Hz exactly 1);
chi and h pass unfiltered. The filter starts at the first measurement (no start-up transient). Its phase
lag at frequency f is about ``order * atan(f / cutoff_hz)`` (``phase_lag_rad``), which the loop pays for in
delay margin: 2 Hz, order 2 costs ~70 ms of delay at 0.5 Hz.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.control.base import Controller
from harv_jax.task.spec import DT_S

#: Number of measured states filtered (the first components of the wind state).
NUM_FILTERED = 8


def butterworth_coefficients(
    cutoff_hz: float, order: int, dt_s: float = DT_S
) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of the discrete Butterworth low-pass (bilinear, prewarped); a[0] = 1, length order + 1."""
    if order not in (1, 2):
        raise ValueError(f"filter order {order!r}; allowed: 1 or 2")
    nyquist_hz = 0.5 / dt_s
    if not (math.isfinite(cutoff_hz) and 0 < cutoff_hz < nyquist_hz):
        raise ValueError(
            f"filter cutoff {cutoff_hz!r} Hz; allowed: above 0 and below {nyquist_hz:g} Hz (Nyquist)"
        )
    k = math.tan(math.pi * cutoff_hz * dt_s)  # prewarped analog cutoff times dt/2
    if order == 1:
        b = np.array([k, k]) / (1 + k)
        a = np.array([1.0, (k - 1) / (1 + k)])
    else:
        q = math.sqrt(2.0)
        norm = 1 + q * k + k * k
        b = np.array([k * k, 2 * k * k, k * k]) / norm
        a = np.array([1.0, 2 * (k * k - 1) / norm, (1 - q * k + k * k) / norm])
    return b, a


def frequency_gain(b: np.ndarray, a: np.ndarray, f_hz: float, dt_s: float = DT_S) -> float:
    """|H(e^{j 2 pi f dt})| of the discrete filter (b, a)."""
    z = np.exp(-1j * 2 * np.pi * f_hz * dt_s * np.arange(len(b)))
    return float(abs(np.sum(b * z) / np.sum(a * z)))


def phase_lag_rad(cutoff_hz: float, order: int, f_hz: float) -> float:
    """Phase lag of the analog Butterworth prototype at ``f_hz``, rad (order 2: exact for the prototype)."""
    w = f_hz / cutoff_hz
    return math.atan(w) if order == 1 else math.atan2(math.sqrt(2.0) * w, 1 - w * w)


def initial_command(inner: object, dtype) -> jnp.ndarray:
    """A wrapped controller state's ``u_prev_rad`` [3] (zeros if it has none): the wrapper's own at init."""
    return getattr(inner, "u_prev_rad", jnp.zeros((3,), dtype))


def inner_at_start(inner: object, first: jnp.ndarray, u_prev_rad: jnp.ndarray) -> object:
    """The wrapped state with the wrapper's ``u_prev_rad`` handed over at the first step (``closed_loop``
    starts the wrapper's at the plant's deflections); unchanged for a state without one."""
    if not hasattr(inner, "u_prev_rad"):
        return inner
    return inner.replace(u_prev_rad=jnp.where(first, u_prev_rad, inner.u_prev_rad))


@struct.dataclass
class FilteredState:
    """The wrapped controller's state, the filter's direct-form-II-transposed memory [order, 8], whether
    the first measurement was seen, and ``u_prev_rad`` [3], handed to the wrapped state at the first step
    (so ``closed_loop`` can start it at the plant's deflections as for any controller)."""

    inner: object
    z: jnp.ndarray
    started: jnp.ndarray
    u_prev_rad: jnp.ndarray


def with_measurement_filter(controller: Controller, cutoff_hz: float, order: int = 2) -> Controller:
    """``controller`` fed the low-pass-filtered measured states (see the module docstring)."""
    b_np, a_np = butterworth_coefficients(cutoff_hz, order)

    def init(params):
        inner = controller.init(params)
        dtype = params.mass_slug.dtype
        u_prev = initial_command(inner, dtype)
        z0 = jnp.zeros((order, NUM_FILTERED), dtype)
        return FilteredState(inner=inner, z=z0, started=jnp.asarray(False), u_prev_rad=u_prev)

    def apply(state, x_wind, reference_rad, key):
        dtype = x_wind.dtype
        b, a = jnp.asarray(b_np, dtype), jnp.asarray(a_np, dtype)
        m = x_wind[:NUM_FILTERED]
        # steady state at the first measurement: the memory that makes the output equal a constant input
        z_ss = jnp.stack([(b[i:] - a[i:] * 1.0).sum() * m for i in range(1, order + 1)])
        z = jnp.where(state.started, state.z, z_ss)
        y = b[0] * m + z[0]
        rows = [
            z[i + 1] + b[i + 1] * m - a[i + 1] * y if i + 1 < order else b[i + 1] * m - a[i + 1] * y
            for i in range(order)
        ]
        z_new = jnp.stack(rows)
        inner = inner_at_start(state.inner, jnp.logical_not(state.started), state.u_prev_rad)
        u, inner, info = controller.apply(inner, x_wind.at[:NUM_FILTERED].set(y), reference_rad, key)
        new = FilteredState(inner=inner, z=z_new, started=jnp.asarray(True), u_prev_rad=u.astype(dtype))
        return u, new, info

    return Controller(init, apply)
