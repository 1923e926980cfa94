"""The recovery criterion in Dryden turbulence: what the controller holds, not what the air mass does.

In still air a run is recovered when |e_alpha| < 2 deg, |e_beta| < 1 deg, |e_mu| < 2 deg and ||omega|| <
0.17 rad/s at every sample of the last 10 s (``harv_jax.task.criteria``). In turbulence the air-relative
angles move with the air mass whatever the controller does (at 400 ft/s a 20 ft/s side gust alone is
2.9 deg of beta), so the same run is judged on what the controller holds, over the same last 10 s:

1. **No bias**: the mean over the window of each error is inside the still-air tolerance (|mean e_alpha| <
   2 deg, |mean e_beta| < 1 deg, |mean e_mu| < 2 deg) and so is the norm of the mean body rates (< 0.17
   rad/s): a flight held off its target or turning steadily fails whatever the turbulence.
2. **No excursion beyond the turbulence's own**: each error low-passed with time constant
   `ANGLE_FILTER_TAU_S` (1 s, from the run's first sample) stays inside its tolerance plus a margin, and
   the norm of the body rates low-passed with `RATE_FILTER_TAU_S` (0.25 s: a limit cycle at 1 Hz keeps
   more than half its amplitude) inside 0.17 rad/s plus a margin, at every sample of the window.

The margins are `MARGIN_K` (1, at most 2) times the RMS the turbulence itself imposes on each filtered
channel, from the Dryden spectra (``harv_jax.dynamics.turbulence``) at the window's mean airspeed V and
altitude (sigma and L of that altitude; tau = L / V, V held at the turbulence's airspeed floor):

- alpha (beta): the air's vertical (lateral) velocity turns the relative wind by w / V (v / V); the
  second-order Dryden spectrum through the filter 1 / (1 + T s) keeps the variance fraction
  ``(a + 2) / (2 (a + 1)^2)`` with ``a = T / tau`` ([`dryden_fraction`][]), so
  ``m = k sigma_w / V sqrt((a + 2) / (2 (a + 1)^2))``;
- mu: the air's roll rate p (first-order spectrum, ``tau_p = 4 b / (pi V)``) turns the aircraft about its
  velocity; its filtered RMS ``sigma_p sqrt(tau_p / (tau_p + T))`` over one filter time constant T gives
  ``m = k T sigma_p sqrt(tau_p / (tau_p + T))`` rad;
- body rates: ``m = k sigma_p sqrt(tau_p / (tau_p + T_rate))`` rad/s.

The recovery time is the start of the last stretch in which every filtered channel is inside its band (the
still-air criterion's settle time, on the filtered channels) less the angle filter's time constant (a
first-order low-pass delays a slowly varying signal by its time constant), at least 0. Without turbulence
none of this is used: the still-air criterion applies, bit for bit.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.dynamics import turbulence as turb
from harv_jax.dynamics.state import h_ft, omega_radps, vt_fps
from harv_jax.task.criteria import RecoveryCriterion, hold_mask, tracking_errors
from harv_jax.task.spec import (
    RECOVERY_ALPHA_TOL_RAD,
    RECOVERY_BETA_TOL_RAD,
    RECOVERY_HOLD_S,
    RECOVERY_MU_TOL_RAD,
    RECOVERY_OMEGA_TOL_RADPS,
)

#: Time constant of the first-order low-pass on the tracking errors, s.
ANGLE_FILTER_TAU_S = 1.0
#: Time constant of the first-order low-pass on the body rates, s.
RATE_FILTER_TAU_S = 0.25
#: Margin = this many times the RMS the turbulence imposes on the filtered channel (at most 2).
MARGIN_K = 1.0


@struct.dataclass
class TurbulentCriterion:
    """The parameters of the criterion in turbulence (as ``summary.json`` records them).

    Attributes:
        turbulence: the run's turbulence (sigma table, low-altitude wind, span).
        angle_filter_tau_s: low-pass time constant of the errors, s.
        rate_filter_tau_s: low-pass time constant of the body rates, s.
        margin_k: margins in RMS of the filtered channel.
    """

    turbulence: turb.TurbulenceParams
    angle_filter_tau_s: float = struct.field(pytree_node=False, default=ANGLE_FILTER_TAU_S)
    rate_filter_tau_s: float = struct.field(pytree_node=False, default=RATE_FILTER_TAU_S)
    margin_k: float = struct.field(pytree_node=False, default=MARGIN_K)


def dryden_fraction(a: jnp.ndarray) -> jnp.ndarray:
    """Variance fraction of a second-order Dryden channel (v or w) kept by a first-order low-pass of time
    constant a tau: ``(1 / pi) int_0^inf (1 + 3 x^2) / ((1 + x^2)^2 (1 + a^2 x^2)) dx = (a + 2) / (2 (a +
    1)^2)`` (partial fractions)."""
    return (a + 2.0) / (2.0 * (a + 1.0) ** 2)


def first_order_fraction(tau_s: jnp.ndarray, filter_tau_s: float) -> jnp.ndarray:
    """Variance fraction of a first-order (Markov) process of correlation time ``tau_s`` kept by a
    first-order low-pass of time constant ``filter_tau_s``: ``tau / (tau + T)``."""
    return tau_s / (tau_s + filter_tau_s)


def margins(crit: TurbulentCriterion, h_ft: jnp.ndarray, airspeed_fps: jnp.ndarray) -> jnp.ndarray:
    """[4] margins (alpha, beta, mu rad; omega rad/s) at altitude ``h_ft`` and airspeed ``airspeed_fps``."""
    tp = crit.turbulence
    v = jnp.maximum(airspeed_fps, turb.AIRSPEED_FLOOR_FPS)
    sigma_u, sigma_w, l_u, l_w = turb.scales(tp, h_ft)
    t_a, t_r = crit.angle_filter_tau_s, crit.rate_filter_tau_s
    m_alpha = sigma_w / v * jnp.sqrt(dryden_fraction(t_a * v / l_w))
    m_beta = sigma_u / v * jnp.sqrt(dryden_fraction(t_a * v / l_u))  # sigma_v = sigma_u, L_v = L_u
    s_p = turb.sigma_p(sigma_w, l_w, tp.span_ft)
    tau_p = 4.0 * tp.span_ft / (jnp.pi * v)
    m_mu = t_a * s_p * jnp.sqrt(first_order_fraction(tau_p, t_a))
    m_omega = s_p * jnp.sqrt(first_order_fraction(tau_p, t_r))
    return crit.margin_k * jnp.stack([m_alpha, m_beta, m_mu, m_omega])


def lowpass(y: jnp.ndarray, tau_s: float, dt_s: float) -> jnp.ndarray:
    """First-order low-pass 1 / (1 + tau s) of samples ``y`` [T, ...] (exact for a signal held over each
    step), started at ``y[0]``."""
    a = float(np.exp(-dt_s / tau_s))

    def step(c: jnp.ndarray, yk: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
        c = a * c + (1.0 - a) * yk
        return c, c

    return jax.lax.scan(step, y[0], y)[1]


def filter_step(
    filtered: jnp.ndarray,
    errors_rad: jnp.ndarray,
    pqr_radps: jnp.ndarray,
    crit: TurbulentCriterion,
    dt_s: float,
) -> jnp.ndarray:
    """One step of the criterion's low-passes, for a loop that judges each step (the env's recovered
    reward): ``filtered`` [6] (errors alpha, beta, mu; p, q, r), as [`lowpass`][] steps them; start it at
    the first sample's ``concatenate([errors_rad, pqr_radps])``."""
    a_angle = float(np.exp(-dt_s / crit.angle_filter_tau_s))
    a_rate = float(np.exp(-dt_s / crit.rate_filter_tau_s))
    e_f = a_angle * filtered[:3] + (1.0 - a_angle) * errors_rad
    pqr_f = a_rate * filtered[3:] + (1.0 - a_rate) * pqr_radps
    return jnp.concatenate([e_f, pqr_f])


