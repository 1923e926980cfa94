"""The F-18/HARV aircraft: owns its data (``data_harv``, cited tables and mass properties), the parameter
pytree (``params``), the jittable aerodynamic lookup (``aero``) and the aircraft randomization
(``randomize``: mass, inertia and aero draws, used by the env and the evaluation). Imports only ``units``."""

from harv_jax.aircraft.params import AircraftParams, harv

__all__ = ["AircraftParams", "harv"]
