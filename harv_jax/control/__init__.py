"""Controllers: owns the shared interface (``base.Controller(init, apply)``), the Lie derivatives of the
controller model (``lie``), sliding-mode control (``smc``) and the SMC with an energy-braking alpha
reference (``smc_brake``), the safety filter, zeta schedules, gate and supervisor, the hybrid (``hybrid``) and
the RL-only controller (``rl``). Observation/action mapping and reset bounds come from ``harv_jax.task``;
``control`` never imports ``env`` or ``evaluation``."""

import importlib
from typing import Any

#: Public names and the module that defines each, imported on first use (PEP 562): importing a submodule such
#: as ``harv_jax.control.registry`` does not load jax, so the command line checks its arguments first.
_EXPORTS = {
    "Controller": "harv_jax.control.base",
    "Y_INDEX": "harv_jax.control.lie",
    "controller_model": "harv_jax.control.lie",
    "output_lie_terms": "harv_jax.control.lie",
    "roll_rate_lie_terms": "harv_jax.control.lie",
    "wind_roll_rate_radps": "harv_jax.control.lie",
    "SMCConfig": "harv_jax.control.smc",
    "SMCGains": "harv_jax.control.smc",
    "SMCState": "harv_jax.control.smc",
    "default_gains": "harv_jax.control.smc",
    "guarded_solve": "harv_jax.control.smc",
    "make_smc": "harv_jax.control.smc",
    "BrakeSchedule": "harv_jax.control.smc_brake",
    "SMCBrakeState": "harv_jax.control.smc_brake",
    "brake_schedule": "harv_jax.control.smc_brake",
    "make_smc_brake": "harv_jax.control.smc_brake",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
