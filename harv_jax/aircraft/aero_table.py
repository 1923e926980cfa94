"""An aircraft's aerodynamic table as a static, hashable value (``AircraftParams.aero_table``).

The table is a compile-time constant of the traced model (a static field of the parameter pytree): two
aircraft with equal tables share compiled code, another table compiles anew. Per-run aerodynamic
uncertainty stays traced in ``AircraftParams.aero_scale``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from harv_jax.aircraft.data_harv import AERO_COLUMNS, AERO_TABLE_PER_RAD, ALPHA_DEG_GRID


class AeroTable:
    """A read-only [27, 33] table on ``ALPHA_DEG_GRID`` (rows) and ``AERO_COLUMNS`` (columns): cd0, clift0,
    cm0 dimensionless, every other column per radian. Equal and hashed by value.

    Args:
        per_rad: the table, shape ``(len(ALPHA_DEG_GRID), len(AERO_COLUMNS))``, finite.
    """

    __slots__ = ("_hash", "per_rad")

    def __init__(self, per_rad: np.ndarray) -> None:
        table = np.array(per_rad, dtype=np.float64)
        shape = (len(ALPHA_DEG_GRID), len(AERO_COLUMNS))
        if table.shape != shape:
            raise ValueError(f"aero table has shape {table.shape}; needs {shape} (alpha rows x columns)")
        if not np.all(np.isfinite(table)):
            raise ValueError("aero table has a value that is not finite")
        table.flags.writeable = False
        self.per_rad = table
        self._hash = hash(table.tobytes())

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, AeroTable):
            return NotImplemented
        return self is other or (self._hash == other._hash and np.array_equal(self.per_rad, other.per_rad))

    def __hash__(self) -> int:
        return self._hash

    def __repr__(self) -> str:
        return f"AeroTable(hash={self._hash & 0xFFFFFFFF:08x})"

    def scaled(self, factors: Mapping[str, float]) -> AeroTable:
        """This table with each named column (``AERO_COLUMNS``) times its factor."""
        unknown = [c for c in factors if c not in AERO_COLUMNS]
        if unknown:
            raise ValueError(f"unknown aero column {unknown[0]!r}; allowed: {', '.join(AERO_COLUMNS)}")
        scale = np.array([factors.get(c, 1.0) for c in AERO_COLUMNS], dtype=np.float64)
        return AeroTable(self.per_rad * scale)


#: The F-18/HARV table (``data_harv.AERO_TABLE_PER_RAD``).
HARV_AERO_TABLE = AeroTable(AERO_TABLE_PER_RAD)
