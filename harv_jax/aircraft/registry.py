"""Aircraft by name: the nominal aircraft of every study, the env and the command line.

``"harv"`` (``params.harv``) is registered and is the default (`DEFAULT_AIRCRAFT`). A user's aircraft
is a factory returning ``AircraftParams`` (e.g. ``harv()`` with other mass properties, or another
``AeroTable``) registered under a new name; the commands then fly it with ``--aircraft NAME``.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams, harv

#: Name of the nominal aircraft when none is given.
DEFAULT_AIRCRAFT = "harv"
#: Recorded name of an aircraft given as ``AircraftParams`` rather than by name.
CUSTOM_AIRCRAFT = "custom"

_FACTORIES: dict[str, Callable[[], AircraftParams]] = {DEFAULT_AIRCRAFT: harv}


def aircraft_names() -> tuple[str, ...]:
    """Registered names, the default first."""
    return tuple(_FACTORIES)


def check_aircraft_name(name: str) -> str:
    """``name`` if registered; ValueError (one line naming it and the allowed names) otherwise."""
    if not isinstance(name, str) or name not in _FACTORIES:
        raise ValueError(f"unknown aircraft {name!r}; allowed: {', '.join(aircraft_names())}")
    return name


def register_aircraft(name: str, factory: Callable[[], AircraftParams]) -> None:
    """Register ``factory`` (no arguments, returns unbatched ``AircraftParams``) under a new ``name``.

    Raises:
        ValueError: ``name`` is empty, has a comma or whitespace, or is already registered.
    """
    if not isinstance(name, str) or not name or any(c.isspace() or c == "," for c in name):
        raise ValueError(f"aircraft name {name!r} must be a non-empty word without commas or spaces")
    if name in _FACTORIES:
        raise ValueError(f"aircraft {name!r} is already registered; choose another name")
    if not callable(factory):
        raise ValueError(f"aircraft {name!r}: the factory must be callable, got {type(factory).__name__}")
    _FACTORIES[name] = factory


def unregister_aircraft(name: str) -> None:
    """Remove a registered aircraft (not the default); ValueError for an unknown name or the default."""
    check_aircraft_name(name)
    if name == DEFAULT_AIRCRAFT:
        raise ValueError(f"aircraft {name!r} is the default and cannot be removed")
    del _FACTORIES[name]


def get_aircraft(name: str = DEFAULT_AIRCRAFT, throttle: float | None = None, dtype=None) -> AircraftParams:
    """The aircraft registered as ``name``.

    Args:
        name: a name of [`aircraft_names`][].
        throttle: fixed throttle in [0, 1] (None: the factory's).
        dtype: float dtype of every leaf (None: jax's default float).

    Raises:
        ValueError: an unknown name, a throttle outside [0, 1], or a factory that returns no
            ``AircraftParams``.
    """
    params = _FACTORIES[check_aircraft_name(name)]()
    if not isinstance(params, AircraftParams):
        kind = type(params).__name__
        raise ValueError(f"aircraft {name!r}: the factory returned {kind}, not AircraftParams")
    dtype = jnp.result_type(float) if dtype is None else dtype
    params = jax.tree.map(lambda a: jnp.asarray(a, dtype=dtype), params)
    if throttle is not None:
        if not 0.0 <= throttle <= 1.0:
            raise ValueError(f"throttle={throttle!r} is outside [0, 1]")
        params = params.replace(throttle=jnp.asarray(throttle, dtype=dtype))
    return params


def resolve_aircraft(aircraft: str | AircraftParams | None) -> tuple[str, AircraftParams]:
    """(recorded name, params) of a study's ``aircraft`` argument: None is the default, a string a
    registered name, ``AircraftParams`` itself (recorded as `CUSTOM_AIRCRAFT`)."""
    if aircraft is None:
        aircraft = DEFAULT_AIRCRAFT
    if isinstance(aircraft, AircraftParams):
        return CUSTOM_AIRCRAFT, aircraft
    return aircraft, get_aircraft(aircraft)
