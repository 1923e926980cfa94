"""The reward's weights (paper Section IV-A): each field of ``RewardParams`` declared once, with its default,
its allowed range (a preset's ``[reward]`` table is checked against it, ``env.settings``) and its meaning.

The defaults are the paper's reward. The fields after ``terminal_reward`` are ours
(``experiments/reward_ablation``); their defaults leave the paper's reward unchanged bit for bit.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import jax.numpy as jnp
from flax import struct

from harv_jax.task.criteria import RECOVERED_TOL


def _field(default: float | tuple[float, ...], low: float, high: float, meaning: str) -> Any:
    """A traced RewardParams field with its default, allowed range [low, high] (per element) and meaning."""
    return struct.field(metadata={"default": default, "range": (low, high), "meaning": meaning})


@struct.dataclass
class RewardParams:
    """Reward weights; traced scalars, or per channel (alpha, beta, mu) arrays where the default is a tuple.

    Each field's default, range and meaning are its ``dataclasses.field`` metadata (``reward_fields()``).
    """

    w_p1: jnp.ndarray = _field(0.3, 0.0, 100.0, "phase-1 weight of the coupling term |pq| + |qr| + |pr|")
    w_p21: jnp.ndarray = _field(
        0.3, 0.0, 100.0, "phase-2 weight of e_alpha * q, also the rate weight of the potential"
    )
    w_p22: jnp.ndarray = _field(0.05, 0.0, 100.0, "phase-2 weight of ||omega||^2 + coupling")
    k_blend: jnp.ndarray = _field(10.0, 0.0, 1000.0, "logistic blend steepness, s/rad")
    omega_th_radps: jnp.ndarray = _field(0.17, 0.0, 100.0, "blend threshold on ||omega||, rad/s")
    bonus_alpha: jnp.ndarray = _field(5.0, 0.0, 1000.0, "alpha bonus, paid when |e_alpha| < bonus_tol_rad")
    bonus_beta: jnp.ndarray = _field(3.0, 0.0, 1000.0, "beta bonus, paid when |e_beta| < bonus_tol_rad")
    bonus_mu: jnp.ndarray = _field(3.0, 0.0, 1000.0, "mu bonus, paid when |e_mu| < bonus_tol_rad")
    bonus_tol_rad: jnp.ndarray = _field(0.017, 0.0, math.pi, "bonus tolerance, rad")
    action_weight: jnp.ndarray = _field(
        1.0, 0.0, 1000.0, "weight of the action penalty -sum(a_i^2) on the normalized action"
    )
    discount: jnp.ndarray = _field(0.99, 0.0, 1.0, "PBRS Gamma (the PPO discount)")
    shaping_weight: jnp.ndarray = _field(1.0, 0.0, 1000.0, "multiplier of the PBRS term (0 disables shaping)")
    terminal_reward: jnp.ndarray = _field(-1000.0, -1e7, 0.0, "reward on leaving the envelope")
    bonus_shape: jnp.ndarray = _field(
        0.0, 0.0, 1.0, "0: the paper's indicator bonuses; 1: smooth bands bonus_i exp(-(e_i / w_i)^2)"
    )
    bonus_width_rad: jnp.ndarray = _field(
        (0.017, 0.017, 0.017), 1e-6, math.pi, "band widths w_i of the smooth bonuses, rad"
    )
    w_track: jnp.ndarray = _field(
        (0.0, 0.0, 0.0), 0.0, 1000.0, "weights of the dense terms -w_i min(|e_i| / track_clip_i, 1)"
    )
    track_clip_rad: jnp.ndarray = _field(
        (0.5, 0.5, 0.5), 1e-6, 2.0 * math.pi, "errors at which the dense terms saturate, rad"
    )
    recovered_bonus: jnp.ndarray = _field(
        0.0, 0.0, 1000.0, "paid on every step whose state meets the recovery criterion"
    )
    recovered_tol: jnp.ndarray = _field(
        tuple(RECOVERED_TOL),
        1e-6,
        10.0,
        "tolerances of that criterion: |e_alpha|, |e_beta|, |e_mu| (rad), ||omega|| (rad/s)",
    )
    raw_weight: jnp.ndarray = _field(
        1.0,
        0.0,
        100.0,
        "multiplier of the blended phase rewards r_raw (below 1 the rate damping weighs less)",
    )
    mu_gamma_lo_rad: jnp.ndarray = _field(
        10.0, 0.0, 10.0, "the mu terms (bonus and dense) weigh 1 for |gamma| <= this, rad (10: beyond any)"
    )
    mu_gamma_hi_rad: jnp.ndarray = _field(
        10.0,
        0.0,
        10.0,
        "the mu terms weigh 0 for |gamma| >= this, rad; smoothstep from the lo edge (mu undefined at 90 deg)",
    )
    alpha_v_lo_fps: jnp.ndarray = _field(
        1e6, 0.0, 1e6, "the alpha terms (bonus and dense) weigh 1 for V <= this, ft/s (1e6: beyond any)"
    )
    alpha_v_hi_fps: jnp.ndarray = _field(
        1e6,
        0.0,
        1e6,
        "the alpha terms weigh 0 for V >= this, ft/s; smoothstep from the lo edge (fast: shed energy first)",
    )
    alpha_brake_on: jnp.ndarray = _field(
        0.0,
        0.0,
        1.0,
        "1: the alpha terms track w alpha_d + (1 - w) alpha_brake_rad instead (w the speed weight above)",
    )
    alpha_brake_rad: jnp.ndarray = _field(1.0, -0.5, 1.5, "the high-drag alpha tracked while fast, rad")


def reward_fields() -> tuple[dataclasses.Field, ...]:
    """The fields of ``RewardParams`` in order; ``metadata`` holds default, range and meaning."""
    return dataclasses.fields(RewardParams)


def paper_reward_params(discount: float = 0.99, dtype=None) -> RewardParams:
    """The declared defaults (the paper's reward) with the PBRS ``discount``."""
    dtype = dtype or jnp.result_type(float)
    values = {f.name: f.metadata["default"] for f in reward_fields()} | {"discount": discount}
    return RewardParams(**{k: jnp.asarray(v, dtype=dtype) for k, v in values.items()})
