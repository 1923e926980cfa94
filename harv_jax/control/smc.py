"""Sliding-mode control of y = [alpha, beta, mu] with feedback linearization (paper Sec. IV-B).

Derivation (per channel i; vectors below are stacked over the three channels):

    e      = y - y_ref                       (mu error wrapped to (-pi, pi])
    e_dot  = L_f y - y_ref_dot
    s      = e_dot + lambda1 e + lambda2 int(e) dt
    s_dot  = e_ddot + lambda1 e_dot + lambda2 e
    y_ddot = L_f^2 y + (L_g L_f y) u          (controller model: relative degree 2 per channel)

Requiring the reaching law s_dot = -(K |s|^(1/2) + eps) sign(s) gives

    nu = y_ref_ddot - lambda1 e_dot - lambda2 e - (K |s|^(1/2) + eps) sign(s)
    u  = (L_g L_f y)^-1 (nu - L_f^2 y).

NOTE the paper's sign typo: its printed u_r = -f + y_ref_ddot - lambda1 e_dot **+** lambda2 e; the
derivation above needs **-** lambda2 e (the same sign as in the paper's own eq. u_r of Sec. V).

Practical additions, all documented where they act:
- switching: ``"sign"`` (the paper) or the boundary layer ``sat(s / phi)``.
- anti-windup: the integral of e runs only while |e| < ``int_band_rad`` and no command saturates,
  it is clipped to ``int_clip_rad_s`` and reset to 0 when the reference changes (``SMCConfig``).
- mu near gamma = +-90 deg: mu is undefined at a vertical flight path and L_f^2 mu grows like
  tan(gamma)/cos(gamma)^2. Between ``gamma_lo_rad`` and ``gamma_hi_rad`` the third row of the
  linearized system is blended (smoothstep weight w(|gamma|)) from the mu sliding mode (w = 1) to a
  first-order damping of the wind-axis roll rate, p_w_dot = -k_pw p_w (w = 0), which is defined at
  gamma = +-90 deg. Both rows are affine in u, so the blend is a valid affine row.
- singularity guard: the 3x3 system A u = b is solved by SVD with damped least squares
  (Maciejewski & Klein): damping rho^2 = (1 - (s_min/s_th)^2) s_th^2 when the smallest singular value
  s_min falls below s_th = max(s_max / cond_max, sigma_floor). Non-finite terms (V -> 0, beta -> 90 deg)
  are zeroed and, if the command is still non-finite, the previous command is held: never NaN.
- saturation: the command is clipped to the position limits (what the plant's actuator model does
  anyway) so that saturation can be detected for the anti-windup; rate limits are the plant's.
"""

from __future__ import annotations

import dataclasses
from typing import Literal

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.aero import wrap_angle_rad
from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.control.lie import output_lie_terms, smc_lie_terms
from harv_jax.dynamics.state import WIND_INDEX
from harv_jax.smooth import smoothstep_falling
from harv_jax.task.spec import DT_S
from harv_jax.units import RAD_PER_DEG

#: Index of the mu channel in y = [alpha, beta, mu].
MU_CHANNEL = 2


@struct.dataclass
class SMCGains:
    """SMC gains: a pytree of traced arrays, so a gain sweep vmaps without recompiling.

    Per-channel leaves are [3] for [alpha, beta, mu]; the others are scalars.

    Attributes:
        lambda1_ps: lambda1, 1/s (sliding surface).
        lambda2_ps2: lambda2, 1/s^2 (integral term of the surface).
        k_reach: K of the reaching law (K |s|^(1/2) + eps), (rad/s)^(1/2)/s.
        eps_radps2: eps of the reaching law, rad/s^2.
        phi_radps: boundary-layer half-width on s, rad/s (``switching="sat"`` only).
        int_clip_rad_s: bound on |int e dt|, rad s.
        int_band_rad: the integral runs only while |e| < int_band_rad, rad.
        gamma_lo_rad: below this |gamma| the mu channel is fully active, rad.
        gamma_hi_rad: above this |gamma| the third row is p_w damping only, rad.
        k_pw_ps: decay rate of the wind-axis roll rate in the near-vertical band, 1/s.
        cond_max: condition number of L_g L_f y above which damped least squares starts.
        sigma_floor: absolute floor of the damping threshold on singular values, rad/s^2 per rad.
    """

    lambda1_ps: jnp.ndarray
    lambda2_ps2: jnp.ndarray
    k_reach: jnp.ndarray
    eps_radps2: jnp.ndarray
    phi_radps: jnp.ndarray
    int_clip_rad_s: jnp.ndarray
    int_band_rad: jnp.ndarray
    gamma_lo_rad: jnp.ndarray
    gamma_hi_rad: jnp.ndarray
    k_pw_ps: jnp.ndarray
    cond_max: jnp.ndarray
    sigma_floor: jnp.ndarray


