"""A bank of developed-spin states for training resets and evaluation, made by flying the pro-spin open loop.

Each bank entry is flown, all of them in one vmapped ``lax.scan``, from a randomized spin entry with the
pro-spin controls of ``harv_jax.task.scenarios`` (full aft stick, full aileron and rudder with the spin's
sense) on a randomized aircraft (the env's mass/inertia/aero ranges) for a randomized time; the state and
deflections reached are the bank entry. Half of the entries are mirror images (a right spin: p, r, beta,
mu, chi and the aileron/rudder negated at entry), since the airframe is laterally symmetric.

| randomized                        | draw                                         |
|-----------------------------------|----------------------------------------------|
| entry V, ft/s                     | U(250, 350)   (scenario: 300)                |
| entry alpha, rad                  | U(0.8, 1.0)   (scenario: 0.9)                |
| entry p, r, rad/s                 | U(-0.7, -0.3) each (scenario: -0.5)          |
| time in the spin, s               | U(spin_s_min, spin_s_max) (scenario: 30)     |
| spin sense                        | left or right, 1/2 each                      |
| aircraft                          | ``aircraft.randomize.sample_aircraft``        |

A state that left the envelope or is non-finite (none in our draws; guarded anyway) is replaced by the
scenario's nominal developed spin. ``spinning`` flags the entries that meet the spin test of
``task.scenarios.spin_check`` over their last 10 s.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.aircraft.randomize import AircraftRandomization, sample_aircraft
from harv_jax.dynamics.plant import plant_step
from harv_jax.dynamics.state import WIND_INDEX, alpha_rad, from_wind, to_wind, yaw_rate_radps
from harv_jax.task.scenarios import (
    SPIN_DURATION_S,
    SPIN_MIN_ALPHA_RAD,
    SPIN_MIN_YAW_RATE_RADPS,
    developed_spin_state,
    spin_controls_rad,
    spin_entry_state,
)
from harv_jax.task.spec import DT_S, H0_FT

#: Entry ranges (ft/s, rad, rad/s) of the randomized spin entries; see the module table.
ENTRY_V_FPS = (250.0, 350.0)
ENTRY_ALPHA_RAD = (0.8, 1.0)
ENTRY_RATE_RADPS = (-0.7, -0.3)
#: Window of the spin test, s.
CHECK_WINDOW_S = 10.0


@struct.dataclass
class SpinBank:
    """Developed-spin states (leading axis: entry).

    Attributes:
        x_wind: [K, 10] wind-axis states reached.
        delta_rad: [K, 3] deflections reached (the pro-spin controls after the actuator).
        spin_s: [K] time flown in the spin, s.
        spinning: [K] the entry met the spin test (alpha > 40 deg, |r| > 0.5 rad/s) over its last 10 s.
    """

    x_wind: jnp.ndarray
    delta_rad: jnp.ndarray
    spin_s: jnp.ndarray
    spinning: jnp.ndarray


def make_spin_bank(
    key: jax.Array,
    n: int,
    nominal: AircraftParams,
    randomization: AircraftRandomization,
    spin_s_min: float = 15.0,
    spin_s_max: float = SPIN_DURATION_S,
    dt_s: float = DT_S,
    h0_ft: float = H0_FT,
) -> SpinBank:
    """Fly ``n`` randomized pro-spin open loops and keep the states reached (jit-compiled inside).

    Args:
        key: PRNG key.
        n: bank size (static).
        nominal: nominal aircraft the randomized ones are drawn around.
        randomization: ranges and switches of the aircraft draws (an ``AircraftRandomization`` or the env's
            ``RandomizationParams``; only mass/inertia/aero are used).
        spin_s_min, spin_s_max: range of the time in the spin, s (0 < min <= max).
        dt_s: step, s.
        h0_ft: entry altitude, ft.

    Returns:
        SpinBank with numpy-convertible leaves of leading size ``n``.
    """
    if not (0.0 < spin_s_min <= spin_s_max):
        raise ValueError(f"spin_s_min={spin_s_min}, spin_s_max={spin_s_max}: need 0 < min <= max")
    if n < 1:
        raise ValueError(f"spin bank size {n} must be >= 1")
    n_max = int(round(spin_s_max / dt_s))
    n_win = int(round(min(CHECK_WINDOW_S, spin_s_min) / dt_s))

    def one(key_i: jax.Array):
        k_ac, k_u = jax.random.split(key_i)
        aircraft = sample_aircraft(k_ac, nominal, randomization)
        u = jax.random.uniform(k_u, (6,))
        dtype = jnp.result_type(nominal.mass_slug)
        sense = jnp.where(u[5] < 0.5, 1.0, -1.0).astype(dtype)  # +1: the scenario's left spin
        x0 = spin_entry_state(h0_ft, dtype)
        i_v, i_alpha, i_p, i_r = (WIND_INDEX[n] for n in ("V", "alpha", "p", "r"))
        x0 = x0.at[i_v].set(ENTRY_V_FPS[0] + (ENTRY_V_FPS[1] - ENTRY_V_FPS[0]) * u[0])
        x0 = x0.at[i_alpha].set(ENTRY_ALPHA_RAD[0] + (ENTRY_ALPHA_RAD[1] - ENTRY_ALPHA_RAD[0]) * u[1])
        lo, hi = ENTRY_RATE_RADPS
        x0 = x0.at[i_p].set(sense * (lo + (hi - lo) * u[2])).at[i_r].set(sense * (lo + (hi - lo) * u[3]))
        cmd = spin_controls_rad(dtype) * jnp.stack([1.0, sense, sense]).astype(dtype)
        n_spin = jnp.round((spin_s_min + (spin_s_max - spin_s_min) * u[4]) / dt_s).astype(jnp.int32)

        def step(carry, k):
            body, delta, r_min, a_min = carry
            body_new, delta_new, _ = plant_step(body, delta, cmd, aircraft, dt_s)
            flying = k < n_spin
            body = jax.tree.map(lambda a, b: jnp.where(flying, a, b), body_new, body)
            delta = jnp.where(flying, delta_new, delta)
            x = to_wind(body)
            in_win = flying & (k >= n_spin - n_win)
            r_min = jnp.where(in_win, jnp.minimum(r_min, sense * -yaw_rate_radps(x)), r_min)
            a_min = jnp.where(in_win, jnp.minimum(a_min, alpha_rad(x)), a_min)
            return (body, delta, r_min, a_min), None

        inf = jnp.asarray(jnp.inf, dtype)
        carry0 = (from_wind(x0), jnp.zeros((3,), dtype), inf, inf)
        (body, delta, r_min, a_min), _ = jax.lax.scan(step, carry0, jnp.arange(n_max))
        x = to_wind(body)
        spinning = (a_min > SPIN_MIN_ALPHA_RAD) & (r_min > SPIN_MIN_YAW_RATE_RADPS)
        return x, delta, n_spin.astype(dtype) * dt_s, spinning

    x, delta, spin_s, spinning = jax.jit(jax.vmap(one))(jax.random.split(key, n))
    ok = jnp.all(jnp.isfinite(x), axis=1) & jnp.all(jnp.isfinite(delta), axis=1) & (alpha_rad(x) < 1.5)
    if not bool(jnp.all(ok)):
        x_nom, d_nom = nominal_spin(nominal, dt_s, h0_ft)
        x = jnp.where(ok[:, None], x, x_nom[None])
        delta = jnp.where(ok[:, None], delta, d_nom[None])
        spinning = spinning & ok
    return SpinBank(x_wind=x, delta_rad=delta, spin_s=spin_s, spinning=spinning)


def nominal_spin(
    nominal: AircraftParams, dt_s: float = DT_S, h0_ft: float = H0_FT
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """The scenario's developed spin (30 s, nominal aircraft): (wind state [10], deflections [3])."""
    body, delta = jax.jit(lambda p: developed_spin_state(p, SPIN_DURATION_S, dt_s, h0_ft))(nominal)
    return to_wind(body), delta
