"""Actuator model: position limits, rate limits and an optional first-order lag (discrete, ZOH)."""

from __future__ import annotations

import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams


def clip_command(cmd_rad: jnp.ndarray, params: AircraftParams) -> jnp.ndarray:
    """Clip a deflection command [3] to the position limits."""
    return jnp.clip(cmd_rad, params.u_min_rad, params.u_max_rad)


def actuator_step(
    delta_rad: jnp.ndarray, cmd_rad: jnp.ndarray, params: AircraftParams, dt_s: float | jnp.ndarray
) -> jnp.ndarray:
    """Advance the surface deflections [3] one step toward the command.

    The command is clipped to the position limits; with ``act_tau_s > 0`` the deflection follows a
    first-order lag (exact discretization), otherwise it moves straight to the command; in both
    cases the change per step is limited by ``u_rate_max_radps * dt_s``.
    """
    target = clip_command(cmd_rad, params)
    tau = params.act_tau_s
    lag_gain = jnp.where(tau > 0, 1.0 - jnp.exp(-dt_s / jnp.where(tau > 0, tau, 1.0)), 1.0)
    step = lag_gain * (target - delta_rad)
    max_step = params.u_rate_max_radps * dt_s
    return clip_command(delta_rad + jnp.clip(step, -max_step, max_step), params)