def inside_bands(filtered: jnp.ndarray, tol: jnp.ndarray, margin: jnp.ndarray) -> jnp.ndarray:
    """Whether the filtered channels [6] (``filter_step``) are inside ``tol`` [4] (alpha, beta, mu rad;
    omega rad/s) plus ``margin`` [4] ([`margins`][]): the excursion test of one sample."""
    return jnp.all(jnp.abs(filtered[:3]) < tol[:3] + margin[:3]) & (
        jnp.linalg.norm(filtered[3:]) < tol[3] + margin[3]
    )


class TurbulentVerdict(struct.PyTreeNode):
    """The criterion in turbulence on one run.

    Attributes:
        ok: [T] every filtered channel inside its band at that sample.
        recovered: the bias and excursion tests over the hold window both pass.
        margins: [4] the margins used (alpha, beta, mu rad; omega rad/s).
    """

    ok: jnp.ndarray
    recovered: jnp.ndarray
    margins: jnp.ndarray


def turbulent_verdict(
    x_wind: jnp.ndarray,
    reference_rad: jnp.ndarray,
    criterion: RecoveryCriterion,
    crit: TurbulentCriterion,
    dt_s: float,
) -> TurbulentVerdict:
    """The criterion in turbulence on air-relative wind states ``x_wind`` [T, 10] sampled every ``dt_s``."""
    in_hold = hold_mask(x_wind.shape[0], dt_s, criterion.hold_s)
    weight = in_hold.astype(x_wind.dtype) / jnp.sum(in_hold)
    e = tracking_errors(x_wind, reference_rad)
    pqr = omega_radps(x_wind)
    h_hold = jnp.sum(weight * h_ft(x_wind))
    v_hold = jnp.sum(weight * vt_fps(x_wind))
    m = margins(crit, h_hold, v_hold).astype(x_wind.dtype)
    tol = jnp.stack([criterion.alpha_tol_rad, criterion.beta_tol_rad, criterion.mu_tol_rad])
    mean_e = jnp.sum(weight[:, None] * e, axis=0)
    mean_pqr = jnp.sum(weight[:, None] * pqr, axis=0)
    no_bias = jnp.all(jnp.abs(mean_e) < tol) & (jnp.linalg.norm(mean_pqr) < criterion.omega_tol_radps)
    e_f = lowpass(e, crit.angle_filter_tau_s, dt_s)
    omega_f = jnp.linalg.norm(lowpass(pqr, crit.rate_filter_tau_s, dt_s), axis=-1)
    ok = jnp.all(jnp.abs(e_f) < (tol + m[:3])[None, :], axis=-1) & (
        omega_f < criterion.omega_tol_radps + m[3]
    )
    recovered = no_bias & jnp.all(ok | ~in_hold)
    return TurbulentVerdict(ok=ok, recovered=recovered, margins=m)


def criterion_record(turbulence: bool) -> dict[str, object]:
    """The recovery criterion's parameters as ``summary.json`` records them (``turbulence``: the runs
    flew in turbulence and were judged by this module's criterion)."""
    still = {
        "alpha_tol_deg": float(np.degrees(RECOVERY_ALPHA_TOL_RAD)),
        "beta_tol_deg": float(np.degrees(RECOVERY_BETA_TOL_RAD)),
        "mu_tol_deg": float(np.degrees(RECOVERY_MU_TOL_RAD)),
        "omega_tol_radps": RECOVERY_OMEGA_TOL_RADPS,
        "hold_s": RECOVERY_HOLD_S,
    }
    if not turbulence:
        return {"kind": "still air: every sample of the hold inside the tolerances", **still}
    return {
        "kind": "turbulence: hold means inside the tolerances, filtered channels inside tolerance + margin",
        **still,
        "angle_filter_tau_s": ANGLE_FILTER_TAU_S,
        "rate_filter_tau_s": RATE_FILTER_TAU_S,
        "margin_k": MARGIN_K,
        "margins": "k x the Dryden RMS of each filtered channel at the hold's mean airspeed and altitude",
    }
