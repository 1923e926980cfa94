"""Straight, wings-level trim: the reference trim table of docs/model.md to its printed digits, residual
<= 1e-8, checked against the independent body-axis oracle as well."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import oracle_body_axis as oracle  # noqa: E402

from harv_jax.aircraft import harv  # noqa: E402
from harv_jax.dynamics.trim import level_flight, level_flight_state  # noqa: E402


def test_level_flight_state_layout(x64):
    x = np.asarray(level_flight_state(500.0, 12000.0, 0.1))
    np.testing.assert_array_equal(x, [500.0, 0.1, 0, 0, 0, 0, 0, 0, 0, 12000.0])


H_FT = 25000.0
#: docs/model.md reference trim at 25,000 ft: V ft/s -> (alpha deg, de deg, throttle), printed digits.
TRIM_TABLE = {
    400.0: (11.1793, -1.0172, 0.35107),
    600.0: (5.1012, -0.2571, 0.22842),
    800.0: (3.0487, 0.1336, 0.27268),
}


@pytest.fixture(scope="module")
def trims():
    import jax

    with jax.enable_x64(True):
        p = harv()
        out = {}
        for v in TRIM_TABLE:
            t = level_flight(v, H_FT, p)
            out[v] = tuple(float(a) for a in t)
            assert t.alpha_rad.dtype == np.float64
    return out


@pytest.mark.parametrize("vt_fps", list(TRIM_TABLE))
def test_trim_table_to_printed_digits(trims, vt_fps):
    alpha_rad, de_rad, throttle, _ = trims[vt_fps]
    alpha_ref, de_ref, thr_ref = TRIM_TABLE[vt_fps]
    # "to the printed digits": rounding to the printed number of decimals gives the printed value
    assert round(np.degrees(alpha_rad), 4) == alpha_ref
    assert round(np.degrees(de_rad), 4) == de_ref
    assert round(throttle, 5) == thr_ref


@pytest.mark.parametrize("vt_fps", list(TRIM_TABLE))
def test_trim_residual(trims, vt_fps):
    alpha_rad, de_rad, throttle, residual = trims[vt_fps]
    assert residual <= 1e-8
    # independently: the body-axis oracle sees an equilibrium (every derivative but h_dot, which is 0 too)
    x = np.array([vt_fps, alpha_rad, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, H_FT])  # float64, not via jnp
    xd = oracle.wind_derivatives(x, np.array([de_rad, 0.0, 0.0]), oracle.params_from_values(throttle))
    scale = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, vt_fps])  # h_dot relative to V
    assert np.max(np.abs(xd) / scale) <= 1e-8, xd