def default_gains(dtype=None) -> SMCGains:
    """Default gains, chosen by the two-round study in ``experiments/smc_tuning/run.py``.

    Starting point (an untuned SMC): lambda1 2, lambda2 0.5, K 1, eps 0.2, phi 0.05. Round 1
    (one at a time) showed a plateau of 100% recovery around it and sharp losses for aggressive
    reaching (K 4, eps 0.5, phi 0.02, lambda1 4: limit cycles against the actuator rate limits);
    round 2 combined the softer settings: K 0.5 and phi 0.2 cut control total variation by ~40%
    and the 45-60 deg mu/p_w blend band cut the median recovery time from ~30 s to ~23 s, with
    100% recovery on nominal and perturbed aircraft (see ``experiments/smc_tuning/README.md``).
    """
    dtype = jnp.result_type(float) if dtype is None else dtype  # not weakly typed: no retrace on sweeps

    def f(v):
        return jnp.asarray(v, dtype=dtype)

    return SMCGains(
        lambda1_ps=f([2.0, 2.0, 2.0]),
        lambda2_ps2=f([0.5, 0.5, 0.5]),
        k_reach=f([0.5, 0.5, 0.5]),
        eps_radps2=f([0.2, 0.2, 0.2]),
        phi_radps=f([0.2, 0.2, 0.2]),
        int_clip_rad_s=f([0.5, 0.5, 0.5]),
        int_band_rad=f([5.0 * RAD_PER_DEG] * 3),
        gamma_lo_rad=f(45.0 * RAD_PER_DEG),
        gamma_hi_rad=f(60.0 * RAD_PER_DEG),
        k_pw_ps=f(1.0),
        cond_max=f(1.0e3),
        sigma_floor=f(1.0e-4),
    )


@dataclasses.dataclass(frozen=True)
class SMCConfig:
    """Static (structural) options of the SMC; changing them recompiles.

    Attributes:
        switching: ``"sat"`` (boundary layer sat(s/phi)) or ``"sign"`` (the paper's discontinuous law).
        dt_s: controller step = plant step, s (integrates the surface's integral term).
        reset_integral_on_reference_change: zero the integral when the reference steps.
        freeze_integral_when_saturated: anti-windup by conditional integration.
        vertical_mu_handling: blend the mu row to p_w damping near gamma = +-90 deg (else pure mu SMC).
    """

    switching: Literal["sat", "sign"] = "sat"
    dt_s: float = DT_S
    reset_integral_on_reference_change: bool = True
    freeze_integral_when_saturated: bool = True
    vertical_mu_handling: bool = True


@struct.dataclass
class SMCState:
    """Per-aircraft controller state (vmap it together with the aircraft).

    Attributes:
        params: the aircraft of the controller model.
        integral_rad_s: [3] int e dt.
        reference_prev_rad: [3] reference seen at the previous step.
        has_reference: bool, False before the first ``apply``.
        u_prev_rad: [3] previous command (fallback if a command is non-finite).
    """

    params: AircraftParams
    integral_rad_s: jnp.ndarray
    reference_prev_rad: jnp.ndarray
    has_reference: jnp.ndarray
    u_prev_rad: jnp.ndarray


