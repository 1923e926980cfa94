"""Empirical stability certificate of the hybrid law (beyond the paper, which assumes the bound).

The paper's Theorem 1 needs the matched mismatch-plus-disturbance Delta in the sliding dynamics

    s_dot = -zeta (K |s|^(1/2) + eps) sw(s) + Delta,      |Delta| <= delta_bar + d_bar,

to satisfy zeta eps > delta_bar + d_bar per channel. Delta collects everything the design ignores: the
learned command's mismatch, control-surface forces, actuator position/rate limits, randomized aircraft
and wind. From closed-loop samples s_k (the controller's sliding variables, every dt_s) it is estimated
as

    Delta_k = (s_{k+1} - s_k) / dt_s + zeta_k (K |s_k|^(1/2) + eps) sw(s_k)

over the steps where the feedback is fully engaged (zeta = 1 at k and k + 1; for mu also the mu row
unblended, w_mu = 1) and everything is finite. The bound is reported as the maximum and the 99th
percentile of |Delta|, with the fraction of samples outside the boundary layer where the reaching
condition s s_dot < 0 held.
"""

from __future__ import annotations

from typing import Any

import numpy as np

CHANNELS = ("alpha", "beta", "mu")


def switching_term(s: np.ndarray, phi: np.ndarray, switching: str) -> np.ndarray:
    """sw(s): sign(s) or sat(s / phi), elementwise ([..., 3])."""
    if switching == "sign":
        return np.sign(s)
    return np.clip(s / phi, -1.0, 1.0)


def empirical_certificate(
    s: np.ndarray,
    zeta: np.ndarray,
    w_mu: np.ndarray,
    k_reach: np.ndarray,
    eps_radps2: np.ndarray,
    phi_radps: np.ndarray,
    dt_s: float,
    switching: str = "sat",
    valid: np.ndarray | None = None,
) -> dict[str, Any]:
    """Estimate delta_bar + d_bar per channel from sampled sliding variables.

    Args:
        s: [..., T, 3] sliding variables (rad/s), leading axes are runs.
        zeta: [..., T] hybrid weight (1 for an SMC-only run).
        w_mu: [..., T] weight of the mu row (SMC info ``w_mu``).
        k_reach, eps_radps2, phi_radps: [3] SMC gains.
        dt_s: sample step, s.
        switching: ``"sat"`` or ``"sign"``.
        valid: optional bool [..., T]: samples to use (e.g. the actuators unsaturated over the step).

    Returns:
        dict per channel name: n_samples, delta_max, delta_p99 (rad/s^2), zeta_eps (eps with zeta = 1),
        holds (eps > delta_max), holds_p99 (eps > delta_p99), reaching_fraction (s s_dot < 0 where
        |s| > phi).
    """
    s = np.asarray(s, np.float64)
    zeta = np.asarray(zeta, np.float64)
    w_mu = np.asarray(w_mu, np.float64)
    k_reach, eps, phi = (
        np.broadcast_to(np.asarray(v, np.float64), (3,)) for v in (k_reach, eps_radps2, phi_radps)
    )
    s0, s1 = s[..., :-1, :], s[..., 1:, :]
    s_dot = (s1 - s0) / dt_s
    z0 = zeta[..., :-1, None]
    delta = s_dot + z0 * (k_reach * np.sqrt(np.abs(s0)) + eps) * switching_term(s0, phi, switching)
    engaged = (zeta[..., :-1] >= 1.0) & (zeta[..., 1:] >= 1.0)
    if valid is not None:
        engaged &= np.asarray(valid, bool)[..., :-1]
    mu_ok = (w_mu[..., :-1] >= 1.0) & (w_mu[..., 1:] >= 1.0)
    out: dict[str, Any] = {}
    for i, name in enumerate(CHANNELS):
        mask = engaged & np.isfinite(delta[..., i])
        if i == 2:
            mask &= mu_ok
        d = np.abs(delta[..., i][mask])
        outside = mask & (np.abs(s0[..., i]) > phi[i])
        reach = (s0[..., i] * s_dot[..., i] < 0)[outside]
        d_max = float(d.max()) if d.size else None
        d_p99 = float(np.percentile(d, 99)) if d.size else None
        out[name] = {
            "n_samples": int(d.size),
            "delta_max": d_max,
            "delta_p99": d_p99,
            "zeta_eps": float(eps[i]),
            "holds": bool(d.size and eps[i] > d_max),
            "holds_p99": bool(d.size and eps[i] > d_p99),
            "reaching_fraction": float(reach.mean()) if reach.size else None,
        }
    return out


def unsaturated_steps(
    delta_rad: np.ndarray, u_min: np.ndarray, u_max: np.ndarray, rate_step: np.ndarray
) -> np.ndarray:
    """bool [..., T]: no surface at a position limit and none moving at its rate limit over step k."""
    tol = 1e-6
    d = np.asarray(delta_rad)
    at_pos = (d <= u_min + tol) | (d >= u_max - tol)
    dd = np.abs(np.diff(d, axis=-2, append=d[..., -1:, :]))
    at_rate = dd >= rate_step - tol
    return ~np.any(at_pos | at_rate, axis=-1)
