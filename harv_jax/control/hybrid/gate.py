"""Certificate-gated zeta: per channel, the least SMC authority that keeps the reaching condition.

On the controller model the sliding variables obey, for a command u (``harv_jax.control.smc``),

    s_dot(u) = A u + d                   A = L_g L_f y (blended mu row), affine in u,

and the SMC command u_SMC = u_RL + u_fb solves A u_SMC = b, i.e. s_dot(u_SMC) = -(K |s|^1/2 + eps) sw(s)
(``reach``). Hence, with the residual r(u) = A (u - u_SMC),

    s_dot(u) = r(u) - reach,         r(u_RL) = -A u_fb.

Certificate (per channel i, q_i = sign(s_i) r_i(u), sign(0) = +1):

    -L_i <= q_i <= U_i,      U_i = m_i + c_i w_i,      L_i = c_i + kappa |s_i| / dt,
    m_i = (K_i |s_i|^1/2 + eps_i - eta_i) |sw_i|,       w_i = max(0, 1 - |s_i| / delta_i).

- The upper bound outside the band |s_i| >= delta_i (w = 0) is the reaching condition
  s_i s_dot_i <= -eta_i |s_i| |sw_i|: rate eta outside the SMC's boundary layer, exponential convergence
  at rate eta / phi inside it (the shape of the SMC's own law there).
- Inside the band, a narrow strip around the surface (default delta = phi / 10), s_dot may exceed the
  SMC's by up to c at s = 0, tightening to the reaching condition at the band's edge: the band is
  invariant (s cannot leave it).
- The lower bound is the discrete-time half of the reaching condition (|s_k+1| < |s_k| needs
  s_k+1 not to overshoot to -s_k): the command may approach the surface faster than the SMC's by at most
  kappa |s| / dt (kappa = 1/2: half the remaining gap in one step), plus c.
- Both bounds, hence zeta, are continuous in s, and symmetric (both c) at s = 0. A one-sided condition
  down to s = 0 is not: just past the surface a policy that pushes s one way needs zeta ~ 1, just before
  it zeta = 0, and a policy with |r| dt > delta crosses the band in one step; the command then chattered
  between u_SMC and u_RL through the rate limits (256 runs, shipped partial policy: control TV 20.8 rad,
  11.3 with the band alone, vs the SMC's 7.3).

With eta <= eps and c >= 0 the SMC command (q = 0) meets it on every channel. So the guarantee on the
controller model: s reaches the band at rate >= eta and stays in it (e then within about delta / lambda1,
the integral removing any steady offset).

Per-channel zeta in the output coordinates. A diagonal zeta applied to the *inputs*
(u = u_RL + Z u_fb) couples the channels through A's off-diagonal terms: r(Z) = -A (I - Z) u_fb, where
raising zeta_j can help or hurt channel i depending on the signs of A_ij u_fb_j, so a per-channel "least
zeta" is neither unique nor found by a scalar rule. Weighting the correction in the sliding coordinates
instead,

    u(zeta) = u_RL + A^-1 (zeta (.) A u_fb)      so that    q_i(zeta) = (1 - zeta_i) q_i(u_RL),

decouples them exactly: channel i's condition depends on zeta_i alone, and its least zeta_i in [0, 1] is
1 - U_i / q_i(u_RL) above the band, 1 - L_i / |q_i(u_RL)| below it, 0 inside (the policy acts
unmodified); every larger zeta also meets it. With equal zeta on every channel, A^-1 zeta A = zeta I:
this is the paper's u = u_RL + zeta u_fb.

The actuator box. The command that acts is clip(u(zeta), lo, hi) (position and rate limits of this step,
``safety.limit_box``), which can break the condition that u(zeta) met. The gate therefore checks the clipped
command along zeta(t) = zeta* + t (1 - zeta*), t in ``BOX_STEPS``, and keeps the first t whose clipped
command meets, on every checked channel, the bounds widened to include q_i(clip u_SMC): the condition
wherever the box-clipped SMC command meets it ("feasible within the box"), else at least the SMC's own
progress. t = 1 is the clipped SMC command, which meets every target: the gate always returns a command.

Not checked (zeta_i = 1, the SMC's row): the mu channel in the near-vertical blend (w_mu < 1: its row is
p_w damping, s_mu is not the controlled quantity). zeta = 1 on every channel (the SMC command, u_RL
cancels) where the singularity guard is active (the solve is not exact, so r(u_RL) is unknown), where A
is not invertible in float, where anything is non-finite, and in the supervisor's fallback.

Release rate (``zeta_lower``; the hybrid keeps zeta as state): zeta may rise to the least value at once
but falls by at most ``release_per_s`` * dt per step, so that the policy's authority returns smoothly.
"""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct

from harv_jax.control.smc import SMCGains

