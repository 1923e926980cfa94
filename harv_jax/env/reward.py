"""The paper's reward (Section IV-A), term by term; pure functions of scalars, vmappable.

| symbol      | meaning                                                        | unit   |
|-------------|----------------------------------------------------------------|--------|
| omega       | body rates [p, q, r]                                           | rad/s  |
| ||omega||   | sqrt(p^2 + q^2 + r^2)                                          | rad/s  |
| coupling    | |pq| + |qr| + |pr|                                             | rad^2/s^2 |
| e_alpha ... | alpha - alpha_d, beta - beta_d, wrap(mu - mu_d) to (-pi, pi]   | rad    |
| eps         | logistic blend 1 / (1 + exp(k (||omega|| - omega_th)))         | -      |
| sigma       | PBRS potential -e_alpha^2 - w_p21 ||omega||^2                  | -      |

The errors are ``harv_jax.task.criteria.tracking_errors`` (the evaluation's).

    r_phase1 = -||omega||^2 - w_p1 coupling
    r_phase2 = -e_alpha^2 - w_p21 e_alpha q - w_p22 (||omega||^2 + coupling)
    r_raw    = (1 - eps) r_phase1 + eps r_phase2
    bonus    = +5 [|e_alpha| < 0.017] + 3 [|e_beta| < 0.017] + 3 [|e_mu| < 0.017]
    action   = -sum_i a_i^2          (a = the normalized action in [-1, 1]^3)
    shaping  = Gamma sigma_{t+1} - sigma_t
    reward   = r_raw + bonus + action + shaping                        (non-terminal step, paper)

Our additions (``RewardParams`` fields after ``terminal_reward``; at their defaults the reward is the
paper's bit for bit, ``tests/test_reward.py``):

    bonus_i     = bonus_i exp(-(e_i / w_i)^2)            when bonus_shape = 1 (smooth bands)
    dense_i     = -w_track_i min(|e_i| / track_clip_i, 1)   (clipped L1 per channel, Dally & van Kampen)
    recovered   = +recovered_bonus [all of |e_alpha|, |e_beta|, |e_mu|, ||omega|| below recovered_tol]
    r_raw       = raw_weight ((1 - eps) r_phase1 + eps r_phase2)     (paper: raw_weight = 1)
    w_mu(gamma) = 1 - smoothstep((|gamma| - mu_gamma_lo) / (mu_gamma_hi - mu_gamma_lo)) multiplies the mu
                  bonus and dense_mu (paper: 1 at every gamma)
    w_alpha(V)  = 1 - smoothstep((V - alpha_v_lo) / (alpha_v_hi - alpha_v_lo)) multiplies the alpha bonus and
                  dense_alpha (paper: 1 at every V); with alpha_brake_on = 1 instead the alpha bonus and
                  dense_alpha are paid on alpha - (w_alpha alpha_d + (1 - w_alpha) alpha_brake)
    reward      = paper reward + dense + recovered                 (non-terminal step)
    reward   = terminal_reward + (Gamma * 0 - sigma_t)                 (terminating step)

The paper lists the bonuses and the action penalty as "Additional Reward" next to the blended phases, so
they are added outside the blend. All state terms are evaluated at the state reached by the step
(s_{t+1}); sigma_t is the potential of the state the step started from.

Terminal step: the episode ends in an absorbing state whose potential is defined as 0 (Ng, Harada &
Russell 1999), so the shaping is -sigma_t and the discounted shaping of any episode telescopes to
Gamma^T sigma_T - sigma_0 with sigma_T = 0 on termination (policy invariance is kept). The performance
terms of a terminating step (possibly non-finite there) are not paid and are reported as 0: the step
pays ``terminal_reward`` (paper -1000) plus that shaping. On a truncation (time limit) s_{t+1} is an
ordinary state: the step is rewarded normally and the learner bootstraps from it.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from harv_jax.dynamics.state import alpha_rad, gamma_rad, omega_radps, vt_fps
from harv_jax.env.reward_params import RewardParams
from harv_jax.smooth import smoothstep_falling
from harv_jax.task.criteria import tracking_errors


class RewardTerms(NamedTuple):
    """Every reward term of one step, separately (scalars; ``total`` is what the learner gets)."""

    phase1: jnp.ndarray
    phase2: jnp.ndarray
    blend: jnp.ndarray
    raw: jnp.ndarray
    bonus_alpha: jnp.ndarray
    bonus_beta: jnp.ndarray
    bonus_mu: jnp.ndarray
    action: jnp.ndarray
    shaping: jnp.ndarray
    terminal: jnp.ndarray
    dense_alpha: jnp.ndarray
    dense_beta: jnp.ndarray
    dense_mu: jnp.ndarray
    recovered: jnp.ndarray
    total: jnp.ndarray


def omega_norm_sq(pqr_radps: jnp.ndarray) -> jnp.ndarray:
    """||omega||^2 = p^2 + q^2 + r^2, rad^2/s^2, of body rates [3]."""
    return jnp.sum(pqr_radps * pqr_radps, axis=-1)


def coupling(pqr_radps: jnp.ndarray) -> jnp.ndarray:
    """Cross-coupling |pq| + |qr| + |pr|, rad^2/s^2, of body rates [3]."""
    p, q, r = pqr_radps[..., 0], pqr_radps[..., 1], pqr_radps[..., 2]
    return jnp.abs(p * q) + jnp.abs(q * r) + jnp.abs(p * r)


def phase1(pqr_radps: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """Phase-1 (rate damping) reward -||omega||^2 - w_p1 (|pq| + |qr| + |pr|)."""
    return -omega_norm_sq(pqr_radps) - params.w_p1 * coupling(pqr_radps)


def phase2(e_alpha_rad: jnp.ndarray, pqr_radps: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """Phase-2 (attitude) reward -e_alpha^2 - w_p21 e_alpha q - w_p22 (||omega||^2 + coupling)."""
    q = pqr_radps[..., 1]
    return (
        -e_alpha_rad * e_alpha_rad
        - params.w_p21 * e_alpha_rad * q
        - params.w_p22 * (omega_norm_sq(pqr_radps) + coupling(pqr_radps))
    )


def blend(omega_norm_radps: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """Logistic gate eps = 1 / (1 + exp(k (||omega|| - omega_th))) in (0, 1); eps -> 1 at low rates.

    Computed as sigmoid(-k (||omega|| - omega_th)), which is the same function without overflow.
    """
    return jax.nn.sigmoid(-params.k_blend * (omega_norm_radps - params.omega_th_radps))


def raw(pqr_radps: jnp.ndarray, e_alpha_rad: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """r_raw = raw_weight ((1 - eps) r_phase1 + eps r_phase2) (raw_weight 1, the paper's: x * 1.0 == x)."""
    eps = blend(jnp.sqrt(omega_norm_sq(pqr_radps)), params)
    blended = (1.0 - eps) * phase1(pqr_radps, params) + eps * phase2(e_alpha_rad, pqr_radps, params)
    return params.raw_weight * blended


def bonuses(errors_rad: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """[bonus_alpha, bonus_beta, bonus_mu]: the paper's (each paid when its |error| < bonus_tol_rad, strict)
    or, when ``bonus_shape`` = 1, smooth bands bonus_i exp(-(e_i / bonus_width_i)^2)."""
    inside = jnp.abs(errors_rad) < params.bonus_tol_rad
    amounts = jnp.stack([params.bonus_alpha, params.bonus_beta, params.bonus_mu])
    indicator = jnp.where(inside, amounts, jnp.zeros_like(amounts))
    smooth = amounts * jnp.exp(-jnp.square(errors_rad / params.bonus_width_rad))
    return jnp.where(params.bonus_shape > 0.5, smooth, indicator)


def mu_weight(gamma_rad: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """Weight of the mu terms: 1 for |gamma| <= mu_gamma_lo_rad, 0 for |gamma| >= mu_gamma_hi_rad."""
    return smoothstep_falling(jnp.abs(gamma_rad), params.mu_gamma_lo_rad, params.mu_gamma_hi_rad)


def alpha_weight(v_fps: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """Weight of the alpha terms: 1 for V <= alpha_v_lo_fps, 0 for V >= alpha_v_hi_fps."""
    return smoothstep_falling(v_fps, params.alpha_v_lo_fps, params.alpha_v_hi_fps)


def dense_tracking(errors_rad: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """[3] dense per-channel terms -w_track_i min(|e_i| / track_clip_i, 1)."""
    return -params.w_track * jnp.minimum(jnp.abs(errors_rad) / params.track_clip_rad, 1.0)


def recovered_term(errors_rad: jnp.ndarray, pqr_radps: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """+recovered_bonus when |e_alpha|, |e_beta|, |e_mu| and ||omega|| are all below ``recovered_tol``."""
    inside = jnp.all(jnp.abs(errors_rad) < params.recovered_tol[:3]) & (
        jnp.sqrt(omega_norm_sq(pqr_radps)) < params.recovered_tol[3]
    )
    return jnp.where(inside, params.recovered_bonus, jnp.zeros_like(params.recovered_bonus))


def action_penalty(action: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """-action_weight * sum_i a_i^2 of the normalized action [3]."""
    return -params.action_weight * jnp.sum(action * action, axis=-1)


def potential(e_alpha_rad: jnp.ndarray, pqr_radps: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """PBRS potential sigma = -e_alpha^2 - w_p21 ||omega||^2 (paper eq. pbrs)."""
    return -e_alpha_rad * e_alpha_rad - params.w_p21 * omega_norm_sq(pqr_radps)


def shaping(potential_next: jnp.ndarray, potential_prev: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """PBRS term shaping_weight * (Gamma sigma_{t+1} - sigma_t)."""
    return params.shaping_weight * (params.discount * potential_next - potential_prev)


def state_potential(x_wind: jnp.ndarray, target_rad: jnp.ndarray, params: RewardParams) -> jnp.ndarray:
    """sigma of a wind-axis state [10] for a target [3]."""
    return potential(alpha_rad(x_wind) - target_rad[0], omega_radps(x_wind), params)


def reward_terms(
    x_wind: jnp.ndarray,
    target_rad: jnp.ndarray,
    action: jnp.ndarray,
    potential_prev: jnp.ndarray,
    terminated: jnp.ndarray,
    params: RewardParams,
    recovered_inside: jnp.ndarray | None = None,
) -> tuple[RewardTerms, jnp.ndarray]:
    """All reward terms of one step and the potential of the new state.

    Args:
        x_wind: [10] wind-axis state reached by the step (s_{t+1}).
        target_rad: [3] target [alpha_d, beta_d, mu_d], rad.
        action: [3] normalized action actually applied (clipped to [-1, 1]).
        potential_prev: sigma_t of the state the step started from.
        terminated: bool, the step left the envelope (s_{t+1} is absorbing, sigma = 0).
        params: reward weights.
        recovered_inside: whether the state counts as recovered for the recovered bonus (the env in
            turbulence: the criterion in turbulence's filtered bands, ``task.turbulent_criterion``);
            default: every error and the rate norm below ``recovered_tol``.

    Returns:
        (RewardTerms, sigma_{t+1}); sigma_{t+1} is the potential of x_wind (not zeroed on termination;
        it may be non-finite there; the env replaces the state on termination anyway).
    """
    pqr = omega_radps(x_wind)
    errors = tracking_errors(x_wind, target_rad)
    e_alpha = errors[0]
    eps = blend(jnp.sqrt(omega_norm_sq(pqr)), params)
    r1 = phase1(pqr, params)
    r2 = phase2(e_alpha, pqr, params)
    r_raw = raw(pqr, e_alpha, params)
    w_mu = mu_weight(gamma_rad(x_wind), params)  # exactly 1 at the paper's settings: x * 1.0 == x
    w_alpha = alpha_weight(vt_fps(x_wind), params)  # exactly 1 at the paper's settings
    brake = params.alpha_brake_on > 0.5  # off (paper): the errors and weights are taken as they are
    shift = (1.0 - w_alpha) * (target_rad[0] - params.alpha_brake_rad)
    track_errors = jnp.where(brake, errors.at[0].add(shift), errors)
    w_alpha = jnp.where(brake, jnp.ones_like(w_alpha), w_alpha)
    channel_w = jnp.stack([w_alpha, jnp.ones_like(w_mu), w_mu])
    bonus = bonuses(track_errors, params) * channel_w
    r_action = action_penalty(action, params)
    pot_next = potential(e_alpha, pqr, params)
    pot_target = jnp.where(terminated, jnp.zeros_like(pot_next), pot_next)
    r_shaping = shaping(pot_target, potential_prev, params)
    dense = dense_tracking(track_errors, params) * channel_w
    r_recovered = recovered_term(errors, pqr, params)
    if recovered_inside is not None:
        r_recovered = jnp.where(
            recovered_inside, params.recovered_bonus, jnp.zeros_like(params.recovered_bonus)
        )
    zero = jnp.zeros_like(r_raw)
    r_terminal = jnp.where(terminated, params.terminal_reward, zero)
    # the paper's sum first, our terms added after it: zero weights leave it bit for bit
    performance = (r_raw + jnp.sum(bonus) + r_action) + (jnp.sum(dense) + r_recovered)
    total = jnp.where(terminated, r_terminal, performance) + r_shaping
    # the performance terms, paid only on a non-terminating step (reported as 0 on a terminating one)
    paid = {
        "phase1": r1,
        "phase2": r2,
        "blend": eps,
        "raw": r_raw,
        "bonus_alpha": bonus[0],
        "bonus_beta": bonus[1],
        "bonus_mu": bonus[2],
        "action": r_action,
        "dense_alpha": dense[0],
        "dense_beta": dense[1],
        "dense_mu": dense[2],
        "recovered": r_recovered,
    }
    terms = RewardTerms(
        **{k: jnp.where(terminated, zero, v) for k, v in paid.items()},
        shaping=r_shaping,
        terminal=r_terminal,
        total=total,
    )
    return terms, pot_next
