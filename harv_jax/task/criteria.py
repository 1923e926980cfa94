"""What counts as recovered and as departed: outcome codes, the recovery criterion, the flight envelope.

One definition for the env (terminations, the reward's recovered term), the evaluation (outcomes,
recovery times) and the training metrics. Values come from ``task.spec``; the traced pytrees below let a
sweep change them without recompiling. Angles rad, rates rad/s, V ft/s, h ft.
"""

from __future__ import annotations

import enum

import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.aircraft.aero import wrap_angle_rad
from harv_jax.dynamics.state import TRACKED_INDEX, alpha_rad, omega_radps, vt_fps
from harv_jax.task.spec import (
    ALPHA_MAX_RAD,
    ALPHA_MIN_RAD,
    GAMMA_MAX_RAD,
    H_FLOOR_FT,
    RATE_MAX_RADPS,
    RECOVERY_ALPHA_TOL_RAD,
    RECOVERY_BETA_TOL_RAD,
    RECOVERY_HOLD_S,
    RECOVERY_MU_TOL_RAD,
    RECOVERY_OMEGA_TOL_RADPS,
    V_MAX_FPS,
    V_MIN_FPS,
)


class Outcome(enum.IntEnum):
    """Outcome codes of one run, in priority order (highest first: NONFINITE)."""

    RECOVERED = 0  # recovery criterion held over the final hold window (and nothing worse)
    TIMEOUT = 1  # stayed in the envelope but did not meet the criterion by the end
    DEPARTED = 2  # left the envelope (Envelope) at some time and did not recover
    GROUND_HIT = 3  # altitude below Envelope.h_floor_ft at some time
    NONFINITE = 4  # the simulation produced a non-finite state


OUTCOME_NAMES: tuple[str, ...] = tuple(o.name for o in Outcome)

#: Tolerances of the recovery criterion [|e_alpha|, |e_beta|, |e_mu| rad; ||omega|| rad/s] as an array
#: (the reward's ``recovered_tol`` default).
RECOVERED_TOL = np.array(
    [RECOVERY_ALPHA_TOL_RAD, RECOVERY_BETA_TOL_RAD, RECOVERY_MU_TOL_RAD, RECOVERY_OMEGA_TOL_RADPS]
)


@struct.dataclass
class RecoveryCriterion:
    """Tolerances of the recovery criterion (traced; rad, rad/s, s)."""

    alpha_tol_rad: jnp.ndarray
    beta_tol_rad: jnp.ndarray
    mu_tol_rad: jnp.ndarray
    omega_tol_radps: jnp.ndarray
    hold_s: jnp.ndarray


def default_criterion() -> RecoveryCriterion:
    """The recovery criterion: 2 deg, 1 deg, 2 deg, 0.17 rad/s, held over the last 10 s (``task.spec``)."""
    dt = jnp.result_type(float)
    return RecoveryCriterion(
        alpha_tol_rad=jnp.asarray(RECOVERY_ALPHA_TOL_RAD, dt),
        beta_tol_rad=jnp.asarray(RECOVERY_BETA_TOL_RAD, dt),
        mu_tol_rad=jnp.asarray(RECOVERY_MU_TOL_RAD, dt),
        omega_tol_radps=jnp.asarray(RECOVERY_OMEGA_TOL_RADPS, dt),
        hold_s=jnp.asarray(RECOVERY_HOLD_S, dt),
    )


@struct.dataclass
class Envelope:
    """Flight envelope (paper observation ranges) plus the ground. Traced.

    The env terminates an episode that leaves it (``env.termination``); the evaluation counts a run that
    leaves it as departed (``within_envelope``: V, alpha, rates) or as a ground hit (h).

    Attributes:
        v_min_fps, v_max_fps: airspeed range, ft/s (``task.spec``: V_MIN_FPS, V_MAX_FPS).
        alpha_min_rad, alpha_max_rad: angle-of-attack range, rad (ALPHA_MIN_RAD, ALPHA_MAX_RAD).
        rate_max_radps: bound on each |p|, |q|, |r|, rad/s (RATE_MAX_RADPS).
        gamma_max_rad: bound on |gamma|, rad (GAMMA_MAX_RAD). Note: gamma from ``to_wind`` lies in
            [-pi/2, pi/2], so the paper's bound cannot bind; it is kept for fidelity and for lower values.
        h_floor_ft: the ground, ft (default 0; -inf disables it).
    """

    v_min_fps: jnp.ndarray
    v_max_fps: jnp.ndarray
    alpha_min_rad: jnp.ndarray
    alpha_max_rad: jnp.ndarray
    rate_max_radps: jnp.ndarray
    gamma_max_rad: jnp.ndarray
    h_floor_ft: jnp.ndarray


