"""Aircraft randomization: mass, inertia and aero-table draws around a nominal aircraft (vmappable).

Used by the env (per-episode domain randomization, ``env.randomize``), the Monte Carlo
(``evaluation.montecarlo.rollout``) and the spin bank (``task.spin_bank``). ``AircraftRandomization`` holds
the traced switches and ranges; the env's ``RandomizationParams`` carries the same fields (plus its gust,
noise and delay items), so either can be passed where ``rand`` is asked for.

| quantity                    | draw                                                      |
|-----------------------------|-----------------------------------------------------------|
| mass                        | m0 (1 + mass_frac U(-1, 1))                               |
| Ixx, Iyy, Izz, Ixz          | each I0 (1 + inertia_frac U(-1, 1)), independent          |
| aero_scale[33]              | per column 1 + frac_group U(-1, 1); *_der shares *_del's  |

Aero groups (columns of ``AERO_COLUMNS``): damping = rate derivatives; control = control-surface
derivatives (the symmetric-stabilator pair *_del/*_der gets one common factor, so that the published
cancellation cn_del + cn_der ~ 0 at low alpha is kept); static = cy_b, croll_b, cn_b, cm0; basic =
clift0, cd0. Independent inertia factors can break the triangle inequality Ixx + Iyy >= Izz (the
tensor stays positive definite; the equations of motion remain well defined).

Draws are 16-bit uniforms (``uniform16``: two per PRNG word, resolution 1/65536).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.aircraft.data_harv import AERO_COLUMNS
from harv_jax.aircraft.params import AircraftParams

_DAMPING = ("cy_p", "cy_r", "croll_p", "croll_r", "cn_p", "cn_r", "cd_q", "clift_q", "cm_q")
_STATIC = ("cy_b", "croll_b", "cn_b", "cm0")
_BASIC = ("clift0", "cd0")
_CONTROL = tuple(c for c in AERO_COLUMNS if c not in _DAMPING + _STATIC + _BASIC)
#: Aero-scale groups: name -> column names. Together they cover every column exactly once.
AERO_GROUPS: dict[str, tuple[str, ...]] = {
    "damping": _DAMPING,
    "control": _CONTROL,
    "static": _STATIC,
    "basic": _BASIC,
}
assert sorted(sum(AERO_GROUPS.values(), ())) == sorted(AERO_COLUMNS)
assert all(c.endswith(("_da", "_del", "_der", "_dr")) for c in _CONTROL)

_COL = {c: i for i, c in enumerate(AERO_COLUMNS)}
#: [33] group index of each column (0 damping, 1 control, 2 static, 3 basic).
_GROUP_OF_COLUMN = np.array(
    [next(g for g, cols in enumerate(AERO_GROUPS.values()) if c in cols) for c in AERO_COLUMNS]
)
#: [33] source column of each column's factor: *_der takes its *_del partner's factor.
_FACTOR_SOURCE = np.array(
    [_COL[c[: -len("_der")] + "_del"] if c.endswith("_der") else _COL[c] for c in AERO_COLUMNS]
)

#: Number of U(0, 1) draws ``aircraft_from_uniform`` consumes: mass 1, inertia 4, aero 33.
NUM_AIRCRAFT_UNIFORMS = 1 + 4 + len(AERO_COLUMNS)
#: Number of U(0, 1) draws ``sample_aircraft`` makes: the aircraft's, then 4 unused (the env's delay, gust
#: std, gust tau and noise draws). It equals the env's per-episode draw (``env.randomize.
#: NUM_EPISODE_UNIFORMS``), so one key gives the same aircraft here as in an env episode.
SAMPLE_UNIFORMS = NUM_AIRCRAFT_UNIFORMS + 4


@struct.dataclass
class AircraftRandomization:
    """Switches and ranges of the aircraft draws (traced). Ranges are half-widths of uniform draws of
    multiplicative factors ``1 + frac * U(-1, 1)``.

    Attributes:
        mass_on: randomize mass and inertias.
        mass_frac: mass factor half-width (default 0.10, i.e. +-10%).
        inertia_frac: Ixx, Iyy, Izz, Ixz factor half-width, each independent (default 0.10).
        aero_on: randomize aero-table column multipliers (``AircraftParams.aero_scale``).
        aero_damping_frac: rate-derivative columns (cy_p, cy_r, croll_p, croll_r, cn_p, cn_r, cd_q,
            clift_q, cm_q), default 0.20.
        aero_control_frac: control-effectiveness columns (all *_da, *_del/_der, *_dr), default 0.15.
        aero_static_frac: static-stability columns (cy_b, croll_b, cn_b, cm0), default 0.10.
        aero_basic_frac: basic lift and drag (clift0, cd0), default 0.05.
    """

    mass_on: jnp.ndarray
    mass_frac: jnp.ndarray
    inertia_frac: jnp.ndarray
    aero_on: jnp.ndarray
    aero_damping_frac: jnp.ndarray
    aero_control_frac: jnp.ndarray
    aero_static_frac: jnp.ndarray
    aero_basic_frac: jnp.ndarray


def default_aircraft_randomization(enabled: bool = True, dtype=None) -> AircraftRandomization:
    """Documented default ranges; ``enabled`` sets both switches."""
    dtype = dtype or jnp.result_type(float)

    def f(v):
        return jnp.asarray(v, dtype=dtype)

    on = jnp.asarray(enabled, dtype=bool)
    return AircraftRandomization(
        mass_on=on,
        mass_frac=f(0.10),
        inertia_frac=f(0.10),
        aero_on=on,
        aero_damping_frac=f(0.20),
        aero_control_frac=f(0.15),
        aero_static_frac=f(0.10),
        aero_basic_frac=f(0.05),
    )


def _sym(u01: jnp.ndarray) -> jnp.ndarray:
    """U(0, 1) -> U(-1, 1)."""
    return 2.0 * u01 - 1.0


def aero_scale_from_uniform(u01: jnp.ndarray, rand: AircraftRandomization) -> jnp.ndarray:
    """[33] aero-table multipliers from [33] U(0, 1) draws (ones when ``aero_on`` is False)."""
    fracs = jnp.stack(
        [rand.aero_damping_frac, rand.aero_control_frac, rand.aero_static_frac, rand.aero_basic_frac]
    )
    u = _sym(u01)[_FACTOR_SOURCE]
    scale = 1.0 + fracs[_GROUP_OF_COLUMN] * u
    return jnp.where(rand.aero_on, scale, jnp.ones_like(scale))


def aircraft_from_uniform(
    u01: jnp.ndarray, nominal: AircraftParams, rand: AircraftRandomization
) -> AircraftParams:
    """One aircraft from ``NUM_AIRCRAFT_UNIFORMS`` U(0, 1) draws (switched-off items stay nominal).

    Args:
        u01: [NUM_AIRCRAFT_UNIFORMS] draws: mass, then the 4 inertias, then the 33 aero columns.
        nominal: nominal aircraft.
        rand: switches and ranges (an ``AircraftRandomization`` or the env's ``RandomizationParams``).
    """
    n_aero = len(AERO_COLUMNS)
    u_mass, u_inertia, u_aero = u01[0], u01[1:5], u01[5 : 5 + n_aero]
    one = jnp.ones_like(u_mass)
    mass_factor = jnp.where(rand.mass_on, 1.0 + rand.mass_frac * _sym(u_mass), one)
    inertia = jnp.where(rand.mass_on, 1.0 + rand.inertia_frac * _sym(u_inertia), jnp.ones_like(u_inertia))
    return nominal.replace(
        mass_slug=nominal.mass_slug * mass_factor,
        Ixx=nominal.Ixx * inertia[0],
        Iyy=nominal.Iyy * inertia[1],
        Izz=nominal.Izz * inertia[2],
        Ixz=nominal.Ixz * inertia[3],
        aero_scale=nominal.aero_scale * aero_scale_from_uniform(u_aero, rand),
    )


def uniform16(key: jax.Array, n: int, dtype=None) -> jnp.ndarray:
    """[n] U(0, 1) draws at 16-bit resolution, two per 32-bit PRNG word.

    Values are (k + 0.5) / 65536 for k in 0..65535: strictly inside (0, 1). With jax's (default)
    partitionable threefry every drawn element costs one hash block whatever its width, so packing two
    16-bit draws in each 32-bit word halves the PRNG work, which dominates the cost of a reset.
    """
    dtype = dtype or jnp.result_type(float)
    words = jax.random.bits(key, ((n + 1) // 2,), dtype=jnp.uint32)
    halves = jnp.concatenate([words >> 16, words & 0xFFFF])[:n]
    return (halves.astype(dtype) + 0.5) / 65536.0


def sample_aircraft(key: jax.Array, nominal: AircraftParams, rand: AircraftRandomization) -> AircraftParams:
    """Draw one aircraft (``SAMPLE_UNIFORMS`` 16-bit uniforms, the first ``NUM_AIRCRAFT_UNIFORMS`` used);
    the same aircraft as the env's episode drawn with ``key`` (``env.randomize.sample_episode``)."""
    u01 = uniform16(key, SAMPLE_UNIFORMS, nominal.mass_slug.dtype)
    return aircraft_from_uniform(u01[:NUM_AIRCRAFT_UNIFORMS], nominal, rand)
