"""Why an episode ends: the envelope checks of one step (``task.criteria.Envelope``, the paper's ranges).

Terminations: non-finite state, V outside (v_min, v_max], alpha outside [alpha_min, alpha_max], any |p|,
|q|, |r| > rate_max, |gamma| > gamma_max, h < h_floor. The time limit is a truncation (``env.recovery``).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from harv_jax.dynamics.state import alpha_rad, gamma_rad, h_ft, omega_radps, vt_fps
from harv_jax.task.criteria import Envelope


class TerminationFlags(NamedTuple):
    """Why an episode terminated (bool scalars); ``any`` is the termination."""

    nonfinite: jnp.ndarray
    speed: jnp.ndarray
    alpha: jnp.ndarray
    rates: jnp.ndarray
    gamma: jnp.ndarray
    altitude: jnp.ndarray

    @property
    def any(self) -> jnp.ndarray:
        return self.nonfinite | self.speed | self.alpha | self.rates | self.gamma | self.altitude


def termination_flags(x_wind: jnp.ndarray, finite: jnp.ndarray, envelope: Envelope) -> TerminationFlags:
    """Envelope checks on a wind-axis state [10] (``finite``: the integration state is finite).

    Comparisons with NaN are False, so a non-finite state raises only ``nonfinite``.
    """
    vt, alpha, pqr, gamma, h = (
        vt_fps(x_wind),
        alpha_rad(x_wind),
        omega_radps(x_wind),
        gamma_rad(x_wind),
        h_ft(x_wind),
    )
    return TerminationFlags(
        nonfinite=~finite,
        speed=(vt <= envelope.v_min_fps) | (vt > envelope.v_max_fps),
        alpha=(alpha < envelope.alpha_min_rad) | (alpha > envelope.alpha_max_rad),
        rates=jnp.any(jnp.abs(pqr) > envelope.rate_max_radps),
        gamma=jnp.abs(gamma) > envelope.gamma_max_rad,
        altitude=h < envelope.h_floor_ft,
    )
