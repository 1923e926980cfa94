"""The class of controls of the optimum: the braking SMC fed a piecewise-linear reference offset in time.

A control of the class is the feedback law of ``harv_jax.control.smc_brake`` (the SMC with alpha_d
replaced by alpha_brake while V > v_switch) whose reference gets an offset that is a function of the time
since engagement alone:

    r(t) = braking_reference(x(t), r_d, schedule) + o(t)
    o(t) = linear interpolation of the knot offsets o_j = amp * tanh(z_j) at t_j = j knot_dt_s,
           j = 0 .. n_knots - 1, and o = 0 from t = n_knots knot_dt_s on

with amp = `OFFSET_AMPLITUDE_RAD` per channel (alpha, beta, mu) and r(t)'s alpha clipped to the
alpha envelope. The decision variables are the raw knots z [n_knots, 3] (unconstrained: tanh keeps every
iterate's reference bounded) and, fixed per run by the warm start, whether the braking schedule is on
(v_switch = `BRAKE_SWITCH_FPS` or `NO_BRAKE_SWITCH_FPS`). After the last knot the reference is
the target and the SMC settles on it as usual. The command is the SMC's, so every deflection the plant sees
goes through the actuator model: each iterate respects the position and rate limits by construction.

At z = 0 the controller is the braking SMC bit for bit (``smc-brake``), or, with braking off, the SMC
(``smc``): the search starts from the better of the two on each run.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.control.smc import SMCConfig, SMCGains, SMCState, make_smc
from harv_jax.control.smc_brake import V_SWITCH_FPS, BrakeSchedule, brake_schedule, braking_reference
from harv_jax.task.spec import ALPHA_MAX_RAD, ALPHA_MIN_RAD, DT_S, V_MAX_FPS

#: Bound on the reference offset per channel [alpha, beta, mu], rad (the tanh's amplitude).
OFFSET_AMPLITUDE_RAD = (0.6, 0.1, 0.6)
#: v_switch of a run that brakes (the braking SMC's), ft/s.
BRAKE_SWITCH_FPS = V_SWITCH_FPS
#: v_switch of a run that does not brake: the envelope's top speed (above it the run has departed), ft/s.
NO_BRAKE_SWITCH_FPS = V_MAX_FPS


@struct.dataclass
class ScheduleState(SMCState):
    """The SMC's state plus the step count since engagement (so ``closed_loop`` sets ``u_prev_rad``).

    Attributes:
        step: int32 number of ``apply`` calls so far (t = step dt_s).
    """

    step: jnp.ndarray


def knot_offsets_rad(z: jnp.ndarray) -> jnp.ndarray:
    """Knot offsets [n_knots, 3], rad, of the raw knots ``z`` [n_knots, 3]: amp * tanh(z)."""
    return jnp.asarray(OFFSET_AMPLITUDE_RAD, z.dtype)[None] * jnp.tanh(z)


def offset_at_rad(z: jnp.ndarray, t_s: jnp.ndarray, knot_dt_s: float) -> jnp.ndarray:
    """The offset o(t) [3], rad: linear between knots, 0 from t = n_knots knot_dt_s on (and for t < 0)."""
    o = jnp.concatenate([knot_offsets_rad(z), jnp.zeros((1, 3), z.dtype)], axis=0)
    n = z.shape[0]
    pos = jnp.clip(t_s / knot_dt_s, 0.0, float(n))
    j = jnp.minimum(jnp.floor(pos).astype(jnp.int32), n - 1)
    frac = (pos - j).astype(z.dtype)
    return (1.0 - frac) * o[j] + frac * o[j + 1]


def scheduled_reference(
    x_wind: jnp.ndarray, reference_rad: jnp.ndarray, schedule: BrakeSchedule, offset_rad: jnp.ndarray
) -> jnp.ndarray:
    """The reference [3] the SMC flies: the braking reference plus the offset, alpha kept in the envelope.

    With a zero offset the result is ``braking_reference``'s, unchanged (no clip applies to it).
    """
    ref, _ = braking_reference(x_wind, reference_rad, schedule)
    ref = ref + offset_rad.astype(ref.dtype)
    return ref.at[0].set(jnp.clip(ref[0], ALPHA_MIN_RAD, ALPHA_MAX_RAD))


def make_scheduled_smc(
    z: jnp.ndarray,
    v_switch_fps: jnp.ndarray | float,
    knot_dt_s: float,
    cfg: SMCConfig | None = None,
    gains: SMCGains | None = None,
    dt_s: float = DT_S,
) -> Controller:
    """The controller of the class for one run (build it inside a jitted/vmapped function from traced knots).

    Args:
        z: [n_knots, 3] raw knots (traced).
        v_switch_fps: airspeed above which the braking alpha reference replaces alpha_d (traced scalar).
        knot_dt_s: knot spacing, s (static).
        cfg: the SMC's static options (default ``SMCConfig()``, the registry's smc and smc-brake).
        gains: the SMC's gains (default ``smc.default_gains()``).
        dt_s: the plant step, s (the controller's clock).

    Returns:
        Controller(init, apply); ``info`` holds the SMC's plus ``reference_rad`` [3], the reference flown.
    """
    smc = make_smc(cfg, gains)

    def init(params: AircraftParams) -> ScheduleState:
        base = smc.init(params)
        fields = {f: getattr(base, f) for f in base.__dataclass_fields__}
        return ScheduleState(**fields, step=jnp.asarray(0, jnp.int32))

    def apply(
        state: ScheduleState, x_wind: jnp.ndarray, reference_rad: jnp.ndarray, key: jax.Array
    ) -> tuple[jnp.ndarray, ScheduleState, dict[str, jnp.ndarray]]:
        dtype = reference_rad.dtype
        sched = brake_schedule(dtype=dtype).replace(v_switch_fps=jnp.asarray(v_switch_fps, dtype))
        t_s = state.step.astype(dtype) * dt_s
        ref = scheduled_reference(
            x_wind, reference_rad, sched, offset_at_rad(z.astype(dtype), t_s, knot_dt_s)
        )
        u, new, info = smc.apply(state, x_wind, ref, key)
        return u, new.replace(step=state.step + 1), {**info, "reference_rad": ref}

    return Controller(init=init, apply=apply)
