"""The flight model: owns the state and its named views (``state``), the atmosphere, the equations of
motion (``eom``), the actuators, RK4 integration, the one plant step (``plant``: actuator -> RK4 -> wind
view), what lies between a controller and the aircraft (``disturbances``, ``turbulence`` and the one
disturbed step that flies them, ``disturbed_step``) and trim (``trim``). Imports only ``aircraft`` and
``units``."""

from harv_jax.dynamics.actuators import actuator_step, clip_command
from harv_jax.dynamics.eom import body_derivatives, derivatives, forces_moments
from harv_jax.dynamics.integrate import rk4_body_step, rk4_step, rk4_step_wind
from harv_jax.dynamics.plant import PlantStep, plant_step, rigid_body_step, rollout
from harv_jax.dynamics.state import (
    CONTROL_NAMES,
    WIND_INDEX,
    WIND_STATE_NAMES,
    BodyState,
    from_wind,
    is_finite,
    to_wind,
)

__all__ = [
    "CONTROL_NAMES",
    "WIND_INDEX",
    "WIND_STATE_NAMES",
    "BodyState",
    "PlantStep",
    "actuator_step",
    "body_derivatives",
    "clip_command",
    "derivatives",
    "forces_moments",
    "from_wind",
    "is_finite",
    "plant_step",
    "rigid_body_step",
    "rk4_body_step",
    "rk4_step",
    "rk4_step_wind",
    "rollout",
    "to_wind",
]
