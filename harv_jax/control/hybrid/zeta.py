"""Schedules of the hybrid weight zeta in u = u_RL + zeta u_fb (paper Sec. V, tube-based switching).

- ``hysteresis`` (the paper's tube): zeta jumps to 1 when any tracking error |e_i| exceeds ``e_on``
  and back to 0 only when all are below ``e_off < e_on``; after a switch, zeta is held for at least
  ``min_dwell_s`` (no Zeno behaviour even when noise crosses both thresholds every step).
- ``continuous`` (the paper's suggested extension): zeta = smoothstep(max_i (|e_i| - e_off_i) /
  (e_on_i - e_off_i)), 0 inside the inner tube, 1 outside the outer one, C^1 in between; no state.

Tube radii may be scalars (the paper's) or per channel [3].

Errors are the SMC's e = [alpha - alpha_d, beta - beta_d, wrap(mu - mu_d)] in rad.
"""

from __future__ import annotations

import jax.numpy as jnp
from flax import struct

from harv_jax.control.smc import SMCGains
from harv_jax.control.smc import default_gains as default_smc_gains
from harv_jax.smooth import smoothstep

#: A time since the last switch long enough for any dwell: the first step may switch at once.
NEVER_SWITCHED_S = 1.0e9


@struct.dataclass
class ZetaState:
    """State of the hysteresis schedule (vmap it with the aircraft).

    Attributes:
        on: bool, zeta = 1.
        time_since_switch_s: time since the last switch, s.
        n_switches: int32, switches so far.
    """

    on: jnp.ndarray
    time_since_switch_s: jnp.ndarray
    n_switches: jnp.ndarray


def zeta_init(dtype) -> ZetaState:
    """Start with zeta = 0 and no dwell pending."""
    return ZetaState(
        on=jnp.asarray(False),
        time_since_switch_s=jnp.asarray(NEVER_SWITCHED_S, dtype),
        n_switches=jnp.asarray(0, jnp.int32),
    )


def hysteresis_step(
    state: ZetaState,
    e_rad: jnp.ndarray,
    e_on_rad: jnp.ndarray,
    e_off_rad: jnp.ndarray,
    min_dwell_s: jnp.ndarray,
    dt_s: float,
) -> tuple[ZetaState, jnp.ndarray]:
    """One step of the hysteresis tube.

    Args:
        state: ZetaState before this step.
        e_rad: [3] tracking errors at this step.
        e_on_rad, e_off_rad: outer and inner tube radii (e_off < e_on), rad: scalars or per channel [3].
        min_dwell_s: minimum time between two switches, s.
        dt_s: step, s.

    Returns:
        (new state whose ``on`` is zeta for this step, bool: a switch happened at this step).
    """
    err = jnp.abs(e_rad)
    err = jnp.where(jnp.isfinite(err), err, jnp.inf)  # a non-finite error counts as outside the tube
    want = jnp.where(state.on, jnp.all(err < e_off_rad), jnp.any(err > e_on_rad))
    switch = want & (state.time_since_switch_s >= min_dwell_s - 0.5 * dt_s)  # half a step: float sums
    new = ZetaState(
        on=state.on ^ switch,
        time_since_switch_s=jnp.where(switch, 0.0, state.time_since_switch_s + dt_s),
        n_switches=state.n_switches + switch.astype(jnp.int32),
    )
    return new, switch


def continuous_zeta(e_rad: jnp.ndarray, e_on_rad: jnp.ndarray, e_off_rad: jnp.ndarray) -> jnp.ndarray:
    """zeta in [0, 1]: smoothstep of the largest |e_i| between e_off_i (0) and e_on_i (1); non-finite -> 1.

    ``e_on_rad``, ``e_off_rad``: scalars or per channel [3].
    """
    err = jnp.abs(e_rad)
    z = jnp.max(jnp.clip((err - e_off_rad) / jnp.maximum(e_on_rad - e_off_rad, 1e-9), 0.0, 1.0))
    return jnp.where(jnp.all(jnp.isfinite(err)), smoothstep(z), 1.0)


