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

The schedule (alpha_brake_rad, v_switch_fps) is a pytree of arrays (:class:`BrakeSchedule`) carried in
the controller state, so it is traced data of ``apply``: build the controller from a traced schedule
inside a jitted function, or replace ``state.schedule`` after ``init``, to sweep it without recompiling.
Crossing V_switch changes the reference the SMC sees, so the SMC's integral is reset there as on any
reference change (``SMCConfig.reset_integral_on_reference_change``).
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


@struct.dataclass
class BrakeSchedule:
    """The reference schedule: traced scalars, so a sweep vmaps or re-runs without recompiling.

    Attributes:
        alpha_brake_rad: alpha reference flown while V > v_switch_fps, rad.
        v_switch_fps: airspeed above which alpha_brake_rad replaces alpha_d, ft/s.
    """

    alpha_brake_rad: jnp.ndarray
    v_switch_fps: jnp.ndarray


def brake_schedule(
    alpha_brake_rad: float = ALPHA_BRAKE_RAD, v_switch_fps: float = V_SWITCH_FPS, dtype=None
) -> BrakeSchedule:
    """A checked :class:`BrakeSchedule` from Python numbers (UsageError naming a bad value).

    alpha_brake_rad must lie in the alpha envelope [ALPHA_MIN_RAD, ALPHA_MAX_RAD]; v_switch_fps in
    [0, V_MAX_FPS] (0: brake at every airspeed; V_MAX_FPS: never brake inside the envelope).
    """
    if not (math.isfinite(alpha_brake_rad) and ALPHA_MIN_RAD <= alpha_brake_rad <= ALPHA_MAX_RAD):
        raise UsageError(
            f"alpha_brake_rad {alpha_brake_rad} is outside the alpha envelope "
            f"[{ALPHA_MIN_RAD}, {ALPHA_MAX_RAD}] rad"
        )
    if not (math.isfinite(v_switch_fps) and 0.0 <= v_switch_fps <= V_MAX_FPS):
        raise UsageError(f"v_switch_fps {v_switch_fps} must be in [0, {V_MAX_FPS:g}] ft/s")
    dtype = jnp.result_type(float) if dtype is None else dtype  # not weakly typed: no retrace on sweeps
    return BrakeSchedule(
        alpha_brake_rad=jnp.asarray(alpha_brake_rad, dtype), v_switch_fps=jnp.asarray(v_switch_fps, dtype)
    )


@struct.dataclass
class SMCBrakeState(SMCState):
    """The SMC's state plus the reference schedule (per aircraft under vmap, like the SMC's).

    Attributes:
        schedule: the :class:`BrakeSchedule` ``apply`` reads.
    """

    schedule: BrakeSchedule


def braking_reference(
    x_wind: jnp.ndarray, reference_rad: jnp.ndarray, schedule: BrakeSchedule
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """(the reference [3] the SMC flies, braking flag): alpha_d -> alpha_brake while V > v_switch."""
    braking = x_wind[WIND_INDEX["V"]] > schedule.v_switch_fps
    alpha = jnp.where(braking, schedule.alpha_brake_rad.astype(reference_rad.dtype), reference_rad[0])
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
        return SMCBrakeState(**{f: getattr(base, f) for f in base.__dataclass_fields__}, schedule=sched)

    def apply(
        state: SMCBrakeState, x_wind: jnp.ndarray, reference_rad: jnp.ndarray, key: jax.Array
    ) -> tuple[jnp.ndarray, SMCBrakeState, dict[str, jnp.ndarray]]:
        ref, braking = braking_reference(x_wind, reference_rad, state.schedule)
        u, new_state, info = smc.apply(state, x_wind, ref, key)
        return u, new_state, {**info, "alpha_ref_rad": ref[0], "braking": braking}

    return Controller(init=init, apply=apply)
