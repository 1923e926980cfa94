"""Per-run outcome codes and recovery metrics (jittable, vmappable) plus a host-side summary.

Everything takes a trajectory sampled every ``dt_s`` from the controller's engagement: wind states
x [T, 10] (the state at t_k = k dt_s, the last row is the final state) and the deflections
delta [T-1, 3] or [T, 3] applied over each step. Angles rad, rates rad/s, h ft.

Recovery criterion, envelope and outcome codes: ``harv_jax.task.criteria`` (|e_alpha| < 2 deg, |e_beta| <
1 deg, |e_mu| < 2 deg (wrapped) and ||omega|| < 0.17 rad/s at every sample of the last ``hold_s`` = 10 s).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics.state import gamma_rad, h_ft
from harv_jax.task.criteria import (
    Envelope,
    Outcome,
    RecoveryCriterion,
    alpha_recovered_mask,
    default_criterion,
    default_envelope,
    hold_mask,
    omega_norm_radps,
    recovered_mask,
    tracking_errors,
    within_envelope,
)
from harv_jax.task.turbulent_criterion import TurbulentCriterion, turbulent_verdict

#: Chatter band: deflection energy above this frequency, Hz.
CHATTER_CUTOFF_HZ = 5.0
#: A deflection within this distance of a position limit counts as saturated, rad.
SATURATION_TOL_RAD = 1e-4


def settle_time_s(ok: jnp.ndarray, dt_s: float | jnp.ndarray) -> jnp.ndarray:
    """Time from which ``ok`` [T] holds to the end, s (t_k = k dt_s); NaN if the last sample fails."""
    n = ok.shape[0]
    idx = jnp.arange(n)
    last_bad = jnp.max(jnp.where(ok, -1, idx))
    t = (last_bad + 1) * dt_s
    return jnp.where(ok[-1], t, jnp.nan)


def first_time_s(flag: jnp.ndarray, dt_s: float | jnp.ndarray) -> jnp.ndarray:
    """Time of the first True of ``flag`` [T], s; NaN if never."""
    n = flag.shape[0]
    k = jnp.min(jnp.where(flag, jnp.arange(n), n))
    return jnp.where(k < n, k * dt_s, jnp.nan)


def total_variation_rad(delta_rad: jnp.ndarray) -> jnp.ndarray:
    """Total variation sum_k |delta_{k+1} - delta_k| per channel [3], rad (delta [T, 3])."""
    return jnp.sum(jnp.abs(jnp.diff(delta_rad, axis=0)), axis=0)


def chatter_index_rad2(
    delta_rad: jnp.ndarray, dt_s: float, cutoff_hz: float = CHATTER_CUTOFF_HZ
) -> jnp.ndarray:
    """High-frequency energy of the deflections: mean square of their content above ``cutoff_hz``.

    By Parseval on the one-sided spectrum of the mean-removed signal (rfft); per channel [3], rad^2.
    A pure sinusoid of amplitude A above the cutoff gives A^2 / 2; a signal below it gives ~0.

    Args:
        delta_rad: [T, 3] deflections sampled every dt_s (T static).
        dt_s: sample period, s (static).
        cutoff_hz: frequency above which energy counts, Hz.
    """
    n = delta_rad.shape[0]
    x = delta_rad - jnp.mean(delta_rad, axis=0, keepdims=True)
    spec = jnp.fft.rfft(x, axis=0)
    freqs = np.fft.rfftfreq(n, d=dt_s)
    # one-sided weights: DC and (even n) Nyquist once, the rest twice
    w = np.full(freqs.shape, 2.0)
    w[0] = 1.0
    if n % 2 == 0:
        w[-1] = 1.0
    w = np.where(freqs > cutoff_hz, w, 0.0)
    return jnp.sum(jnp.asarray(w, dtype=x.dtype)[:, None] * jnp.abs(spec) ** 2, axis=0) / (n * n)


def saturation_fractions(
    delta_rad: jnp.ndarray, params: AircraftParams, dt_s: float | jnp.ndarray
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Fractions of steps at a position limit and at a rate limit, each per channel [3].

    Args:
        delta_rad: [T, 3] deflections applied over each step.
        params: aircraft (limits).
        dt_s: step, s.

    Returns:
        (position [3], rate [3]); rate uses the T-1 increments.
    """
    u_min = jnp.broadcast_to(params.u_min_rad, delta_rad.shape)
    u_max = jnp.broadcast_to(params.u_max_rad, delta_rad.shape)
    at_pos = (jnp.abs(delta_rad - u_min) < SATURATION_TOL_RAD) | (
        jnp.abs(delta_rad - u_max) < SATURATION_TOL_RAD
    )
    step = jnp.abs(jnp.diff(delta_rad, axis=0))
    at_rate = step >= jnp.broadcast_to(params.u_rate_max_radps * dt_s * (1.0 - 1e-3), step.shape)
    return jnp.mean(at_pos, axis=0), jnp.mean(at_rate, axis=0)


