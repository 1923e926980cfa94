"""Fallback supervisor of the hybrid controller: SMC-only when the learned command cannot be trusted.

Falls back (reason code in ``FallbackReason``) when

- the state leaves the box the policy was trained on (out of distribution), or
- the safety filter intervened on more than ``max_interventions`` of the last ``window_steps`` steps;

and returns to the hybrid law after both conditions have been normal for ``dwell_s`` without a break.
The mode for step k is decided from the state at k and the interventions up to k - 1 (``supervise``);
the intervention of step k is then recorded (``record_intervention``). Pure and vmappable.
"""

from __future__ import annotations

import enum

import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.dynamics.state import WIND_INDEX
from harv_jax.task.scenarios import RESET_HIGH, RESET_LOW
from harv_jax.task.spec import ALPHA_MIN_RAD, V_MIN_FPS


class FallbackReason(enum.IntEnum):
    """Why the supervisor is in fallback (0: it is not)."""

    NONE = 0
    OUT_OF_ENVELOPE = 1
    INTERVENTIONS = 2


#: Indices of [V, alpha, beta, p, q, r] in the wind state.
SUPERVISED_INDEX = tuple(WIND_INDEX[n] for n in ("V", "alpha", "beta", "p", "q", "r"))
#: Default trusted box of [V ft/s, alpha, beta rad, p, q, r rad/s]: the paper's reset bounds (where
#: training episodes start), widened by 10% of their width on each side, with alpha's lower edge at the
#: envelope's lower alpha (``task.spec.ALPHA_MIN_RAD``).
_WIDTH = RESET_HIGH[:6] - RESET_LOW[:6]
DEFAULT_BOX_LOW = np.maximum(
    RESET_LOW[:6] - 0.1 * _WIDTH, [V_MIN_FPS, ALPHA_MIN_RAD, -np.inf, -np.inf, -np.inf, -np.inf]
)
DEFAULT_BOX_HIGH = RESET_HIGH[:6] + 0.1 * _WIDTH


@struct.dataclass
class SupervisorGains:
    """Traced settings of the supervisor.

    Attributes:
        box_low, box_high: [6] trusted box of [V, alpha, beta, p, q, r] (ft/s, rad, rad/s).
        max_interventions: fall back when more steps than this intervened within the window.
        dwell_s: time conditions must be normal before returning to the hybrid law, s.
    """

    box_low: jnp.ndarray
    box_high: jnp.ndarray
    max_interventions: jnp.ndarray
    dwell_s: jnp.ndarray


def default_supervisor_gains(dtype=None) -> SupervisorGains:
    """Trusted box = widened reset bounds; > 50 of the last 100 steps intervened; 2 s dwell."""
    dtype = jnp.result_type(float) if dtype is None else dtype
    return SupervisorGains(
        box_low=jnp.asarray(DEFAULT_BOX_LOW, dtype),
        box_high=jnp.asarray(DEFAULT_BOX_HIGH, dtype),
        max_interventions=jnp.asarray(50, jnp.int32),
        dwell_s=jnp.asarray(2.0, dtype),
    )


@struct.dataclass
class SupervisorState:
    """Per-aircraft supervisor state.

    Attributes:
        fallback: bool, SMC-only mode.
        reason: int32 FallbackReason of the current fallback.
        normal_time_s: time conditions have been normal during the fallback, s.
        window: bool [W] ring buffer of per-step interventions.
        window_pos: int32 next slot of the ring buffer.
        window_count: int32 number of True slots in ``window`` (kept with it, so no step sums the window).
        n_fallbacks: int32 fallbacks so far.
    """

    fallback: jnp.ndarray
    reason: jnp.ndarray
    normal_time_s: jnp.ndarray
    window: jnp.ndarray
    window_pos: jnp.ndarray
    window_count: jnp.ndarray
    n_fallbacks: jnp.ndarray


def supervisor_init(window_steps: int, dtype) -> SupervisorState:
    """Hybrid mode, empty window."""
    return SupervisorState(
        fallback=jnp.asarray(False),
        reason=jnp.asarray(FallbackReason.NONE, jnp.int32),
        normal_time_s=jnp.asarray(0.0, dtype),
        window=jnp.zeros((window_steps,), bool),
        window_pos=jnp.asarray(0, jnp.int32),
        window_count=jnp.asarray(0, jnp.int32),
        n_fallbacks=jnp.asarray(0, jnp.int32),
    )


def outside_box(x_wind: jnp.ndarray, box_low: jnp.ndarray, box_high: jnp.ndarray) -> jnp.ndarray:
    """bool: [V, alpha, beta, p, q, r] of ``x_wind`` outside [box_low, box_high] (or non-finite)."""
    z = jnp.stack([x_wind[i] for i in SUPERVISED_INDEX])
    return ~jnp.all((z >= box_low) & (z <= box_high))


def out_of_envelope(x_wind: jnp.ndarray, gains: SupervisorGains) -> jnp.ndarray:
    """bool: [V, alpha, beta, p, q, r] outside the trusted box (or non-finite)."""
    return outside_box(x_wind, gains.box_low, gains.box_high)


def supervise(
    state: SupervisorState, x_wind: jnp.ndarray, gains: SupervisorGains, dt_s: float
) -> SupervisorState:
    """Decide the mode for this step (``state.fallback`` of the result)."""
    ood = out_of_envelope(x_wind, gains)
    too_many = state.window_count > gains.max_interventions
    trigger = ood | too_many
    enter = ~state.fallback & trigger
    normal_time = jnp.where(state.fallback & ~trigger, state.normal_time_s + dt_s, 0.0)
    leave = state.fallback & (normal_time >= gains.dwell_s - 0.5 * dt_s)  # half a step: float sums
    reason = jnp.where(
        enter,
        jnp.where(ood, FallbackReason.OUT_OF_ENVELOPE, FallbackReason.INTERVENTIONS),
        jnp.where(leave, FallbackReason.NONE, state.reason),
    ).astype(jnp.int32)
    return state.replace(
        fallback=(state.fallback | enter) & ~leave,
        reason=reason,
        normal_time_s=jnp.where(leave, 0.0, normal_time),
        n_fallbacks=state.n_fallbacks + enter.astype(jnp.int32),
    )


def record_intervention(state: SupervisorState, intervened: jnp.ndarray) -> SupervisorState:
    """Push this step's intervention flag into the ring buffer (the flag it replaces leaves the count)."""
    w = state.window.shape[0]
    leaving = state.window[state.window_pos]
    return state.replace(
        window=state.window.at[state.window_pos].set(intervened),
        window_pos=(state.window_pos + 1) % w,
        window_count=state.window_count + intervened.astype(jnp.int32) - leaving.astype(jnp.int32),
    )
