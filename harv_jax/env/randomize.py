"""Per-episode domain randomization: the aircraft (``harv_jax.aircraft.randomize``), gust, sensor noise,
actuator delay.

Everything drawn here lives in an ``EpisodeParams`` pytree held in the env state, so new draws never
recompile; the env draws a fresh one at every reset (every episode, not once per env slot).

Draws (``RandomizationParams`` holds the switches and ranges; defaults documented there):

| quantity                    | draw                                                      |
|-----------------------------|-----------------------------------------------------------|
| mass                        | m0 (1 + mass_frac U(-1, 1))                               |
| Ixx, Iyy, Izz, Ixz          | each I0 (1 + inertia_frac U(-1, 1)), independent          |
| aero_scale[33]              | per column 1 + frac_group U(-1, 1); *_der shares *_del's  |
| gust std, correlation time  | U(0, gust_std_max_fps), U(gust_tau_min_s, gust_tau_max_s) |
| sensor-noise std [8]        | U(0, 1) noise_std_max (one factor per episode)            |
| actuator delay, steps       | randint(0, delay_max_steps) inclusive, capped             |
| actuator lag, s             | U(0, lag_max_s) (its own key: `extra_from_uniform`)        |
| turbulence sigma            | U(0, 1) turbulence table (its own key; with turbulence)   |
| an added disturbance's level| U(0, its `[randomization]` maximum) (a key of its own)     |

The env draws all of these from 16-bit uniforms (``uniform16``: two per PRNG word, resolution 1/65536).
The aircraft groups and ranges are documented in ``harv_jax.aircraft.randomize``.

The gust, noise and delay models themselves are ``harv_jax.dynamics.disturbances`` and the turbulence
``harv_jax.dynamics.turbulence``, flown by ``harv_jax.dynamics.disturbed_step`` (shared with the
closed-loop evaluation); this module draws their per-episode levels. The lag and the turbulence are drawn
from a key of their own, so that they change none of the other draws.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.aircraft.randomize import (
    NUM_AIRCRAFT_UNIFORMS,
    SAMPLE_UNIFORMS,
    aircraft_from_uniform,
    uniform16,
)
from harv_jax.dynamics import disturbances
from harv_jax.dynamics.disturbance_model import Models, model_key
from harv_jax.dynamics.disturbances import DisturbanceParams
from harv_jax.dynamics.turbulence import TurbulenceParams
from harv_jax.env.config import RandomizationParams
from harv_jax.task.disturbance_table import added_models
from harv_jax.task.spaces import NUM_MEASURED


@struct.dataclass
class EpisodeParams:
    """What is drawn per episode (traced; one per env).

    Attributes:
        aircraft: the episode's aircraft (mass, inertia, aero_scale randomized).
        delay_steps: int32 actuator command delay, steps.
        gust_std_fps: stationary gust std per body axis, ft/s (0 = no gust).
        gust_tau_s: gust correlation time, s.
        noise_std: [8] sensor-noise std of [V, alpha, beta, p, q, r, mu, gamma] (ft/s, rad, rad/s).
        turbulence: the episode's Dryden turbulence, or None (``EnvConfig.turbulence`` off).
        added_levels: name -> the episode's level of each disturbance added to the table.
        added_models: their models (static; ``dynamics.disturbance_model``).
    """

    aircraft: AircraftParams
    delay_steps: jnp.ndarray
    gust_std_fps: jnp.ndarray
    gust_tau_s: jnp.ndarray
    noise_std: jnp.ndarray
    turbulence: TurbulenceParams | None = None
    added_levels: dict[str, jnp.ndarray] = struct.field(default_factory=dict)
    added_models: Models = struct.field(pytree_node=False, default=())

    @property
    def levels(self) -> DisturbanceParams:
        """The episode's disturbance levels as the disturbed step reads them."""
        return DisturbanceParams(
            self.noise_std,
            self.delay_steps,
            self.gust_std_fps,
            self.gust_tau_s,
            self.turbulence,
            self.added_levels,
            self.added_models,
        )


def nominal_episode(nominal: AircraftParams, rand: RandomizationParams) -> EpisodeParams:
    """Episode parameters with no randomization (nominal aircraft, no delay, gust or noise)."""
    dtype = nominal.mass_slug.dtype
    zero = jnp.zeros((), dtype=dtype)
    return EpisodeParams(
        aircraft=nominal,
        delay_steps=jnp.zeros((), dtype=jnp.int32),
        gust_std_fps=zero,
        gust_tau_s=jnp.asarray(rand.gust_tau_max_s, dtype=dtype),
        noise_std=jnp.zeros((NUM_MEASURED,), dtype=dtype),
    )


#: Number of U(0, 1) draws ``episode_from_uniform`` consumes: the aircraft's (mass 1, inertia 4, aero 33),
#: delay 1, gust std 1, gust tau 1, noise 1.
NUM_EPISODE_UNIFORMS = NUM_AIRCRAFT_UNIFORMS + 4
assert NUM_EPISODE_UNIFORMS == SAMPLE_UNIFORMS  # aircraft.randomize.sample_aircraft draws the same stream
#: Number of N(0, 1) draws per step: gust 3, sensor noise NUM_MEASURED.
NUM_STEP_NORMALS = disturbances.NUM_STEP_NORMALS
assert disturbances.NUM_NOISY_STATES == NUM_MEASURED