class RunMetrics(struct.PyTreeNode):
    """Metrics of one run (leading batch axes under vmap). Times from engagement, s; NaN = never.

    Attributes:
        outcome: int32 ``Outcome`` code.
        recovered: bool, the criterion held over the hold window.
        t_recover_s: time from which the full criterion holds to the end.
        t_recover_alpha_s: time from which |e_alpha| < tol and ||omega|| < tol hold to the end.
        overshoot_rad: [3] max excursion past the reference opposite to the initial error.
        altitude_loss_ft: h(0) - min h.
        control_tv_rad: [3] total variation of the deflections.
        chatter_index_rad2: [3] deflection energy above 5 Hz (mean square).
        sat_position_fraction: [3] fraction of steps at a position limit.
        sat_rate_fraction: [3] fraction of steps at a rate limit.
        left_envelope: bool; t_left_envelope_s: first time outside the envelope.
        hit_ground: bool.  nonfinite: bool.
        max_abs_error_hold_rad: [3] max |e| over the hold window.
        max_omega_hold_radps: max ||omega|| over the hold window.
        final_error_rad: [3] errors at the final sample.
        max_abs_gamma_rad: max |gamma| over the run.
    """

    outcome: jnp.ndarray
    recovered: jnp.ndarray
    t_recover_s: jnp.ndarray
    t_recover_alpha_s: jnp.ndarray
    overshoot_rad: jnp.ndarray
    altitude_loss_ft: jnp.ndarray
    control_tv_rad: jnp.ndarray
    chatter_index_rad2: jnp.ndarray
    sat_position_fraction: jnp.ndarray
    sat_rate_fraction: jnp.ndarray
    left_envelope: jnp.ndarray
    t_left_envelope_s: jnp.ndarray
    hit_ground: jnp.ndarray
    nonfinite: jnp.ndarray
    max_abs_error_hold_rad: jnp.ndarray
    max_omega_hold_radps: jnp.ndarray
    final_error_rad: jnp.ndarray
    max_abs_gamma_rad: jnp.ndarray


def compute_metrics(
    x_wind: jnp.ndarray,
    delta_rad: jnp.ndarray,
    reference_rad: jnp.ndarray,
    params: AircraftParams,
    dt_s: float,
    nonfinite: jnp.ndarray | bool = False,
    criterion: RecoveryCriterion | None = None,
    envelope: Envelope | None = None,
    turbulence: TurbulentCriterion | None = None,
) -> RunMetrics:
    """All metrics of one run (jittable; vmap for batches).

    Args:
        x_wind: [T, 10] wind states at t_k = k dt_s from engagement (T static).
        delta_rad: [T', 3] deflections applied over each step (T' = T or T - 1).
        reference_rad: [3] [alpha_d, beta_d, mu_d].
        params: aircraft (actuator limits).
        dt_s: sample period, s (static: it sets the chatter frequency grid).
        nonfinite: the simulation hit a non-finite state (see ``closed_loop``); non-finite values in
            ``x_wind`` or ``delta_rad`` set it too.
        criterion: recovery criterion (default ``default_criterion()``).
        envelope: envelope (default ``default_envelope()``).
        turbulence: the run's turbulence: recovered and the recovery time then follow the criterion in
            turbulence (``harv_jax.task.turbulent_criterion``); None: the still-air criterion.
    """
    criterion = default_criterion() if criterion is None else criterion
    envelope = default_envelope() if envelope is None else envelope
    in_hold = hold_mask(x_wind.shape[0], dt_s, criterion.hold_s)
    if turbulence is None:
        ok = recovered_mask(x_wind, reference_rad, criterion)
        recovered = jnp.all(ok | ~in_hold)
        t_recover = settle_time_s(ok, dt_s)
    else:
        verdict = turbulent_verdict(x_wind, reference_rad, criterion, turbulence, dt_s)
        ok, recovered = verdict.ok, verdict.recovered
        # the filtered channels' settle time less the filter's delay (NaN stays NaN)
        t_recover = jnp.maximum(settle_time_s(ok, dt_s) - turbulence.angle_filter_tau_s, 0.0)
    e = tracking_errors(x_wind, reference_rad)
    e0_sign = jnp.sign(e[:1])
    overshoot = jnp.maximum(0.0, jnp.max(-e0_sign * e, axis=0))
    inside = within_envelope(x_wind, envelope)
    left = ~jnp.all(inside)
    ground = jnp.any(h_ft(x_wind) < envelope.h_floor_ft)
    nonfinite = jnp.asarray(nonfinite) | ~jnp.all(jnp.isfinite(x_wind)) | ~jnp.all(jnp.isfinite(delta_rad))
    outcome = jnp.where(
        nonfinite,
        Outcome.NONFINITE,
        jnp.where(
            ground,
            Outcome.GROUND_HIT,
            jnp.where(recovered, Outcome.RECOVERED, jnp.where(left, Outcome.DEPARTED, Outcome.TIMEOUT)),
        ),
    ).astype(jnp.int32)
    pos_sat, rate_sat = saturation_fractions(delta_rad, params, dt_s)
    abs_e_hold = jnp.where(in_hold[:, None], jnp.abs(e), 0.0)
    omega_hold = jnp.where(in_hold, omega_norm_radps(x_wind), 0.0)
    return RunMetrics(
        outcome=outcome,
        recovered=recovered & ~nonfinite & ~ground,
        t_recover_s=jnp.where(recovered, t_recover, jnp.nan),
        t_recover_alpha_s=settle_time_s(alpha_recovered_mask(x_wind, reference_rad, criterion), dt_s),
        overshoot_rad=overshoot,
        altitude_loss_ft=h_ft(x_wind[0]) - jnp.min(h_ft(x_wind)),
        control_tv_rad=total_variation_rad(delta_rad),
        chatter_index_rad2=chatter_index_rad2(delta_rad, dt_s),
        sat_position_fraction=pos_sat,
        sat_rate_fraction=rate_sat,
        left_envelope=left,
        t_left_envelope_s=first_time_s(~inside, dt_s),
        hit_ground=ground,
        nonfinite=nonfinite,
        max_abs_error_hold_rad=jnp.max(abs_e_hold, axis=0),
        max_omega_hold_radps=jnp.max(omega_hold),
        final_error_rad=e[-1],
        max_abs_gamma_rad=jnp.max(jnp.abs(gamma_rad(x_wind))),
    )
