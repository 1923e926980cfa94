"""Raw F-18/HARV data as numpy constants, loaded once from the package's CSV files.

Sources (see ``data/harv_aero_table.README.md`` for the full provenance):
- Aerodynamic table: IIT Madras F-18 HARV model, ``F18HARVdata.m`` in the public repository
  willcmc/f18-env (commit aa618f6, unchanged at e36ac2f). 27 alpha breakpoints (-14..90 deg, step 4),
  33 coefficient columns; cd0, clift0, cm0 dimensionless, every other column per degree.
- Mass, inertia, geometry, thrust: the ``IITM_willcmc`` row of ``data/harv_mass_geometry.csv``.
"""

from __future__ import annotations

import csv
from importlib import resources

import numpy as np

from harv_jax.units import DEG_PER_RAD

_DATA = resources.files("harv_jax.aircraft") / "data"

#: Column names of the aero table, in the HARV_aero.m order (without alpha_deg).
AERO_COLUMNS: tuple[str, ...] = (
    "cy_b", "cy_p", "cy_r", "cy_da", "cy_del", "cy_der", "cy_dr",
    "croll_b", "croll_p", "croll_r", "croll_da", "croll_del", "croll_der", "croll_dr",
    "cn_b", "cn_p", "cn_r", "cn_da", "cn_del", "cn_der", "cn_dr",
    "cd0", "cd_q", "cd_del", "cd_der", "clift0", "clift_q", "clift_del", "clift_der",
    "cm0", "cm_q", "cm_del", "cm_der",
)  # fmt: skip
#: Dimensionless columns; all others are per degree (of angle or of non-dimensional rate).
DIMENSIONLESS_COLUMNS: tuple[str, ...] = ("cd0", "clift0", "cm0")

ALPHA_MIN_DEG = -14.0
ALPHA_MAX_DEG = 90.0
ALPHA_STEP_DEG = 4.0


def _load_aero_table() -> tuple[np.ndarray, np.ndarray]:
    with (_DATA / "harv_aero_table.csv").open() as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    if tuple(header[1:]) != AERO_COLUMNS or header[0] != "alpha_deg":
        raise ValueError(f"unexpected aero table header: {header}")
    data = np.array([[float(v) for v in r] for r in body], dtype=np.float64)
    return data[:, 0], data[:, 1:]


ALPHA_DEG_GRID, AERO_TABLE_RAW = _load_aero_table()
assert np.allclose(np.diff(ALPHA_DEG_GRID), ALPHA_STEP_DEG)
assert ALPHA_DEG_GRID[0] == ALPHA_MIN_DEG and ALPHA_DEG_GRID[-1] == ALPHA_MAX_DEG

#: The table with every per-degree column converted to per radian (cd0, clift0, cm0 unchanged).
_PER_RAD_SCALE = np.array([1.0 if c in DIMENSIONLESS_COLUMNS else DEG_PER_RAD for c in AERO_COLUMNS])
AERO_TABLE_PER_RAD: np.ndarray = AERO_TABLE_RAW * _PER_RAD_SCALE


def _load_mass_geometry(source_id: str = "IITM_willcmc") -> dict[str, float]:
    out: dict[str, float] = {}
    with (_DATA / "harv_mass_geometry.csv").open() as f:
        for row in csv.DictReader(f):
            if row["source_id"] != source_id:
                continue
            try:
                out[row["quantity"]] = float(row["value"])
            except ValueError:
                continue  # descriptive rows (thrust model text, limits)
    return out


#: IITM row: weight 36,100 lbf; Ixx 22,789, Iyy 176,809, Izz 191,744, Ixz -2,305 slug ft^2;
#: S 400 ft^2, b 37.4 ft, cbar 11.52 ft; T_max 32,000 lbf sea-level static.
IITM_MASS_GEOMETRY: dict[str, float] = _load_mass_geometry()
