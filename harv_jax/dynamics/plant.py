"""The plant step, defined once: actuator -> RK4 of the body-axis state -> wind-axis view.

Used by the env step, the closed loop (``evaluation.closed_loop``), the open-loop scenarios and the spin
bank (``task.scenarios``, ``task.spin_bank``) and ``rollout``; every caller gets the same operations in
the same order, so their results agree bit for bit.

    delta_k+1 = actuator_step(delta_k, cmd_k, params, dt_s)          (position + rate limits, optional lag)
    state_k+1 = rk4_body_step(state_k, delta_k+1, params, dt_s, wind)  (singularity-free body form)
    x_k+1     = to_wind(state_k+1)                                     (wind-axis view [10])
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics.actuators import actuator_step
from harv_jax.dynamics.integrate import rk4_body_step
from harv_jax.dynamics.state import BodyState, from_wind, to_wind


class PlantStep(NamedTuple):
    """What one plant step produces.

    Attributes:
        body: BodyState after the step.
        delta_rad: [3] deflections applied over the step (after the actuator), rad.
        x_wind: [10] wind-axis view of ``body`` (unused outputs cost nothing under jit).
    """

    body: BodyState
    delta_rad: jnp.ndarray
    x_wind: jnp.ndarray


def rigid_body_step(
    body: BodyState,
    delta_rad: jnp.ndarray,
    params: AircraftParams,
    dt_s: float | jnp.ndarray,
    wind_body_fps: jnp.ndarray | None = None,
    wind_pqr_radps: jnp.ndarray | None = None,
) -> tuple[BodyState, jnp.ndarray]:
    """RK4 with the deflections ``delta_rad`` [3] held over the step, then the wind view: (body, x_wind)."""
    new = rk4_body_step(body, delta_rad, params, dt_s, wind_body_fps, wind_pqr_radps)
    return new, to_wind(new)


def plant_step(
    body: BodyState,
    delta_rad: jnp.ndarray,
    cmd_rad: jnp.ndarray,
    params: AircraftParams,
    dt_s: float | jnp.ndarray,
    wind_body_fps: jnp.ndarray | None = None,
    wind_pqr_radps: jnp.ndarray | None = None,
) -> PlantStep:
    """One plant step from deflections ``delta_rad`` [3] toward the command ``cmd_rad`` [3], rad.

    Args:
        body: integration state.
        delta_rad: [3] current deflections, rad.
        cmd_rad: [3] deflection command, rad (clipped and rate limited by the actuator).
        params: aircraft.
        dt_s: step, s.
        wind_body_fps: optional [3] body-axis wind (gust, turbulence), ft/s.
        wind_pqr_radps: optional [3] body-axis rotation rate of the air (turbulence), rad/s.

    Returns:
        PlantStep(body, delta_rad, x_wind) after the step.
    """
    delta_new = actuator_step(delta_rad, cmd_rad, params, dt_s)
    new, x_wind = rigid_body_step(body, delta_new, params, dt_s, wind_body_fps, wind_pqr_radps)
    return PlantStep(new, delta_new, x_wind)


def rollout(
    x0: BodyState | jnp.ndarray,
    u_seq: jnp.ndarray,
    params: AircraftParams,
    dt_s: float | jnp.ndarray,
) -> jnp.ndarray:
    """Open-loop rollout with ``lax.scan`` in the body form, deflections given per step (no actuator).

    Args:
        x0: initial wind-axis state [10] or BodyState.
        u_seq: [T, 3] deflections per step, rad.
        params: aircraft parameters.
        dt_s: step, s.

    Returns:
        [T + 1, 10] wind-axis states (initial state first). x_N, y_E are not returned.
    """
    if jnp.ndim(u_seq) != 2 or jnp.shape(u_seq)[1] != 3:
        raise ValueError(f"u_seq has shape {list(jnp.shape(u_seq))}, expected [T, 3] (de, da, dr per step)")
    body0 = x0 if isinstance(x0, BodyState) else from_wind(x0)

    def step(s, u):
        return rigid_body_step(s, u, params, dt_s)

    _, xs = jax.lax.scan(step, body0, u_seq)
    return jnp.concatenate([to_wind(body0)[None], xs], axis=0)
