"""Smoothstep: the C^1 ramp 3 t^2 - 2 t^3 from 0 to 1, and the band weight built on it."""

from __future__ import annotations

import jax.numpy as jnp

#: Narrowest band ``smoothstep_falling`` divides by (lo = hi: a step at lo).
MIN_BAND_WIDTH = 1e-6


def smoothstep(t: jnp.ndarray) -> jnp.ndarray:
    """t^2 (3 - 2 t) of t clipped to [0, 1]: 0 for t <= 0, 1 for t >= 1, zero slope at both ends."""
    t = jnp.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def smoothstep_falling(x: jnp.ndarray, lo: jnp.ndarray, hi: jnp.ndarray) -> jnp.ndarray:
    """Weight 1 for x <= lo, 0 for x >= hi, 1 - smoothstep between (same units for x, lo, hi)."""
    width = jnp.maximum(hi - lo, MIN_BAND_WIDTH)
    return 1.0 - smoothstep((x - lo) / width)
