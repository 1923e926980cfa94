"""Flight model: wind-axis derivatives (the paper's), body-axis integration, actuators."""

from harv_jax.dynamics.actuators import actuator_step, clip_command
from harv_jax.dynamics.eom import body_derivatives, derivatives, forces_moments
from harv_jax.dynamics.integrate import rk4_body_step, rk4_step, rk4_step_wind, rollout
from harv_jax.dynamics.state import (
    CONTROL_NAMES,
    WIND_STATE_NAMES,
    BodyState,
    from_wind,
    is_finite,
    to_wind,
)

__all__ = [
    "CONTROL_NAMES",
    "WIND_STATE_NAMES",
    "BodyState",
    "actuator_step",
    "body_derivatives",
    "clip_command",
    "derivatives",
    "forces_moments",
    "from_wind",
    "is_finite",
    "rk4_body_step",
    "rk4_step",
    "rk4_step_wind",
    "rollout",
    "to_wind",
]