#: Fractions t of the way from the unclipped least zeta to 1 tried against the actuator box.
BOX_STEPS = (0.0, 0.25, 0.5, 0.75, 1.0)
#: Slack of the certificate test, rad/s^2 (float32 rounding of A (u - u_SMC)).
CERT_TOL_RADPS2 = 1e-5


@struct.dataclass
class GateGains:
    """Traced settings of the certificate gate (per channel [3] unless noted).

    Attributes:
        eta_radps2: required reaching rate outside the band, rad/s^2 (<= eps keeps u_SMC certified).
        band_radps: half-width delta of the band around s = 0, rad/s.
        band_rate_radps2: c, the drift of s_dot from the SMC's allowed at s = 0, rad/s^2.
        approach_frac: scalar kappa, the fraction of |s| the command may close per step beyond the SMC.
        release_per_s: scalar, fastest fall of zeta, 1/s (rises are immediate).
    """

    eta_radps2: jnp.ndarray
    band_radps: jnp.ndarray
    band_rate_radps2: jnp.ndarray
    approach_frac: jnp.ndarray
    release_per_s: jnp.ndarray


def default_gate_gains(smc: SMCGains) -> GateGains:
    """eta = eps; band delta = phi / 10 (0.02 rad/s: e within ~0.01 rad); c = eps; kappa 1/2; release
    0.2/s (256 runs, shipped partial policy: control TV 7.9 rad vs 11.3 at 2/s)."""
    dtype = smc.eps_radps2.dtype
    return GateGains(
        eta_radps2=smc.eps_radps2,
        band_radps=0.1 * smc.phi_radps,
        band_rate_radps2=smc.eps_radps2,
        approach_frac=jnp.asarray(0.5, dtype),
        release_per_s=jnp.asarray(0.2, dtype),
    )


def switching_fn(s: jnp.ndarray, phi_radps: jnp.ndarray, switching: str) -> jnp.ndarray:
    """sw(s): sign(s) or sat(s / phi) [3]."""
    if switching == "sign":
        return jnp.sign(s)
    return jnp.clip(s / phi_radps, -1.0, 1.0)


def certificate_bounds(
    s: jnp.ndarray, smc: SMCGains, gains: GateGains, switching: str, dt_s: float
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """(U, L) [3], rad/s^2: the certificate holds on channel i iff -L_i <= sign(s_i) r_i <= U_i."""
    sw = switching_fn(s, smc.phi_radps, switching)
    m = (smc.k_reach * jnp.sqrt(jnp.abs(s)) + smc.eps_radps2 - gains.eta_radps2) * jnp.abs(sw)
    w = jnp.clip(1.0 - jnp.abs(s) / gains.band_radps, 0.0, 1.0)
    upper = m + gains.band_rate_radps2 * w
    lower = gains.band_rate_radps2 + gains.approach_frac * jnp.abs(s) / dt_s
    return upper, lower


def signed_residual(
    a: jnp.ndarray, u_rad: jnp.ndarray, u_smc_rad: jnp.ndarray, s: jnp.ndarray
) -> jnp.ndarray:
    """q = sign(s) r(u) [3] with r(u) = A (u - u_SMC) = s_dot(u) - s_dot(u_SMC); sign(0) = +1."""
    return jnp.where(s >= 0, 1.0, -1.0) * (a @ (u_rad - u_smc_rad))


def certificate_holds(
    a: jnp.ndarray,
    u_applied_rad: jnp.ndarray,
    u_smc_rad: jnp.ndarray,
    s: jnp.ndarray,
    smc: SMCGains,
    gains: GateGains,
    switching: str,
    dt_s: float,
) -> jnp.ndarray:
    """bool [3]: the certificate holds on the controller model for the command that acts (any schedule)."""
    a = jnp.where(jnp.isfinite(a), a, 0.0)
    upper, lower = certificate_bounds(s, smc, gains, switching, dt_s)
    q = signed_residual(a, u_applied_rad, u_smc_rad, s)
    return (q <= upper + CERT_TOL_RADPS2) & (q >= -lower - CERT_TOL_RADPS2)


class GateResult(struct.PyTreeNode):
    """Output of ``gate``.

    Attributes:
        zeta: [3] per-channel weight in [0, 1].
        u_raw_rad: [3] u(zeta) before the box (the hybrid's safety filter clips it).
        zeta_unboxed: [3] least zeta of the unclipped condition (before the box search).
        forced: bool, zeta = 1 everywhere by rule (guard, fallback, non-finite).
    """

    zeta: jnp.ndarray
    u_raw_rad: jnp.ndarray
    zeta_unboxed: jnp.ndarray
    forced: jnp.ndarray


def inv3(a: jnp.ndarray) -> jnp.ndarray:
    """Inverse of a [3, 3] matrix from its adjugate, non-finite where ``a`` is singular.

    Elementwise arithmetic only: it vectorizes over a batch of aircraft, where ``jnp.linalg.inv`` runs a
    LAPACK LU and two triangular solves per matrix on a CPU (~330 of ~1,700 us per gated hybrid step of
    1,000 aircraft in XLA's trace). Equal to it to rounding for the matrices the gate inverts (the SMC's
    guarded solve flags the ill-conditioned ones, and the gate then uses the SMC command).
    """
    c00 = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c01 = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c02 = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    det = a[0, 0] * c00 + a[0, 1] * c01 + a[0, 2] * c02
    adjugate = jnp.stack(
        [
            jnp.stack([c00, a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2], a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]]),
            jnp.stack([c01, a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0], a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]]),
            jnp.stack([c02, a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1], a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]]),
        ]
    )
    return adjugate / det


