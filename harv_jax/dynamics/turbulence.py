"""Dryden turbulence of MIL-F-8785C (MIL-HDBK-1797): the linear and roll velocities of the air mass.

Spectra, with tau = L / V (V the airspeed, held at or above `AIRSPEED_FLOOR_FPS`), one-sided in the
circular frequency omega (their integrals over omega >= 0 are the variances):

- u:  sigma_u^2 (2 tau_u / pi) / (1 + (tau_u omega)^2)                     (first order)
- v:  sigma_v^2 (tau_v / pi) (1 + 3 (tau_v omega)^2) / (1 + (tau_v omega)^2)^2   (second order; w alike)
- p:  sigma_p^2 (2 tau_p / pi) / (1 + (tau_p omega)^2), tau_p = 4 b / (pi V) and
  sigma_p^2 = sigma_w^2 0.8 pi^2 / (8 b L_w) (pi L_w / (4 b))^(1/3)  (b the wing span), uncorrelated with w.

The pitch and yaw components q and r (MIL-F-8785C derives them from w and v over the span and the tail
arm: q = (s / V) w / (1 + 4 b s / (pi V))) are not modelled: their RMS is 0.24 and 0.28 deg/s per ft/s of
sigma_w and sigma_v whatever the airspeed (``tests/test_turbulence.py`` integrates the spectra), 1.6 and
1.8 deg/s in moderate and 4.8 and 5.5 deg/s in severe turbulence at 25,000 ft, against the 9.7 deg/s
(0.17 rad/s) rate bound of the recovery criterion.

Intensities (``sigma``) and scale lengths (``L``) follow the altitude of the aircraft at every step:

- above 2000 ft: L_u = L_v = L_w = 1750 ft and sigma_u = sigma_v = sigma_w from the probability-of-exceedance
  chart (MIL-F-8785C Fig. 7): `INTENSITIES` names light (exceeded with probability 1e-2), moderate
  (1e-3) and severe (1e-5), about 2.7, 6.6 and 20 ft/s at 25,000 ft;
- below 1000 ft: L_w = h, L_u = L_v = h / (0.177 + 0.000823 h)^1.2, sigma_w = 0.1 W20 and
  sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4, W20 the wind at 20 ft (15, 30, 45 kt);
- between 1000 and 2000 ft: both linearly interpolated in altitude.

A number instead of a name (``sigma_fps``) sets sigma_u = sigma_v = sigma_w to it at every altitude above
2000 ft (and W20 = 10 sigma below 1000 ft).

Each channel is a linear filter of white noise, normalized to unit stationary variance and scaled by its
sigma; it is stepped with the exact discretization for the step's tau (the state transition and the
covariance of the noise a step accumulates, in closed form): for constant tau the sampled process has the
Dryden autocovariance at every lag, whatever the step. It starts in its stationary distribution.

The velocities are those of the air mass in a frame that does not turn with the aircraft: x along the
initial horizontal heading, y to its right, z down ([`turbulence_ned`][]), rotated into body axes by the
plant ([`body_from_ned`][]). p is a body-axis roll rate of the air (``turbulence_state.p`` times sigma_p).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
from flax import struct

#: Altitudes of the probability-of-exceedance chart, ft (the chart's grid, in thousands of feet).
POE_ALTITUDES_FT = 1000.0 * np.array([0.5, 1.75, 3.75, 7.5, 15, 25, 35, 45, 55, 65, 75, 80])
#: sigma_u = sigma_v = sigma_w (ft/s) at those altitudes for the named probabilities of exceedance
#: (MIL-F-8785C, Fig. 7; MIL-HDBK-1797, Fig. 262).
POE_SIGMA_FPS = {
    "light": np.array([6.6, 6.9, 7.4, 6.7, 4.6, 2.7, 0.4, 0.0, 0.0, 0.0, 0.0, 0.0]),  # 1e-2
    "moderate": np.array([8.6, 9.6, 10.6, 10.1, 8.0, 6.6, 5.0, 4.2, 2.7, 0.0, 0.0, 0.0]),  # 1e-3
    "severe": np.array([15.6, 17.6, 23.0, 23.6, 22.1, 20.0, 16.0, 15.1, 12.1, 7.9, 6.2, 5.1]),  # 1e-5
}
#: Wind at 20 ft above ground of each intensity below 1000 ft, ft/s (15, 30 and 45 knots).
WIND_20FT_FPS = {"light": 25.32, "moderate": 50.64, "severe": 75.95}
#: The named intensities.
INTENSITIES = tuple(POE_SIGMA_FPS)
#: Scale length above 2000 ft, ft.
L_HIGH_FT = 1750.0
#: Altitude bounds of the low- and medium-altitude models, ft.
LOW_ALTITUDE_FT, HIGH_ALTITUDE_FT = 1000.0, 2000.0
#: Lowest altitude the formulas are evaluated at, ft (L_w = h vanishes at the ground).
MIN_ALTITUDE_FT = 10.0
#: Below this airspeed tau = L / V is held at L / AIRSPEED_FLOOR_FPS: at the bottom of a recovery (about
#: 130 ft/s) the spectra stay defined and the correlation times finite (13 s for L = 1750 ft).
AIRSPEED_FLOOR_FPS = 100.0
#: Normal draws per step: u 1, v 2, w 2, p 1.
NUM_TURBULENCE_NORMALS = 6
#: Below this step / tau the noise covariance is evaluated by its series (the closed forms cancel).
_SERIES_BELOW = 0.5
_SERIES_TERMS = 20


@struct.dataclass
class TurbulenceParams:
    """The turbulence of one run (traced; batch over runs).

    Attributes:
        sigma_table_fps: [12] sigma_u = sigma_v = sigma_w at `POE_ALTITUDES_FT` (0: still air).
        wind_20ft_fps: W20 of the low-altitude model, ft/s.
        span_ft: wing span b of the aircraft, ft (sets p).
    """

    sigma_table_fps: jnp.ndarray
    wind_20ft_fps: jnp.ndarray
    span_ft: jnp.ndarray


@struct.dataclass
class TurbulenceState:
    """Unit-variance filter states: u [1], v [2], w [2], p [1]."""

    u: jnp.ndarray
    v: jnp.ndarray
    w: jnp.ndarray
    p: jnp.ndarray


def turbulence_params(intensity: str | float, span_ft: float, dtype=jnp.float32) -> TurbulenceParams:
    """The parameters of a named intensity (`INTENSITIES`) or of a sigma in ft/s; ValueError naming
    the value and what is allowed otherwise."""
    if isinstance(intensity, str):
        if intensity not in POE_SIGMA_FPS:
            raise ValueError(
                f"turbulence {intensity!r} is unknown; allowed: {', '.join(INTENSITIES)} or a sigma in ft/s"
            )
        table, w20 = POE_SIGMA_FPS[intensity], WIND_20FT_FPS[intensity]
    else:
        sigma = float(intensity)
        if not (math.isfinite(sigma) and sigma >= 0):
            raise ValueError(f"turbulence sigma {intensity!r} ft/s: allowed: a finite number >= 0")
        table, w20 = np.full(POE_ALTITUDES_FT.shape, sigma), 10.0 * sigma
    if not (math.isfinite(span_ft) and span_ft > 0):
        raise ValueError(f"wing span {span_ft!r} ft: allowed: a finite number > 0")
    return TurbulenceParams(jnp.asarray(table, dtype), jnp.asarray(w20, dtype), jnp.asarray(span_ft, dtype))


def _low_altitude_ratio(h: jnp.ndarray) -> jnp.ndarray:
    return 0.177 + 0.000823 * h


def scales(params: TurbulenceParams, h_ft: jnp.ndarray) -> tuple[jnp.ndarray, ...]:
    """(sigma_u, sigma_w, L_u, L_w) at altitude ``h_ft`` (sigma_v = sigma_u, L_v = L_u), ft/s and ft."""
    h = jnp.maximum(h_ft, MIN_ALTITUDE_FT)
    hl = jnp.minimum(h, LOW_ALTITUDE_FT)
    ratio = _low_altitude_ratio(hl)
    sw_low = 0.1 * params.wind_20ft_fps
    su_low, lu_low, lw_low = sw_low / ratio**0.4, hl / ratio**1.2, hl
    hi = jnp.maximum(h, HIGH_ALTITUDE_FT)
    s_high = jnp.interp(hi, jnp.asarray(POE_ALTITUDES_FT, h.dtype), params.sigma_table_fps)
    f = jnp.clip((h - LOW_ALTITUDE_FT) / (HIGH_ALTITUDE_FT - LOW_ALTITUDE_FT), 0.0, 1.0)
    mix = lambda low, high: (1.0 - f) * low + f * high  # noqa: E731
    return mix(su_low, s_high), mix(sw_low, s_high), mix(lu_low, L_HIGH_FT), mix(lw_low, L_HIGH_FT)


def sigma_p(sigma_w: jnp.ndarray, l_w: jnp.ndarray, span_ft: jnp.ndarray) -> jnp.ndarray:
    """RMS roll rate of the air, rad/s (MIL-F-8785C)."""
    shape = (jnp.pi * l_w / (4.0 * span_ft)) ** (1 / 3)
    return sigma_w * jnp.sqrt(0.8 * jnp.pi**2 / (8.0 * span_ft * l_w) * shape)


def _exp_moments(a: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray, jnp.ndarray]:
    """I_m(a) = int_0^a u^m exp(-2u) du for m = 0, 1, 2 (series for small a, closed forms above)."""
    e = jnp.exp(-2.0 * a)
    closed = ((1 - e) / 2, (1 - e * (1 + 2 * a)) / 4, (1 - e * (1 + 2 * a + 2 * a * a)) / 4)
    small = jnp.minimum(a, _SERIES_BELOW)
    series = []
    for m in range(3):
        total, coef = jnp.zeros_like(a), 1.0
        for n in range(_SERIES_TERMS):
            total = total + coef * small ** (n + m + 1) / (n + m + 1)
            coef = coef * (-2.0) / (n + 1)
        series.append(total)
    return tuple(jnp.where(a < _SERIES_BELOW, s, c) for s, c in zip(series, closed, strict=True))


def first_order_step(z: jnp.ndarray, a: jnp.ndarray, normal: jnp.ndarray) -> jnp.ndarray:
    """Exact step of a unit-variance first-order (OU) state over dt = a tau."""
    decay = jnp.exp(-a)
    return decay * z + jnp.sqrt(-jnp.expm1(-2.0 * a)) * normal


def second_order_step(z: jnp.ndarray, a: jnp.ndarray, normal2: jnp.ndarray) -> jnp.ndarray:
    """Exact step of the Dryden v/w filter state [2] over dt = a tau.

    dz1 = -z1/tau dt + sqrt(2/tau) dW, dz2 = (z1 - z2)/tau dt: z1 has unit variance, and
    y = (sqrt(3) z1 + (1 - sqrt(3)) z2) / sqrt(2) has unit variance and the Dryden spectrum. Transition
    exp(-a) [[1, 0], [a, 1]]; noise covariance 2 [[I0, I1], [I1, I2]] (`_exp_moments`).
    """
    decay = jnp.exp(-a)
    z1 = decay * z[0]
    z2 = decay * (a * z[0] + z[1])
    i0, i1, i2 = _exp_moments(a)
    l11 = jnp.sqrt(2.0 * i0)
    l21 = 2.0 * i1 / l11
    l22 = jnp.sqrt(jnp.maximum(2.0 * i2 - l21 * l21, 0.0))
    return jnp.stack([z1 + l11 * normal2[0], z2 + l21 * normal2[0] + l22 * normal2[1]])


def second_order_output(z: jnp.ndarray) -> jnp.ndarray:
    """The unit-variance Dryden v/w output of a filter state [2]."""
    return (math.sqrt(3.0) * z[0] + (1.0 - math.sqrt(3.0)) * z[1]) / math.sqrt(2.0)


def turbulence_init(normal6: jnp.ndarray) -> TurbulenceState:
    """The stationary distribution from 6 N(0, 1) draws (z2 = z1 / 2 + n / 2: covariance [[1, .5], [.5, .5]]
    for v and w)."""
    n = normal6
    return TurbulenceState(
        u=n[0:1],
        v=jnp.stack([n[1], 0.5 * n[1] + 0.5 * n[2]]),
        w=jnp.stack([n[3], 0.5 * n[3] + 0.5 * n[4]]),
        p=n[5:6],
    )


def _taus(params: TurbulenceParams, h_ft: jnp.ndarray, airspeed_fps: jnp.ndarray) -> tuple[jnp.ndarray, ...]:
    v = jnp.maximum(airspeed_fps, AIRSPEED_FLOOR_FPS)
    _, _, l_u, l_w = scales(params, h_ft)
    return l_u / v, l_w / v, 4.0 * params.span_ft / (jnp.pi * v)


def turbulence_step(
    state: TurbulenceState,
    params: TurbulenceParams,
    h_ft: jnp.ndarray,
    airspeed_fps: jnp.ndarray,
    dt_s: float | jnp.ndarray,
    normal6: jnp.ndarray,
) -> TurbulenceState:
    """Advance every channel by ``dt_s`` with the correlation times at this altitude and airspeed."""
    tau_u, tau_w, tau_p = _taus(params, h_ft, airspeed_fps)
    return TurbulenceState(
        u=first_order_step(state.u, dt_s / tau_u, normal6[0:1]),
        v=second_order_step(state.v, dt_s / tau_u, normal6[1:3]),
        w=second_order_step(state.w, dt_s / tau_w, normal6[3:5]),
        p=first_order_step(state.p, dt_s / tau_p, normal6[5:6]),
    )


def turbulence_velocity(
    state: TurbulenceState, params: TurbulenceParams, h_ft: jnp.ndarray
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """([3] air-mass velocity in the turbulence frame, ft/s; roll rate of the air, rad/s) at ``h_ft``.

    With every sigma 0 both are exactly 0."""
    s_u, s_w, _, l_w = scales(params, h_ft)
    uvw = jnp.stack(
        [s_u * state.u[0], s_u * second_order_output(state.v), s_w * second_order_output(state.w)]
    )
    return uvw, sigma_p(s_w, jnp.maximum(l_w, MIN_ALTITUDE_FT), params.span_ft) * state.p[0]


def turbulence_ned(uvw_turb_fps: jnp.ndarray, heading0_rad: jnp.ndarray) -> jnp.ndarray:
    """The turbulence velocity [3] in NED: the turbulence frame is the initial heading's (x ahead, z down)."""
    c, s = jnp.cos(heading0_rad), jnp.sin(heading0_rad)
    x, y, z = uvw_turb_fps[0], uvw_turb_fps[1], uvw_turb_fps[2]
    return jnp.stack([c * x - s * y, s * x + c * y, z])


def body_from_ned(c_nb: jnp.ndarray, vec_ned: jnp.ndarray) -> jnp.ndarray:
    """A NED vector [3] in body axes, given the body -> NED direction cosines ``c_nb`` [3, 3]."""
    return c_nb.T @ vec_ned