def default_envelope(h_floor_ft: float = H_FLOOR_FT, dtype=None) -> Envelope:
    """The paper's envelope (``task.spec``) plus an altitude floor, ft."""

    def f(v):
        return jnp.asarray(v, dtype=dtype or jnp.result_type(float))

    return Envelope(
        v_min_fps=f(V_MIN_FPS),
        v_max_fps=f(V_MAX_FPS),
        alpha_min_rad=f(ALPHA_MIN_RAD),
        alpha_max_rad=f(ALPHA_MAX_RAD),
        rate_max_radps=f(RATE_MAX_RADPS),
        gamma_max_rad=f(GAMMA_MAX_RAD),
        h_floor_ft=f(h_floor_ft),
    )


def hold_mask(n_samples: int, dt_s: float | jnp.ndarray, hold_s: jnp.ndarray) -> jnp.ndarray:
    """Bool [n_samples]: the samples (t_k = k dt_s) inside the last ``hold_s`` of the run."""
    t = jnp.arange(n_samples) * dt_s
    return t >= (n_samples - 1) * dt_s - hold_s - 1e-9


def tracking_errors(x_wind: jnp.ndarray, reference_rad: jnp.ndarray) -> jnp.ndarray:
    """[..., 3] errors [alpha - alpha_d, beta - beta_d, wrap(mu - mu_d)], rad (x [..., 10], ref [..., 3]).

    e_mu is wrapped to (-pi, pi] (mu is an angle; mu = pi and mu = -pi are the same attitude).
    """
    y = jnp.stack([x_wind[..., i] for i in TRACKED_INDEX], axis=-1)
    e = y - jnp.broadcast_to(reference_rad, y.shape)
    return jnp.concatenate([e[..., :2], wrap_angle_rad(e[..., 2:])], axis=-1)


def omega_norm_radps(x_wind: jnp.ndarray) -> jnp.ndarray:
    """||(p, q, r)||, rad/s, [...]."""
    return jnp.linalg.norm(omega_radps(x_wind), axis=-1)


def recovered_mask(
    x_wind: jnp.ndarray, reference_rad: jnp.ndarray, criterion: RecoveryCriterion
) -> jnp.ndarray:
    """Per-sample bool [...]: all four conditions of the recovery criterion hold."""
    e = jnp.abs(tracking_errors(x_wind, reference_rad))
    return (
        (e[..., 0] < criterion.alpha_tol_rad)
        & (e[..., 1] < criterion.beta_tol_rad)
        & (e[..., 2] < criterion.mu_tol_rad)
        & (omega_norm_radps(x_wind) < criterion.omega_tol_radps)
    )


def alpha_recovered_mask(
    x_wind: jnp.ndarray, reference_rad: jnp.ndarray, criterion: RecoveryCriterion
) -> jnp.ndarray:
    """Per-sample bool [...]: |e_alpha| < tol and ||omega|| < tol (the recovery-time condition)."""
    e = jnp.abs(tracking_errors(x_wind, reference_rad))
    return (e[..., 0] < criterion.alpha_tol_rad) & (omega_norm_radps(x_wind) < criterion.omega_tol_radps)


def within_envelope(x_wind: jnp.ndarray, envelope: Envelope) -> jnp.ndarray:
    """Per-sample bool [...]: V, alpha and body rates inside the envelope (not altitude, not gamma)."""
    return (
        (vt_fps(x_wind) >= envelope.v_min_fps)
        & (vt_fps(x_wind) <= envelope.v_max_fps)
        & (alpha_rad(x_wind) >= envelope.alpha_min_rad)
        & (alpha_rad(x_wind) <= envelope.alpha_max_rad)
        & jnp.all(jnp.abs(omega_radps(x_wind)) <= envelope.rate_max_radps, axis=-1)
    )
