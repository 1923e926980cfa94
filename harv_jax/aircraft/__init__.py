"""The F-18/HARV aircraft: owns its data (``data_harv``, cited tables and mass properties), the parameter
pytree (``params``; its static aerodynamic table: ``aero_table``), the jittable aerodynamic lookup (``aero``),
the aircraft randomization (``randomize``: mass, inertia and aero draws, used by the env and the evaluation)
and the aircraft by name (``registry``: ``"harv"``, the default, and any registered one). Imports only
``units``."""

from harv_jax.aircraft.aero_table import AeroTable
from harv_jax.aircraft.params import AircraftParams, harv
from harv_jax.aircraft.registry import (
    DEFAULT_AIRCRAFT,
    aircraft_names,
    get_aircraft,
    register_aircraft,
    unregister_aircraft,
)

__all__ = [
    "DEFAULT_AIRCRAFT",
    "AeroTable",
    "AircraftParams",
    "aircraft_names",
    "get_aircraft",
    "harv",
    "register_aircraft",
    "unregister_aircraft",
]
