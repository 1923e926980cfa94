"""One disturbed plant step, shared by the training env and the closed-loop evaluation.

What lies between a controller and the aircraft (``dynamics.disturbances``: sensor noise, command delay,
the body-axis gust; ``dynamics.turbulence``: the Dryden turbulence) is held in a [`DisturbanceState`][]
and advanced here, with the plant, by one function: [`disturbed_plant_step`][]. The env
(``env.recovery``) and the Monte Carlo (``evaluation.closed_loop``) call it with the same arguments and
the same keys, so that both fly the same trajectories.

One step k:

    air_k   = air_data(body_k, dist_k, levels)        (the air mass's velocity and the angles it makes)
    y_k     = measured(air_k.x_wind, dist_k, levels)  (what the sensors report: air data plus noise)
    u_k     = controller(y_k)                         (outside: a controller, or the env's action)
    body_k+1, delta_k+1, dist_k+1 = disturbed_plant_step(body_k, delta_k, dist_k, u_k, air_k, ..., key_k)

Inside the step the command enters the FIFO, the plant flies the command ``delay_steps`` old in the wind
of air_k, then the step's key gives the gust and noise of k+1 (one PRNG call, ``disturbances.step_normals``)
and, with turbulence, the turbulence's own normals (a key folded with `TURBULENCE_KEY_TAG`, so turning
turbulence on changes no other draw). The turbulence's scales follow the altitude and the airspeed at the
start of the step.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics import disturbance_model as dm
from harv_jax.dynamics import disturbances as dist
from harv_jax.dynamics import turbulence as turb
from harv_jax.dynamics.plant import PlantStep, plant_step
from harv_jax.dynamics.state import WIND_INDEX, BodyState, quat_to_dcm, to_wind, vt_fps

#: Folded into a step's (or the initial) disturbance key for the turbulence draws.
TURBULENCE_KEY_TAG = 0x54555242  # "TURB"


@struct.dataclass
class DisturbanceState:
    """What the disturbances carry from step to step.

    Attributes:
        cmd_buffer_rad: [D + 1, 3] past commands, newest first, rad (``disturbances.push_command``).
        gust_fps: [3] body-axis gust, ft/s.
        noise_normals: [8] the N(0, 1) draws of the sensor noise on the current measurement (scaled by
            the levels' std where the measurement is taken: ``measured``), or None (no noise drawn: the
            measurement is the air data).
        turbulence: the Dryden filter states, or None (no turbulence).
        heading0_rad: the turbulence frame's heading (the initial one), rad.
        added: name -> state of each disturbance added to the table (``dynamics.disturbance_model``).
    """

    cmd_buffer_rad: jnp.ndarray
    gust_fps: jnp.ndarray
    noise_normals: jnp.ndarray | None
    turbulence: turb.TurbulenceState | None
    heading0_rad: jnp.ndarray
    added: dict[str, Any] = struct.field(default_factory=dict)


class AirData(NamedTuple):
    """The air around the aircraft at one instant.

    Attributes:
        x_wind: [10] wind state relative to the air mass (``air_relative``): what air data measure.
        wind_fps: [3] body-axis velocity of the air mass (gust plus turbulence), ft/s.
        wind_pqr_radps: [3] body-axis rotation rate of the air (turbulence), rad/s, or None.
    """

    x_wind: jnp.ndarray
    wind_fps: jnp.ndarray
    wind_pqr_radps: jnp.ndarray | None


def air_relative(body: BodyState, wind_fps: jnp.ndarray) -> jnp.ndarray:
    """The wind state [10] relative to the air mass moving at the body-axis ``wind_fps`` [3]: V, alpha,
    beta as air data measure them (the aerodynamics see the same velocity), mu, gamma, chi about the
    air-relative velocity; p, q, r and h are unchanged. With a zero wind it equals ``to_wind(body)``."""
    return to_wind(body.replace(uvw_fps=body.uvw_fps - wind_fps))


def air_data(body: BodyState, state: DisturbanceState, levels: dist.DisturbanceParams) -> AirData:
    """The air data of ``body`` in the gust and turbulence of ``state``."""
    wind, pqr = body_wind_fps(state, levels), None
    if levels.turbulence is not None:
        uvw, p = turb.turbulence_velocity(state.turbulence, levels.turbulence, body.pos_ft[2])
        ned = turb.turbulence_ned(uvw, state.heading0_rad)
        wind = wind + turb.body_from_ned(quat_to_dcm(body.quat), ned)
        pqr = jnp.stack([p, jnp.zeros_like(p), jnp.zeros_like(p)])
    return AirData(air_relative(body, wind), wind, pqr)


def body_wind_fps(state: DisturbanceState, levels: dist.DisturbanceParams) -> jnp.ndarray:
    """[3] the body-axis wind besides the turbulence: the gust plus the air velocity of the disturbances
    added to the table, ft/s."""
    added = dm.added_wind_fps(levels.added_models, state.added, levels.added_levels)
    return state.gust_fps if added is None else state.gust_fps + added


def sensor_noise(state: DisturbanceState, levels: dist.DisturbanceParams) -> jnp.ndarray | None:
    """[8] the sensor noise on the current measurement (None: none drawn)."""
    if state.noise_normals is None:
        return None
    return dist.sensor_noise(state.noise_normals, levels.noise_std)


def measured(x_wind: jnp.ndarray, state: DisturbanceState, levels: dist.DisturbanceParams) -> jnp.ndarray:
    """The wind state [10] as the sensors report it (``x_wind`` plus the state's noise, if any, then the
    disturbances added to the table)."""
    noise = sensor_noise(state, levels)
    y = x_wind if noise is None else dist.measured(x_wind, noise)
    return dm.measure(levels.added_models, y, state.added, levels.added_levels)


def _turbulence_normals(key: jax.Array, dtype) -> jnp.ndarray:
    return jax.random.normal(
        jax.random.fold_in(key, TURBULENCE_KEY_TAG), (turb.NUM_TURBULENCE_NORMALS,), dtype
    )


def disturbance_init(
    normals: jnp.ndarray | None,
    levels: dist.DisturbanceParams,
    delta0_rad: jnp.ndarray,
    heading0_rad: jnp.ndarray,
    max_delay_steps: int,
    turbulence_key: jax.Array | None = None,
) -> DisturbanceState:
    """The disturbances at engagement: the FIFO full of ``delta0_rad``, the gust in its stationary
    distribution and the first noise from ``normals`` (None: gust zero, no noise), the turbulence in its
    stationary distribution from ``turbulence_key`` (folded with `TURBULENCE_KEY_TAG`).

    Args:
        normals: [>= 11] N(0, 1) draws: gust [:3], noise [3:11] (``disturbances.step_normals``).
        levels: the run's disturbance levels.
        delta0_rad: [3] deflections at engagement.
        heading0_rad: heading at engagement (the turbulence frame's), rad.
        max_delay_steps: static FIFO size minus one.
        turbulence_key: the key of the initial turbulence draws (required with turbulence) and of the
            added disturbances' (``dynamics.disturbance_model``).
    """
    dtype = delta0_rad.dtype
    buffer = jnp.broadcast_to(delta0_rad, (max_delay_steps + 1, 3))
    gust, noise = jnp.zeros((3,), dtype), None
    if normals is not None:
        gust = dist.gust_init(normals[:3], levels.gust_std_fps).astype(dtype)
        noise = normals[3 : 3 + dist.NUM_NOISY_STATES].astype(dtype)
    tstate = None
    if levels.turbulence is not None:
        if turbulence_key is None:
            raise ValueError("disturbance_init: turbulence needs a turbulence_key")
        tstate = turb.turbulence_init(_turbulence_normals(turbulence_key, dtype))
    added = dm.init_states(levels.added_models, levels.added_levels, turbulence_key)
    return DisturbanceState(buffer, gust, noise, tstate, jnp.asarray(heading0_rad, dtype), added)


def initial_heading(body: BodyState) -> jnp.ndarray:
    """The heading chi of ``body``, rad (the turbulence frame of a run that starts there)."""
    return to_wind(body)[WIND_INDEX["chi"]]


class DisturbedStep(NamedTuple):
    """What one disturbed step produces.

    Attributes:
        plant: the plant step (body, deflections, inertial wind-axis view ``to_wind(body)``).
        disturbance: the disturbance state of the next step.
    """

    plant: PlantStep
    disturbance: DisturbanceState


def disturbed_plant_step(
    body: BodyState,
    delta_rad: jnp.ndarray,
    state: DisturbanceState,
    cmd_rad: jnp.ndarray,
    air: AirData,
    aircraft: AircraftParams,
    levels: dist.DisturbanceParams,
    dt_s: float | jnp.ndarray,
    key: jax.Array | None,
) -> DisturbedStep:
    """One plant step with the disturbances (module docstring).

    Args:
        body: integration state at step k.
        delta_rad: [3] deflections at step k, rad.
        state: disturbances at step k.
        cmd_rad: [3] the controller's command at step k, rad.
        air: ``air_data(body, state, levels)`` (the caller has it: the controller saw it).
        aircraft: the plant's aircraft.
        levels: the disturbance levels (``levels.delay_steps`` within the FIFO).
        dt_s: step, s.
        key: the step's disturbance key (None: nothing drawn, gust, noise and the added disturbances held;
            needs no turbulence).

    Returns:
        DisturbedStep(plant step, disturbances at k + 1).
    """
    buffer = dist.push_command(state.cmd_buffer_rad, cmd_rad)
    u_plant = dist.delayed_command(buffer, levels.delay_steps)
    ps = plant_step(body, delta_rad, u_plant, aircraft, dt_s, air.wind_fps, air.wind_pqr_radps)
    if key is None:
        if levels.turbulence is not None:
            raise ValueError("disturbed_plant_step: turbulence needs a key")
        return DisturbedStep(ps, state.replace(cmd_buffer_rad=buffer))
    dtype = state.gust_fps.dtype
    normals = dist.step_normals(key, dtype)
    gust = dist.gust_step(state.gust_fps, levels.gust_std_fps, levels.gust_tau_s, dt_s, normals[:3])
    noise = state.noise_normals
    if noise is not None:
        noise = normals[3 : 3 + dist.NUM_NOISY_STATES].astype(noise.dtype)
    tstate = state.turbulence
    if levels.turbulence is not None:
        n6 = _turbulence_normals(key, dtype)
        tstate = turb.turbulence_step(tstate, levels.turbulence, body.pos_ft[2], vt_fps(air.x_wind), dt_s, n6)
    added = dm.step_states(levels.added_models, state.added, levels.added_levels, key, dt_s)
    return DisturbedStep(
        ps,
        state.replace(
            cmd_buffer_rad=buffer, gust_fps=gust, noise_normals=noise, turbulence=tstate, added=added
        ),
    )
