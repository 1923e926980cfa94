"""The SMC with an energy-braking alpha reference: ``smc-brake``.

The default SMC (``harv_jax.control.smc``) flies with one alpha reference, alpha_d (20 deg by default).
This controller feeds the same SMC a scheduled reference instead:

    alpha_ref = alpha_brake   while V > V_switch   (default 1.0 rad ~ 57 deg, 500 ft/s)
    alpha_ref = alpha_d       otherwise            (the command's reference, unchanged)

beta_d and mu_d pass through. Below V_switch the command equals the SMC's exactly; above it, it equals
the SMC's command for the reference with alpha_d replaced by alpha_brake.

Why it recovers faster: from a fast upset the SMC at alpha_d = 20 deg converts the excess speed into a
zoom climb and then waits for it to bleed off (an Immelmann of 17-23 s from 1000-1500 ft/s). Pulling to
~57 deg while fast sheds that energy by drag in a few seconds instead; once V falls below V_switch the
ordinary reference takes over and the SMC settles as usual. After the developed spin
of ``compare`` the airspeed stays below V_switch and it flies as the SMC. The recovery criterion is still
scored against the command's alpha_d (20 deg), never against alpha_brake.

The schedule (alpha_brake_rad, v_switch_fps) is a pytree of arrays ([`BrakeSchedule`][]) carried in
the controller state, so it is traced data of ``apply``: build the controller from a traced schedule
inside a jitted function, or replace ``state.schedule`` after ``init``, to sweep it without recompiling.
Crossing V_switch changes the reference the SMC sees, so the SMC's integral is reset there as on any
reference change (``SMCConfig.reset_integral_on_reference_change``).

``smc-brake-zoom`` chooses from the current state whether braking pays (from the fastest upsets the SMC's
zoom climb is the quicker way down): it brakes only while

    V_switch < V < V_zoom - k_zoom * max(gamma, 0)     (default 600 ft/s, 1200 ft/s, 600 ft/s per rad)

Above the upper bound the aircraft is fast for its climb angle: it is in (or entering) the SMC's zoom climb,
which from the fastest upsets sheds the energy sooner than braking does; braking starts only once the climb
has bled the airspeed below the bound. An aircraft that brakes decelerates far faster than it steepens its
climb, so it stays below the bound once it has started.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.control.smc import SMCConfig, SMCGains, SMCState, make_smc
from harv_jax.dynamics.state import WIND_INDEX
from harv_jax.errors import UsageError
from harv_jax.task.spec import ALPHA_MAX_RAD, ALPHA_MIN_RAD, V_MAX_FPS

#: Default braking alpha reference, rad (~57 deg).
ALPHA_BRAKE_RAD = 1.0
#: Default airspeed above which the braking reference is flown, ft/s.
V_SWITCH_FPS = 500.0
#: ``smc-brake-zoom``: braking starts above this airspeed, ft/s.
ZOOM_V_SWITCH_FPS = 600.0
#: ``smc-brake-zoom``: no braking at or above this airspeed in level flight, ft/s.
V_ZOOM_FPS = 1200.0
#: ``smc-brake-zoom``: how much each radian of climb angle lowers that bound, ft/s per rad.
ZOOM_SLOPE_FPS_PER_RAD = 600.0


@struct.dataclass
class BrakeSchedule:
    """The reference schedule: traced scalars, so a sweep vmaps or re-runs without recompiling.

    Attributes:
        alpha_brake_rad: alpha reference flown while V > v_switch_fps, rad.
        v_switch_fps: airspeed above which alpha_brake_rad replaces alpha_d, ft/s.
        v_zoom_fps: brake only while V < v_zoom_fps - zoom_slope_fps_per_rad * max(gamma, 0), ft/s
            (inf: no upper bound, ``smc-brake``).
        zoom_slope_fps_per_rad: how much the climb angle lowers that bound, ft/s per rad.
    """

    alpha_brake_rad: jnp.ndarray
    v_switch_fps: jnp.ndarray
    v_zoom_fps: jnp.ndarray
    zoom_slope_fps_per_rad: jnp.ndarray


def brake_schedule(
    alpha_brake_rad: float = ALPHA_BRAKE_RAD,
    v_switch_fps: float = V_SWITCH_FPS,
    dtype=None,
    v_zoom_fps: float = math.inf,
    zoom_slope_fps_per_rad: float = 0.0,
) -> BrakeSchedule:
    """A checked [`BrakeSchedule`][] from Python numbers (UsageError naming a bad value).

    alpha_brake_rad must lie in the alpha envelope [ALPHA_MIN_RAD, ALPHA_MAX_RAD]; v_switch_fps in
    [0, V_MAX_FPS] (0: brake at every airspeed; V_MAX_FPS: never brake inside the envelope);
    v_zoom_fps above v_switch_fps (inf: no upper bound); zoom_slope_fps_per_rad finite and >= 0.
    """
    if not (math.isfinite(alpha_brake_rad) and ALPHA_MIN_RAD <= alpha_brake_rad <= ALPHA_MAX_RAD):
        raise UsageError(
            f"alpha_brake_rad {alpha_brake_rad} is outside the alpha envelope "
            f"[{ALPHA_MIN_RAD}, {ALPHA_MAX_RAD}] rad"
        )
    if not (math.isfinite(v_switch_fps) and 0.0 <= v_switch_fps <= V_MAX_FPS):
        raise UsageError(f"v_switch_fps {v_switch_fps} must be in [0, {V_MAX_FPS:g}] ft/s")
    if not (v_zoom_fps > v_switch_fps):  # also false for nan
        raise UsageError(
            f"v_zoom_fps {v_zoom_fps} must be above v_switch_fps ({v_switch_fps:g} ft/s; inf: no upper bound)"
        )
    if not (math.isfinite(zoom_slope_fps_per_rad) and zoom_slope_fps_per_rad >= 0.0):
        raise UsageError(
            f"zoom_slope_fps_per_rad {zoom_slope_fps_per_rad} must be finite and >= 0 ft/s per rad"
        )
    dtype = jnp.result_type(float) if dtype is None else dtype  # not weakly typed: no retrace on sweeps
    return BrakeSchedule(
        alpha_brake_rad=jnp.asarray(alpha_brake_rad, dtype),
        v_switch_fps=jnp.asarray(v_switch_fps, dtype),
        v_zoom_fps=jnp.asarray(v_zoom_fps, dtype),
        zoom_slope_fps_per_rad=jnp.asarray(zoom_slope_fps_per_rad, dtype),
    )


@struct.dataclass
class SMCBrakeState(SMCState):
    """The SMC's state plus the reference schedule (per aircraft under vmap, like the SMC's).

    Attributes:
        schedule: the [`BrakeSchedule`][] ``apply`` reads.
    """

    schedule: BrakeSchedule


def zoom_schedule(dtype=None) -> BrakeSchedule:
    """``smc-brake-zoom``'s schedule: brake while ZOOM_V_SWITCH_FPS < V < V_ZOOM_FPS - ZOOM_SLOPE_FPS_PER_RAD
    max(gamma, 0)."""
    return brake_schedule(
        v_switch_fps=ZOOM_V_SWITCH_FPS,
        dtype=dtype,
        v_zoom_fps=V_ZOOM_FPS,
        zoom_slope_fps_per_rad=ZOOM_SLOPE_FPS_PER_RAD,
    )


def braking_reference(
    x_wind: jnp.ndarray, reference_rad: jnp.ndarray, schedule: BrakeSchedule
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """(the reference [3] the SMC flies, braking flag): alpha_d -> alpha_brake while
    v_switch < V < v_zoom - k_zoom max(gamma, 0)."""
    v = x_wind[WIND_INDEX["V"]]
    climb_rad = jnp.maximum(x_wind[WIND_INDEX["gamma"]], 0.0)
    v_upper = schedule.v_zoom_fps - schedule.zoom_slope_fps_per_rad * climb_rad
    braking = (v > schedule.v_switch_fps) & (v < v_upper)
    alpha_brake = schedule.alpha_brake_rad.astype(reference_rad.dtype)
    alpha = jnp.where(braking, alpha_brake, reference_rad[0])
    return reference_rad.at[0].set(alpha), braking


def make_smc_brake(
    cfg: SMCConfig | None = None, gains: SMCGains | None = None, schedule: BrakeSchedule | None = None
) -> Controller:
    """Build the braking SMC.

    Args:
        cfg: the SMC's static options (default ``SMCConfig()``).
        gains: the SMC's gains (default ``smc.default_gains()``).
        schedule: the reference schedule (default ``brake_schedule()``: 1.0 rad above 500 ft/s); stored
            in the state by ``init`` in the aircraft's dtype.

    Returns:
        Controller(init, apply); ``info`` holds the SMC's (its ``e``, ``s`` are relative to the reference
        flown) plus ``alpha_ref_rad`` (the alpha reference flown) and ``braking`` (V > v_switch).
    """
    smc = make_smc(cfg, gains)
    schedule_ = brake_schedule() if schedule is None else schedule

    def init(params: AircraftParams) -> SMCBrakeState:
        base = smc.init(params)
        dtype = jnp.result_type(params.mass_slug)
        sched = jax.tree.map(lambda a: jnp.asarray(a, dtype), schedule_)
        fields = {f: getattr(base, f) for f in base.__dataclass_fields__}
        return SMCBrakeState(**fields, schedule=sched)

    def apply(
        state: SMCBrakeState, x_wind: jnp.ndarray, reference_rad: jnp.ndarray, key: jax.Array
    ) -> tuple[jnp.ndarray, SMCBrakeState, dict[str, jnp.ndarray]]:
        ref, braking = braking_reference(x_wind, reference_rad, state.schedule)
        u, new_state, info = smc.apply(state, x_wind, ref, key)
        return u, new_state, {**info, "alpha_ref_rad": ref[0], "braking": braking}

    return Controller(init=init, apply=apply)
