"""F-18/HARV aircraft data, parameters and aerodynamic lookup."""

from harv_jax.aircraft.params import AircraftParams, harv

__all__ = ["AircraftParams", "harv"]
