"""Elementwise safety filter of the hybrid controller (minimal modification, per channel).

Two stages, both clips (the Euclidean projection onto a box, hence the minimal modification and
idempotent):

1. authority cap on the learned command: u_RL in [frac * u_min, frac * u_max] per channel (``frac`` in
   (0, 1]; 1 leaves u_RL alone, since the policy's command already lies in [u_min, u_max]);
2. limits on the total command: position limits and rate limits relative to the previous filtered
   command, i.e. the box [max(u_min, u_prev - r dt), min(u_max, u_prev + r dt)], which always contains
   u_prev (itself within the position limits), so it is never empty.

Flags say which channels each stage changed (its interventions).
"""

from __future__ import annotations

import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams


def cap_authority(
    u_rl_rad: jnp.ndarray, params: AircraftParams, authority_frac: jnp.ndarray
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Clip the learned command [3] to ``authority_frac`` (scalar or [3]) of each deflection range.

    Returns:
        (capped u_RL [3] rad, bool [3] channels changed).
    """
    capped = jnp.clip(u_rl_rad, authority_frac * params.u_min_rad, authority_frac * params.u_max_rad)
    return capped, capped != u_rl_rad


def limit_box(
    u_prev_rad: jnp.ndarray, params: AircraftParams, dt_s: float | jnp.ndarray
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """The admissible command box (lo [3], hi [3]) after ``u_prev_rad``: position and rate limits."""
    step = params.u_rate_max_radps * dt_s
    lo = jnp.maximum(params.u_min_rad, u_prev_rad - step)
    hi = jnp.minimum(params.u_max_rad, u_prev_rad + step)
    return lo, jnp.maximum(hi, lo)


def filter_command(
    u_rad: jnp.ndarray, u_prev_rad: jnp.ndarray, params: AircraftParams, dt_s: float | jnp.ndarray
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Clip a total command [3] into the position/rate box after ``u_prev_rad``.

    Returns:
        (filtered u [3] rad, bool [3] channels changed).
    """
    lo, hi = limit_box(u_prev_rad, params, dt_s)
    u = jnp.clip(u_rad, lo, hi)
    return u, u != u_rad
