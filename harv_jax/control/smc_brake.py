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
ordinary reference takes over and the SMC settles as usual (``experiments/imitation/README.md``, 256
Monte Carlo runs: 100% recovered, median 8.2 s against the default SMC's 17.7 s). After the developed spin
of ``compare`` the airspeed stays below V_switch and it flies as the SMC. The recovery criterion is still
scored against the command's alpha_d (20 deg), never against alpha_brake.

The schedule (alpha_brake_rad, v_switch_fps) is a pytree of arrays ([`BrakeSchedule`][]) carried in
the controller state, so it is traced data of ``apply``: build the controller from a traced schedule
inside a jitted function, or replace ``state.schedule`` after ``init``, to sweep it without recompiling.
Crossing V_switch changes the reference the SMC sees, so the SMC's integral is reset there as on any
reference change (``SMCConfig.reset_integral_on_reference_change``).

``smc-brake-v0`` chooses at engagement whether to brake at all: it brakes as above only if the airspeed of
its first measurement is below ``v_engage_max_fps`` (1200 ft/s) and flies the plain SMC for the whole
recovery otherwise. From the fastest upsets the SMC's zoom climb is the quicker way down to the reference:
on 1000 Monte Carlo runs (seed 11) braking was more than 1 s slower than the SMC on 27.8% of the runs, with
a mean initial airspeed of 1082 ft/s on those against 671 ft/s on the others; choosing at engagement made
it slower on 11-13% (thresholds 1150-1250 ft/s) and its mean recovery time 0.65-0.68x the SMC's against
smc-brake's 0.75x. A rule on the current airspeed alone (brake while 500 < V < 1250 ft/s) does not do it
(0.80x, 28% slower).

``smc-brake-zoom`` makes the same choice from the current state instead, so that a memoryless policy can
learn it: it brakes only while

    V_switch < V < V_zoom - k_zoom * max(gamma, 0)     (default 600 ft/s, 1200 ft/s, 600 ft/s per rad)

Above the upper bound the aircraft is fast for its climb angle: it is in (or entering) the SMC's zoom climb,
which from the fastest upsets sheds the energy sooner than braking does; braking starts only once the climb
has bled the airspeed below the bound. An aircraft that brakes decelerates far faster than it steepens its
climb, so it stays below the bound once it has started. On the same 1000 runs (seed 11): mean recovery time
0.67x the SMC's, slower than the SMC by > 1 s on 5.8% of the runs, control TV 7.0 rad (SMC 7.6), against
smc-brake's 0.75x, 27.8% and 9.3 rad (``experiments/teacher_recipe/README.md``).

``smc-brake-zoom-soft`` blends instead of switching: alpha_ref = alpha_d + b (alpha_brake - alpha_d), b a
product of smoothsteps 100 ft/s wide centred on the two bounds (``BrakeSchedule.blend_fps``), and its SMC
resets the integral only on reference steps above 0.02 rad; a command without a step, as a teacher (same
runs: 0.70x the SMC's mean, slower by > 1 s on 5.7%, TV 6.9 rad).
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
#: ``smc-brake-v0``: brake only if the airspeed at engagement is below this, ft/s.
V_ENGAGE_MAX_FPS = 1200.0
#: ``smc-brake-zoom``: braking starts above this airspeed, ft/s.
ZOOM_V_SWITCH_FPS = 600.0
#: ``smc-brake-zoom``: no braking at or above this airspeed in level flight, ft/s.
V_ZOOM_FPS = 1200.0
#: ``smc-brake-zoom``: how much each radian of climb angle lowers that bound, ft/s per rad.
ZOOM_SLOPE_FPS_PER_RAD = 600.0
#: ``smc-brake-zoom-soft``: width of the blend at each bound of the braking band, ft/s.
SOFT_BLEND_FPS = 100.0
#: Largest blend width a schedule accepts, ft/s.
MAX_BLEND_FPS = 500.0
#: ``smc-brake-zoom-soft``: the SMC's integral is reset only on reference steps larger than this, rad
#: (the blended reference moves a little every step; a target change steps it by far more).
SOFT_RESET_TOL_RAD = 0.02


@struct.dataclass
class BrakeSchedule:
    """The reference schedule: traced scalars, so a sweep vmaps or re-runs without recompiling.

    Attributes:
        alpha_brake_rad: alpha reference flown while V > v_switch_fps, rad.
        v_switch_fps: airspeed above which alpha_brake_rad replaces alpha_d, ft/s.
        v_engage_max_fps: brake only if the airspeed at engagement (the first ``apply``) is below this,
            ft/s (inf: always, ``smc-brake``).
        v_zoom_fps: brake only while V < v_zoom_fps - zoom_slope_fps_per_rad * max(gamma, 0), ft/s
            (inf: no upper bound, ``smc-brake``).
        zoom_slope_fps_per_rad: how much the climb angle lowers that bound, ft/s per rad.
        blend_fps: width of the airspeed band over which the reference blends from alpha_d to
            alpha_brake at each bound (a smoothstep centred on the bound), ft/s (0: a step at the bound).
    """

    alpha_brake_rad: jnp.ndarray
    v_switch_fps: jnp.ndarray
    v_engage_max_fps: jnp.ndarray
    v_zoom_fps: jnp.ndarray
    zoom_slope_fps_per_rad: jnp.ndarray
    blend_fps: jnp.ndarray


def brake_schedule(
    alpha_brake_rad: float = ALPHA_BRAKE_RAD,
    v_switch_fps: float = V_SWITCH_FPS,
    dtype=None,
    v_engage_max_fps: float = math.inf,
    v_zoom_fps: float = math.inf,
    zoom_slope_fps_per_rad: float = 0.0,
    blend_fps: float = 0.0,
) -> BrakeSchedule:
    """A checked [`BrakeSchedule`][] from Python numbers (UsageError naming a bad value).

    alpha_brake_rad must lie in the alpha envelope [ALPHA_MIN_RAD, ALPHA_MAX_RAD]; v_switch_fps in
    [0, V_MAX_FPS] (0: brake at every airspeed; V_MAX_FPS: never brake inside the envelope);
    v_engage_max_fps above 0 (inf: brake from any engagement airspeed); v_zoom_fps above v_switch_fps
    (inf: no upper bound); zoom_slope_fps_per_rad finite and >= 0; blend_fps in [0, MAX_BLEND_FPS].
    """
    if not (math.isfinite(alpha_brake_rad) and ALPHA_MIN_RAD <= alpha_brake_rad <= ALPHA_MAX_RAD):
        raise UsageError(
            f"alpha_brake_rad {alpha_brake_rad} is outside the alpha envelope "
            f"[{ALPHA_MIN_RAD}, {ALPHA_MAX_RAD}] rad"
        )
    if not (math.isfinite(v_switch_fps) and 0.0 <= v_switch_fps <= V_MAX_FPS):
        raise UsageError(f"v_switch_fps {v_switch_fps} must be in [0, {V_MAX_FPS:g}] ft/s")
    if not (v_engage_max_fps > 0.0):  # also false for nan
        raise UsageError(f"v_engage_max_fps {v_engage_max_fps} must be above 0 ft/s (inf: always brake)")
    if not (v_zoom_fps > v_switch_fps):  # also false for nan
        raise UsageError(
            f"v_zoom_fps {v_zoom_fps} must be above v_switch_fps ({v_switch_fps:g} ft/s; inf: no upper bound)"
        )
    if not (math.isfinite(zoom_slope_fps_per_rad) and zoom_slope_fps_per_rad >= 0.0):
        raise UsageError(
            f"zoom_slope_fps_per_rad {zoom_slope_fps_per_rad} must be finite and >= 0 ft/s per rad"
        )
    if not (math.isfinite(blend_fps) and 0.0 <= blend_fps <= MAX_BLEND_FPS):
        raise UsageError(f"blend_fps {blend_fps} must be in [0, {MAX_BLEND_FPS:g}] ft/s (0: a step)")
    dtype = jnp.result_type(float) if dtype is None else dtype  # not weakly typed: no retrace on sweeps
    return BrakeSchedule(
        alpha_brake_rad=jnp.asarray(alpha_brake_rad, dtype),
        v_switch_fps=jnp.asarray(v_switch_fps, dtype),
        v_engage_max_fps=jnp.asarray(v_engage_max_fps, dtype),
        v_zoom_fps=jnp.asarray(v_zoom_fps, dtype),
        zoom_slope_fps_per_rad=jnp.asarray(zoom_slope_fps_per_rad, dtype),
        blend_fps=jnp.asarray(blend_fps, dtype),
    )


@struct.dataclass
class SMCBrakeState(SMCState):
    """The SMC's state plus the reference schedule (per aircraft under vmap, like the SMC's).

    Attributes:
        schedule: the [`BrakeSchedule`][] ``apply`` reads.
        brake_enabled: whether this recovery brakes at all (set at the first ``apply`` from the airspeed
            at engagement and ``schedule.v_engage_max_fps``).
    """

    schedule: BrakeSchedule
    brake_enabled: jnp.ndarray


def zoom_schedule(dtype=None, blend_fps: float = 0.0) -> BrakeSchedule:
    """``smc-brake-zoom``'s schedule: brake while ZOOM_V_SWITCH_FPS < V < V_ZOOM_FPS - ZOOM_SLOPE_FPS_PER_RAD
    max(gamma, 0); ``blend_fps`` > 0 blends the reference across each bound (``smc-brake-zoom-soft``)."""
    return brake_schedule(
        v_switch_fps=ZOOM_V_SWITCH_FPS,
        dtype=dtype,
        v_zoom_fps=V_ZOOM_FPS,
        zoom_slope_fps_per_rad=ZOOM_SLOPE_FPS_PER_RAD,
        blend_fps=blend_fps,
    )


def _smoothstep(x: jnp.ndarray) -> jnp.ndarray:
    """0 below 0, 1 above 1, 3x^2 - 2x^3 between."""
    x = jnp.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def braking_reference(
    x_wind: jnp.ndarray,
    reference_rad: jnp.ndarray,
    schedule: BrakeSchedule,
    enabled: jnp.ndarray | bool = True,
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """(the reference [3] the SMC flies, braking flag): alpha_d -> alpha_brake while
    v_switch < V < v_zoom - k_zoom max(gamma, 0) (and ``enabled``, the engagement-time choice).

    With ``schedule.blend_fps`` = w > 0 the alpha reference is alpha_d + b (alpha_brake - alpha_d), b the
    product of smoothsteps of width w centred on each bound (continuous in V and gamma; b = 1 deep inside
    the band, 0 outside it by w / 2); the flag is b > 1/2. With w = 0 it is the step, exactly."""
    v = x_wind[WIND_INDEX["V"]]
    climb_rad = jnp.maximum(x_wind[WIND_INDEX["gamma"]], 0.0)
    v_upper = schedule.v_zoom_fps - schedule.zoom_slope_fps_per_rad * climb_rad
    braking = (v > schedule.v_switch_fps) & (v < v_upper) & enabled
    alpha_brake = schedule.alpha_brake_rad.astype(reference_rad.dtype)
    alpha = jnp.where(braking, alpha_brake, reference_rad[0])
    width = schedule.blend_fps
    soft = width > 0.0
    safe_width = jnp.where(soft, width, 1.0)
    blend = (
        _smoothstep((v - schedule.v_switch_fps) / safe_width + 0.5)
        * _smoothstep((v_upper - v) / safe_width + 0.5)
        * jnp.asarray(enabled, reference_rad.dtype)
    ).astype(reference_rad.dtype)
    alpha = jnp.where(soft, reference_rad[0] + blend * (alpha_brake - reference_rad[0]), alpha)
    braking = jnp.where(soft, blend > 0.5, braking)
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
        return SMCBrakeState(**fields, schedule=sched, brake_enabled=jnp.asarray(True))

    def apply(
        state: SMCBrakeState, x_wind: jnp.ndarray, reference_rad: jnp.ndarray, key: jax.Array
    ) -> tuple[jnp.ndarray, SMCBrakeState, dict[str, jnp.ndarray]]:
        at_engagement = x_wind[WIND_INDEX["V"]] < state.schedule.v_engage_max_fps
        enabled = jnp.where(state.has_reference, state.brake_enabled, at_engagement)
        ref, braking = braking_reference(x_wind, reference_rad, state.schedule, enabled)
        u, new_state, info = smc.apply(state, x_wind, ref, key)
        new_state = new_state.replace(brake_enabled=enabled)
        return u, new_state, {**info, "alpha_ref_rad": ref[0], "braking": braking}

    return Controller(init=init, apply=apply)
