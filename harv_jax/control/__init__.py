"""Controllers: owns the shared interface (``base.Controller(init, apply)``), the Lie derivatives of the
controller model (``lie``), sliding-mode control (``smc``), the safety filter, zeta schedules, gate and
supervisor, the hybrid (``hybrid``) and the RL-only controller (``rl``). Observation/action mapping and
reset bounds come from ``harv_jax.task``; ``control`` never imports ``env`` or ``evaluation``."""

from harv_jax.control.base import Controller
from harv_jax.control.lie import (
    Y_INDEX,
    controller_model,
    output_lie_terms,
    roll_rate_lie_terms,
    wind_roll_rate_radps,
)
from harv_jax.control.smc import SMCConfig, SMCGains, SMCState, default_gains, guarded_solve, make_smc

__all__ = [
    "Y_INDEX",
    "Controller",
    "SMCConfig",
    "SMCGains",
    "SMCState",
    "controller_model",
    "default_gains",
    "guarded_solve",
    "make_smc",
    "output_lie_terms",
    "roll_rate_lie_terms",
    "wind_roll_rate_radps",
]