@struct.dataclass
class SimplexGains:
    """Traced settings of the ``simplex`` schedule (Simplex architecture: Sha 2001; Seto et al. 1998).

    Attributes:
        box_low, box_high: [6] box of [V, alpha, beta, p, q, r] (ft/s, rad, rad/s) the policy may fly in.
        deadline_s: from this time on the tracking errors must stay inside ``tube_rad``, s.
        tube_rad: [3] |e_alpha|, |e_beta|, |e_mu| allowed from the deadline on, rad.
        fallback_smc: SMCGains of the SMC that flies after the hand-over (``simplex_fallback_gains``).
        hold_speed_fps, hold_rate_radps, hold_until_s: the deadline does not trip while V < hold_speed_fps
            and ||omega|| < hold_rate_radps, before hold_until_s (slow and calm: the SMC has no more authority
            there than the policy; 0 ft/s: never held). The box trips as ever.
    """

    box_low: jnp.ndarray
    box_high: jnp.ndarray
    deadline_s: jnp.ndarray
    tube_rad: jnp.ndarray
    fallback_smc: SMCGains
    hold_speed_fps: jnp.ndarray
    hold_rate_radps: jnp.ndarray
    hold_until_s: jnp.ndarray


#: SMC gains of the ``simplex`` fallback that differ from ``smc.default_gains``: the "soft" corner of the
#: Pareto study (``experiments/hybrid_pareto/``: on its control-TV front, 100% recovered, slower than the
#: default). After a hand-over the SMC must recover, not race: with the ``fast`` policy these gains cut the
#: hybrid's control TV by 0.5-0.8 rad against the default gains (``experiments/hybrid_simplex/README.md``).
SIMPLEX_FALLBACK_SMC: dict[str, float] = {
    "lambda1_ps": 3.0,
    "k_reach": 0.25,
    "eps_radps2": 0.1,
    "phi_radps": 0.4,
}


def simplex_fallback_gains(dtype=None) -> SMCGains:
    """The ``simplex`` fallback's SMC gains: ``smc.default_gains`` with ``SIMPLEX_FALLBACK_SMC``."""
    g = default_smc_gains(dtype)
    return g.replace(**{k: jnp.full_like(getattr(g, k), v) for k, v in SIMPLEX_FALLBACK_SMC.items()})


@struct.dataclass
class SimplexState:
    """State of the ``simplex`` schedule.

    Attributes:
        time_s: time since engagement, s.
        latched: bool, the SMC has taken over for good.
        reason: int32 index in ``SIMPLEX_REASONS`` of the take-over (0: none yet).
    """

    time_s: jnp.ndarray
    latched: jnp.ndarray
    reason: jnp.ndarray


def simplex_init(dtype) -> SimplexState:
    """The policy in charge at engagement."""
    return SimplexState(
        time_s=jnp.zeros((), dtype), latched=jnp.asarray(False), reason=jnp.asarray(0, jnp.int32)
    )


#: Why the ``simplex`` schedule handed over to the SMC (``SimplexState.reason`` indexes it).
SIMPLEX_REASONS: tuple[str, ...] = ("none", "box", "deadline", "nonfinite")


def simplex_step(
    state: SimplexState,
    outside_box: jnp.ndarray,
    e_rad: jnp.ndarray,
    command_finite: jnp.ndarray,
    gains: SimplexGains,
    dt_s: float,
    speed_fps: jnp.ndarray,
    rate_radps: jnp.ndarray,
) -> SimplexState:
    """One step of the ``simplex`` schedule: zeta = 0 (the policy acts alone) until the first step on which
    the state is outside the box (``outside_box``), the policy's command is non-finite, or, from
    ``deadline_s`` on, a tracking error is outside ``tube_rad`` while the aircraft is not held (slow and calm:
    ``speed_fps`` < ``hold_speed_fps`` and ``rate_radps`` = ||omega|| < ``hold_rate_radps``, before
    ``hold_until_s``); from then on zeta = 1 (the SMC) for good.

    Returns:
        the new state, whose ``latched`` is zeta for this step.
    """
    outside_tube = ~jnp.all(jnp.abs(e_rad) < gains.tube_rad)  # a non-finite error counts as outside
    held = (speed_fps < gains.hold_speed_fps) & (rate_radps < gains.hold_rate_radps)
    held = held & (state.time_s < gains.hold_until_s - 0.5 * dt_s)
    late = (state.time_s >= gains.deadline_s - 0.5 * dt_s) & outside_tube  # half a step: float sums
    late = late & ~held
    why = jnp.where(outside_box, 1, jnp.where(~command_finite, 3, jnp.where(late, 2, 0))).astype(jnp.int32)
    enter = ~state.latched & (why > 0)
    return SimplexState(
        time_s=state.time_s + dt_s,
        latched=state.latched | enter,
        reason=jnp.where(enter, why, state.reason),
    )