class SolveInfo(struct.PyTreeNode):
    """Diagnostics of the guarded solve: cond (s_max/s_min), damping rho^2, guard active flag."""

    cond: jnp.ndarray
    rho2: jnp.ndarray
    guard_active: jnp.ndarray


#: Cyclic sweeps of the one-sided Jacobi SVD in ``guarded_solve`` (3 rotations each). Jacobi converges
#: quadratically: after 4 sweeps the columns of a float32 or float64 3x3 are orthogonal to rounding.
JACOBI_SWEEPS = 5


def _jacobi_svd3(a: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """One-sided (Hestenes) Jacobi SVD of a [3, 3] matrix: W = a V with orthogonal columns.

    Returns (w [3, 3], v [3, 3]): a = W V^T, the singular values are the column norms of W (unsorted)
    and column i of W is s_i u_i. Elementwise arithmetic only (no LAPACK call): vectorizes over a
    batch, which a batched 3x3 ``jnp.linalg.svd`` does not do on a CPU.
    """
    cols = [a[:, 0], a[:, 1], a[:, 2]]
    v = [jnp.zeros(3, a.dtype).at[i].set(1.0) for i in range(3)]
    tiny = jnp.finfo(a.dtype).tiny
    for _ in range(JACOBI_SWEEPS):
        for i, j in ((0, 1), (0, 2), (1, 2)):
            ai, aj = cols[i], cols[j]
            alpha, beta, gamma = ai @ ai, aj @ aj, ai @ aj
            rotate = jnp.abs(gamma) > tiny
            zeta = (beta - alpha) / jnp.where(rotate, 2.0 * gamma, 1.0)
            t = jnp.where(zeta >= 0, 1.0, -1.0) / (jnp.abs(zeta) + jnp.sqrt(1.0 + zeta * zeta))
            t = jnp.where(rotate & jnp.isfinite(t), t, 0.0)  # |zeta| overflow: already orthogonal
            c = 1.0 / jnp.sqrt(1.0 + t * t)
            s = c * t
            cols[i], cols[j] = c * ai - s * aj, s * ai + c * aj
            v[i], v[j] = c * v[i] - s * v[j], s * v[i] + c * v[j]
    return jnp.stack(cols, axis=1), jnp.stack(v, axis=1)


def guarded_solve(
    a: jnp.ndarray, b: jnp.ndarray, cond_max: jnp.ndarray, sigma_floor: jnp.ndarray
) -> tuple[jnp.ndarray, SolveInfo]:
    """Solve a u = b [3x3] with damped least squares when a is ill-conditioned; always finite.

    The SVD a = U S V^T is a one-sided Jacobi SVD (W = a V = U S), so u = V (S / (S^2 + rho^2)) U^T b
    = sum_i v_i (w_i . b) / (s_i^2 + rho^2).

    Args:
        a: [3, 3] matrix (non-finite entries are treated as 0).
        b: [3] right-hand side (non-finite entries are treated as 0).
        cond_max: condition number above which damping is applied.
        sigma_floor: absolute floor of the singular-value threshold (so a = 0 gives u = 0).

    Returns:
        (u [3], SolveInfo). Equals ``solve(a, b)`` when cond(a) <= cond_max and s_min >= sigma_floor.
    """
    a = jnp.where(jnp.isfinite(a), a, 0.0)
    b = jnp.where(jnp.isfinite(b), b, 0.0)
    w, v = _jacobi_svd3(a)
    sv = jnp.sqrt(jnp.sum(w * w, axis=0))
    s_max, s_min = jnp.max(sv), jnp.min(sv)
    s_th = jnp.maximum(s_max / cond_max, sigma_floor)
    ratio = jnp.minimum(s_min / s_th, 1.0)
    rho2 = (1.0 - ratio * ratio) * s_th * s_th
    u = v @ ((w.T @ b) / (sv * sv + rho2))
    cond = s_max / jnp.maximum(s_min, jnp.finfo(sv.dtype).tiny)
    return u, SolveInfo(cond=cond, rho2=rho2, guard_active=rho2 > 0)


def mu_channel_weight(gamma_rad: jnp.ndarray, gains: SMCGains) -> jnp.ndarray:
    """Weight of the mu sliding mode in the third row: 1 for |gamma| <= lo, 0 for |gamma| >= hi."""
    return smoothstep_falling(jnp.abs(gamma_rad), gains.gamma_lo_rad, gains.gamma_hi_rad)


class SMCTerms(struct.PyTreeNode):
    """Per-step terms of the law (all rad-based): e, e_dot, s [3]; w_mu; the solve diagnostics; the
    decoupling matrix [3, 3] solved with (L_g L_f y, mu row blended), so s_dot is affine in u through it."""

    e: jnp.ndarray
    e_dot: jnp.ndarray
    s: jnp.ndarray
    w_mu: jnp.ndarray
    solve: SolveInfo
    decoupling: jnp.ndarray


def smc_command(
    x: jnp.ndarray,
    reference_rad: jnp.ndarray,
    integral_rad_s: jnp.ndarray,
    params: AircraftParams,
    gains: SMCGains,
    cfg: SMCConfig,
    u_offset_rad: jnp.ndarray | None = None,
) -> tuple[jnp.ndarray, SMCTerms]:
    """The SMC law for a constant reference (y_ref_dot = y_ref_ddot = 0): unsaturated command.

    With ``u_offset_rad`` (the hybrid's learned command u_RL) the law is designed against the
    RL-compensated dynamics y_ddot = L_f^2 y + L_g L_f y (u_RL + u_fb) (paper Sec. V): it returns the
    feedback term u_fb = (L_g L_f y)^-1 (nu - L_f^2 y - L_g L_f y u_RL), so that u_RL + u_fb is the SMC
    command whenever the solve is exact (guard inactive).

    Args:
        x: wind-axis state [10].
        reference_rad: [3] [alpha_d, beta_d, mu_d], rad.
        integral_rad_s: [3] int e dt.
        params: aircraft of the controller model.
        gains: SMCGains.
        cfg: SMCConfig.
        u_offset_rad: [3] command already applied by another law (default none).

    Returns:
        (u [3] rad, unclipped; SMCTerms).
    """
    if cfg.vertical_mu_handling:
        lt, pw = smc_lie_terms(x, params)
    else:
        lt = output_lie_terms(x, params)
    e = lt.y - reference_rad
    e = e.at[MU_CHANNEL].set(wrap_angle_rad(e[MU_CHANNEL]))
    e_dot = lt.lf_y
    s = e_dot + gains.lambda1_ps * e + gains.lambda2_ps2 * integral_rad_s
    if cfg.switching == "sign":
        sw = jnp.sign(s)
    elif cfg.switching == "sat":
        sw = jnp.clip(s / gains.phi_radps, -1.0, 1.0)
    else:
        raise ValueError(f"switching={cfg.switching!r}; allowed: 'sat', 'sign'")
    # nu = y_ref_ddot - l1 e_dot - l2 e - (K |s|^1/2 + eps) sw   (paper prints +l2 e: typo, see above)
    nu = (
        -gains.lambda1_ps * e_dot
        - gains.lambda2_ps2 * e
        - (gains.k_reach * jnp.sqrt(jnp.abs(s)) + gains.eps_radps2) * sw
    )
    a = lt.lglf_y
    b = nu - lt.lf2_y
    if cfg.vertical_mu_handling:
        w = mu_channel_weight(x[WIND_INDEX["gamma"]], gains)
        p_w = pw.h[0]
        # pure mu row is useless (and tan(gamma)-large) near vertical: blend in p_w_dot = -k_pw p_w
        # (where, not 0 * x: at |gamma| = 90 deg exactly the mu terms may be inf/NaN)
        b_mu = jnp.where(w > 0, b[MU_CHANNEL], 0.0)
        a_mu = jnp.where(w > 0, a[MU_CHANNEL], 0.0)
        a = a.at[MU_CHANNEL].set(w * a_mu + (1.0 - w) * pw.lg_h[0])
        b = b.at[MU_CHANNEL].set(w * b_mu + (1.0 - w) * (-gains.k_pw_ps * p_w - pw.lf_h[0]))
    else:
        w = jnp.ones_like(x[WIND_INDEX["gamma"]])
    if u_offset_rad is not None:
        b = b - jnp.where(jnp.isfinite(a), a, 0.0) @ u_offset_rad
    u, solve = guarded_solve(a, b, gains.cond_max, gains.sigma_floor)
    return u, SMCTerms(e=e, e_dot=e_dot, s=s, w_mu=w, solve=solve, decoupling=a)


def update_integral(
    integral_rad_s: jnp.ndarray,
    terms: SMCTerms,
    saturated: jnp.ndarray,
    gains: SMCGains,
    cfg: SMCConfig,
    enabled: jnp.ndarray | bool = True,
) -> jnp.ndarray:
    """Anti-windup update of int e dt [3]: runs only inside the band, not while saturated, not for mu
    in the near-vertical blend, and not when ``enabled`` is False (the hybrid with zeta = 0)."""
    active = (jnp.abs(terms.e) < gains.int_band_rad) & enabled
    if cfg.freeze_integral_when_saturated:
        active = active & ~saturated
    active = active.at[MU_CHANNEL].set(active[MU_CHANNEL] & (terms.w_mu >= 1.0))
    return jnp.clip(
        integral_rad_s + cfg.dt_s * jnp.where(active, terms.e, 0.0),
        -gains.int_clip_rad_s,
        gains.int_clip_rad_s,
    )


def make_smc(cfg: SMCConfig | None = None, gains: SMCGains | None = None) -> Controller:
    """Build the sliding-mode controller.

    Args:
        cfg: static options (default ``SMCConfig()``).
        gains: gains pytree (default ``default_gains()``). Build the controller inside a jitted
            function from traced gains to sweep gains without recompiling.

    Returns:
        Controller(init, apply); ``info`` holds e, e_dot, s [3], u_unsat_rad [3], w_mu, cond, rho2,
        guard_active, saturated, integral_rad_s [3].
    """
    cfg = SMCConfig() if cfg is None else cfg
    gains_ = default_gains() if gains is None else gains

    def init(params: AircraftParams) -> SMCState:
        dtype = jnp.result_type(params.mass_slug)
        z3 = jnp.zeros((3,), dtype=dtype)
        return SMCState(
            params=params,
            integral_rad_s=z3,
            reference_prev_rad=z3,
            has_reference=jnp.asarray(False),
            u_prev_rad=z3,
        )

    def apply(
        state: SMCState, x_wind: jnp.ndarray, reference_rad: jnp.ndarray, key: jax.Array
    ) -> tuple[jnp.ndarray, SMCState, dict[str, jnp.ndarray]]:
        del key  # deterministic
        params = state.params
        integral = state.integral_rad_s
        if cfg.reset_integral_on_reference_change:
            changed = state.has_reference & jnp.any(reference_rad != state.reference_prev_rad)
            integral = jnp.where(changed, 0.0, integral)
        u_raw, terms = smc_command(x_wind, reference_rad, integral, params, gains_, cfg)
        u_raw = jnp.where(jnp.all(jnp.isfinite(u_raw)), u_raw, state.u_prev_rad)
        u = jnp.clip(u_raw, params.u_min_rad, params.u_max_rad)
        saturated = jnp.any(u != u_raw)
        integral = update_integral(integral, terms, saturated, gains_, cfg)
        new_state = state.replace(
            integral_rad_s=integral,
            reference_prev_rad=reference_rad.astype(state.reference_prev_rad.dtype),
            has_reference=jnp.asarray(True),
            u_prev_rad=u,
        )
        info = {
            "e": terms.e,
            "e_dot": terms.e_dot,
            "s": terms.s,
            "u_unsat_rad": u_raw,
            "w_mu": terms.w_mu,
            "cond": terms.solve.cond,
            "rho2": terms.solve.rho2,
            "guard_active": terms.solve.guard_active,
            "saturated": saturated,
            "integral_rad_s": integral,
        }
        return u, new_state, info

    return Controller(init=init, apply=apply)