def episode_from_uniform(
    u01: jnp.ndarray, nominal: AircraftParams, rand: RandomizationParams, max_delay_steps: int
) -> EpisodeParams:
    """One episode's parameters from ``NUM_EPISODE_UNIFORMS`` U(0, 1) draws.

    Drawing all uniforms in one call keeps the compiled graph small (each PRNG call site compiles its
    own hash); ``sample_episode`` is the keyed form.

    Args:
        u01: [NUM_EPISODE_UNIFORMS] U(0, 1) draws.
        nominal: nominal aircraft.
        rand: switches and ranges.
        max_delay_steps: static cap of the delay (the env's buffer size minus one).

    Returns:
        EpisodeParams (switched-off items at their nominal values).
    """
    n_ac = NUM_AIRCRAFT_UNIFORMS
    aircraft = aircraft_from_uniform(u01[:n_ac], nominal, rand)
    u_delay, u_gstd, u_gtau, u_noise = (u01[n_ac + i] for i in range(4))
    delay_hi = jnp.clip(rand.delay_max_steps, 0, max_delay_steps)
    delay = jnp.minimum(jnp.floor(u_delay * (delay_hi + 1)).astype(jnp.int32), delay_hi)
    delay = jnp.where(rand.delay_on, delay, 0).astype(jnp.int32)
    gust_std = rand.gust_std_max_fps * u_gstd
    gust_tau = rand.gust_tau_min_s + (rand.gust_tau_max_s - rand.gust_tau_min_s) * u_gtau
    noise_std = rand.noise_std_max * u_noise
    return EpisodeParams(
        aircraft=aircraft,
        delay_steps=delay,
        gust_std_fps=jnp.where(rand.gust_on, gust_std, jnp.zeros_like(gust_std)),
        gust_tau_s=gust_tau,
        noise_std=jnp.where(rand.noise_on, noise_std, jnp.zeros_like(noise_std)),
    )


def sample_episode(
    key: jax.Array, nominal: AircraftParams, rand: RandomizationParams, max_delay_steps: int
) -> EpisodeParams:
    """Draw one episode's parameters (see ``episode_from_uniform``; 16-bit uniforms, ``uniform16``)."""
    u01 = uniform16(key, NUM_EPISODE_UNIFORMS, nominal.mass_slug.dtype)
    return episode_from_uniform(u01, nominal, rand, max_delay_steps)


#: Number of U(0, 1) draws of ``extra_from_uniform`` (actuator lag 1, turbulence 1), from their own key.
NUM_EXTRA_UNIFORMS = 2
#: Folded into a reset's key for the lag and turbulence draws.
EXTRA_KEY_TAG = 0x4C414754  # "LAGT"


def extra_from_uniform(
    u01: jnp.ndarray, episode: EpisodeParams, rand: RandomizationParams, turbulence: bool
) -> EpisodeParams:
    """``episode`` with its actuator lag (U(0, lag_max_s)) and, with ``turbulence`` (static), its
    turbulence (U(0, 1) times the table) from ``NUM_EXTRA_UNIFORMS`` U(0, 1) draws."""
    ac = episode.aircraft
    ac = ac.replace(act_tau_s=(rand.lag_max_s * u01[0]).astype(ac.act_tau_s.dtype))
    tp = None
    if turbulence:
        tp = TurbulenceParams(
            rand.turbulence_sigma_table_fps * u01[1], rand.turbulence_wind_20ft_fps * u01[1], ac.b
        )
    return episode.replace(aircraft=ac, turbulence=tp)


#: Folded into a reset's key for the draws of the disturbances added to the table (each then folds its name).
ADDED_KEY_TAG = 0x41444444  # "ADDD"


def added_from_key(key: jax.Array, episode: EpisodeParams, rand: RandomizationParams) -> EpisodeParams:
    """``episode`` with the level of each disturbance added to the table: U(0, 1) times its
    ``[randomization]`` maximum (``rand.added_max``; none: ``episode`` unchanged, nothing drawn)."""
    if not rand.added_max:
        return episode
    dtype = episode.gust_std_fps.dtype
    levels = {
        name: (top * uniform16(model_key(key, name), 2, dtype)[0]).astype(dtype)
        for name, top in rand.added_max.items()
    }
    return episode.replace(added_levels=levels, added_models=added_models(list(levels)))


#: Box-Muller normals from uniforms (the one implementation: ``dynamics.disturbances``).
normals_from_uniform = disturbances.normals_from_uniform


def gust_init(normal3: jnp.ndarray, episode: EpisodeParams) -> jnp.ndarray:
    """[3] initial body-axis gust, ft/s, from the stationary distribution, given [3] N(0, 1) draws."""
    return disturbances.gust_init(normal3, episode.gust_std_fps)


def gust_step(
    gust_fps: jnp.ndarray, episode: EpisodeParams, dt_s: float, normal3: jnp.ndarray
) -> jnp.ndarray:
    """Advance the [3] body-axis OU gust by dt_s (``dynamics.disturbances.gust_step``)."""
    return disturbances.gust_step(gust_fps, episode.gust_std_fps, episode.gust_tau_s, dt_s, normal3)


def sensor_noise(normal8: jnp.ndarray, episode: EpisodeParams) -> jnp.ndarray:
    """[8] additive sensor noise for the measured observations from [8] N(0, 1) draws."""
    return disturbances.sensor_noise(normal8, episode.noise_std)