def gate(
    u_rl_rad: jnp.ndarray,
    u_fb_rad: jnp.ndarray,
    a: jnp.ndarray,
    s: jnp.ndarray,
    box_lo_rad: jnp.ndarray,
    box_hi_rad: jnp.ndarray,
    smc: SMCGains,
    gains: GateGains,
    switching: str,
    dt_s: float,
    unchecked: jnp.ndarray,
    force_one: jnp.ndarray,
    zeta_lower: jnp.ndarray | float = 0.0,
) -> GateResult:
    """Least per-channel zeta meeting the certificate with the box-clipped command (module docstring).

    Args:
        u_rl_rad: [3] learned command (after the authority cap; 0 in fallback).
        u_fb_rad: [3] feedback term designed on the RL-compensated dynamics (``smc_command(u_offset=u_RL)``).
        a: [3, 3] the decoupling matrix the SMC solved with (``SMCTerms.decoupling``).
        s: [3] sliding variables.
        box_lo_rad, box_hi_rad: [3] the deflections reachable this step.
        smc: SMC gains (K, eps, phi).
        gains: GateGains.
        switching: the SMC's ``"sat"`` or ``"sign"``.
        dt_s: controller step, s.
        unchecked: bool [3] channels with zeta = 1 by rule (the mu row in the near-vertical blend).
        force_one: bool, zeta = 1 on every channel (guard active, fallback).
        zeta_lower: [3] or scalar lower bound of zeta (the release floor); any zeta above the least one
            also meets the unclipped condition.

    Returns:
        GateResult.
    """
    dtype = u_fb_rad.dtype
    a = jnp.where(jnp.isfinite(a), a, 0.0)
    a_inv = inv3(a)
    a_u_fb = a @ u_fb_rad
    u_smc = u_rl_rad + u_fb_rad
    upper, lower = certificate_bounds(s, smc, gains, switching, dt_s)
    q_rl = signed_residual(a, u_rl_rad, u_smc, s)  # = -sign(s) A u_fb
    above = q_rl > upper
    below = q_rl < -lower
    safe_q = jnp.where(above | below, q_rl, 1.0)
    z_star = jnp.where(above, 1.0 - upper / safe_q, jnp.where(below, 1.0 + lower / safe_q, 0.0))
    z_star = jnp.clip(z_star, 0.0, 1.0)
    z_star = jnp.maximum(jnp.where(unchecked, 1.0, z_star), zeta_lower).astype(dtype)

    q_smc_box = signed_residual(a, jnp.clip(u_smc, box_lo_rad, box_hi_rad), u_smc, s)
    hi_target = jnp.maximum(upper, q_smc_box) + CERT_TOL_RADPS2
    lo_target = jnp.minimum(-lower, q_smc_box) - CERT_TOL_RADPS2
    t = jnp.asarray(BOX_STEPS, dtype)[:, None]
    zetas = z_star[None, :] + t * (1.0 - z_star[None, :])  # [n_t, 3]; the last row is all ones

    def try_one(z):
        # u_RL + u_fb - A^-1 ((1 - zeta) A u_fb): exactly u_SMC at zeta = 1, exactly u_RL at zeta = 0
        u = jnp.where(jnp.all(z == 0.0), u_rl_rad, u_smc - a_inv @ ((1.0 - z) * a_u_fb))
        q = signed_residual(a, jnp.clip(u, box_lo_rad, box_hi_rad), u_smc, s)
        return u, jnp.all(unchecked | ((q <= hi_target) & (q >= lo_target)))

    us, ok = zip(*(try_one(zetas[k]) for k in range(len(BOX_STEPS))), strict=True)
    us, ok = jnp.stack(us), jnp.stack(ok).at[-1].set(True)
    k = jnp.argmax(ok)
    zeta, u_raw = zetas[k], us[k]

    finite = jnp.all(jnp.isfinite(a_inv)) & jnp.all(jnp.isfinite(u_raw)) & jnp.all(jnp.isfinite(s))
    forced = force_one | ~finite
    zeta = jnp.where(forced, 1.0, zeta)
    u_raw = jnp.where(forced, u_smc, u_raw)
    return GateResult(zeta=zeta, u_raw_rad=u_raw, zeta_unboxed=z_star, forced=forced)
