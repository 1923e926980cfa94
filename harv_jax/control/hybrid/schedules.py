"""The hybrid's zeta schedules as objects: ``zeta_schedule(name, ...)`` picks one when the hybrid is built.

A schedule acts twice in a hybrid step (``harv_jax.control.hybrid.law``):

- ``watch``, before the feedback term: whether the SMC flies alone (fallback). Every schedule but
  ``simplex`` runs the supervisor (``control.hybrid.supervisor``; off when the config disables it);
  ``simplex`` runs its own monitor (``hybrid.zeta.simplex_step``) instead.
- ``weigh``, after the feedback term: zeta per channel and the command before the safety filter
  (``hysteresis``, ``continuous``: ``control.hybrid.zeta``; ``gated``: ``control.hybrid.gate``; ``always``: 1;
  ``never`` and ``simplex``: 0). zeta = 1 in fallback.

The other fields are what the hybrid reads of the schedule: the SMC gains of its feedback term, the gate
gains of the certificate it logs, how the intervention window is kept and the schedule's own info entries.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax.numpy as jnp

from harv_jax.control.hybrid.gate import GateGains, default_gate_gains, gate
from harv_jax.control.hybrid.settings import HybridGains
from harv_jax.control.hybrid.supervisor import SupervisorState, outside_box, record_intervention, supervise
from harv_jax.control.hybrid.zeta import (
    SIMPLEX_REASONS,
    SimplexState,
    ZetaState,
    continuous_zeta,
    hysteresis_step,
    simplex_step,
)
from harv_jax.control.smc import SMCConfig, SMCGains, SMCTerms
from harv_jax.dynamics.state import vt_fps
from harv_jax.task.criteria import omega_norm_radps, tracking_errors


class Watch(NamedTuple):
    """Output of a schedule's ``watch``: the monitors' new states and whether the SMC flies alone."""

    supervisor: SupervisorState
    simplex: SimplexState
    fallback: jnp.ndarray


class ZetaInputs(NamedTuple):
    """What a schedule's ``weigh`` reads.

    Attributes:
        terms: the feedback term's SMCTerms.
        u_rl_rad: [3] learned command (after the cap; 0 in fallback).
        u_fb_rad: [3] feedback term.
        box_lo_rad, box_hi_rad: [3] the deflections reachable this step.
        mu_blended: bool [3], the channel's row is blended out (the mu row near vertical flight).
        fallback: bool, the SMC flies alone.
        zeta_prev: [3] zeta of the previous step.
        zeta_state: ZetaState of the hysteresis tube.
    """

    terms: SMCTerms
    u_rl_rad: jnp.ndarray
    u_fb_rad: jnp.ndarray
    box_lo_rad: jnp.ndarray
    box_hi_rad: jnp.ndarray
    mu_blended: jnp.ndarray
    fallback: jnp.ndarray
    zeta_prev: jnp.ndarray
    zeta_state: ZetaState


class ZetaOutput(NamedTuple):
    """Output of a schedule's ``weigh``.

    Attributes:
        zeta: [3] zeta per channel (1 in fallback).
        u_raw_rad: [3] command before the safety filter.
        integral_on: bool, the SMC's integral runs at this step.
        rl_acting: bool [3], channels on which the learned command contributes (fallback aside).
        zeta_state: ZetaState of the hysteresis tube after this step.
        switched: bool, the tube switched at this step.
    """

    zeta: jnp.ndarray
    u_raw_rad: jnp.ndarray
    integral_on: jnp.ndarray
    rl_acting: jnp.ndarray
    zeta_state: ZetaState
    switched: jnp.ndarray


class ZetaSchedule(NamedTuple):
    """One zeta schedule, as the hybrid step calls it.

    Attributes:
        smc_gains: SMCGains of the feedback term.
        gate_gains: GateGains of the logged certificate.
        watch: (supervisor, simplex, x_wind [10], reference_rad [3], u_rl_rad [3]) -> Watch.
        weigh: ZetaInputs -> ZetaOutput.
        record: (supervisor, intervened) -> supervisor, the intervention window after this step.
        info: SimplexState -> the schedule's own info entries.
    """

    smc_gains: SMCGains
    gate_gains: GateGains
    watch: Callable[..., Watch]
    weigh: Callable[[ZetaInputs], ZetaOutput]
    record: Callable[[SupervisorState, jnp.ndarray], SupervisorState]
    info: Callable[[SimplexState], dict[str, jnp.ndarray]]


def _scalar(zeta: jnp.ndarray, x: ZetaInputs, zeta_state: ZetaState, switched: jnp.ndarray) -> ZetaOutput:
    """One zeta for every channel: u = u_RL + zeta u_fb."""
    zeta = jnp.where(x.fallback, 1.0, zeta)
    zeta_ch = jnp.broadcast_to(zeta, (3,)).astype(x.u_fb_rad.dtype)
    return ZetaOutput(
        zeta=zeta_ch,
        u_raw_rad=x.u_rl_rad + zeta * x.u_fb_rad,
        integral_on=zeta > 0,
        rl_acting=zeta_ch < 1.0,
        zeta_state=zeta_state,
        switched=switched,
    )


def _constant(value: float) -> Callable[[ZetaInputs], ZetaOutput]:
    def weigh(x: ZetaInputs) -> ZetaOutput:
        zeta = jnp.full((), value, x.u_fb_rad.dtype)
        return _scalar(zeta, x, x.zeta_state, jnp.asarray(False))

    return weigh


def _hysteresis(g: HybridGains, dt_s: float) -> Callable[[ZetaInputs], ZetaOutput]:
    def weigh(x: ZetaInputs) -> ZetaOutput:
        zstate, switched = hysteresis_step(
            x.zeta_state, x.terms.e, g.e_on_rad, g.e_off_rad, g.zeta_min_dwell_s, dt_s
        )
        zeta = g.zeta_floor + (1.0 - g.zeta_floor) * zstate.on.astype(x.u_fb_rad.dtype)
        return _scalar(zeta, x, zstate, switched)

    return weigh


def _continuous(g: HybridGains) -> Callable[[ZetaInputs], ZetaOutput]:
    def weigh(x: ZetaInputs) -> ZetaOutput:
        z = continuous_zeta(x.terms.e, g.e_on_rad, g.e_off_rad)
        return _scalar(g.zeta_floor + (1.0 - g.zeta_floor) * z, x, x.zeta_state, jnp.asarray(False))

    return weigh


def _gated(g: HybridGains, smc_cfg: SMCConfig) -> Callable[[ZetaInputs], ZetaOutput]:
    dt_s = smc_cfg.dt_s

    def weigh(x: ZetaInputs) -> ZetaOutput:
        t = x.terms
        gated = gate(
            x.u_rl_rad,
            x.u_fb_rad,
            t.decoupling,
            t.s,
            x.box_lo_rad,
            x.box_hi_rad,
            g.smc,
            g.gate,
            smc_cfg.switching,
            dt_s,
            x.mu_blended,
            x.fallback | t.solve.guard_active,
            x.zeta_prev - g.gate.release_per_s * dt_s,
        )
        zeta = jnp.where(x.fallback, 1.0, gated.zeta)
        zeta_ch = jnp.broadcast_to(zeta, (3,)).astype(x.u_fb_rad.dtype)
        return ZetaOutput(
            zeta=zeta_ch,
            u_raw_rad=gated.u_raw_rad,
            integral_on=jnp.asarray(True),  # s contains the integral and the gate drives s to 0
            rl_acting=zeta_ch == 0.0,  # elsewhere the gate already chose zeta against the box
            zeta_state=x.zeta_state,
            switched=jnp.asarray(False),
        )

    return weigh


def _supervised(g: HybridGains, dt_s: float) -> Callable[..., Watch]:
    def watch(
        sup: SupervisorState,
        simplex: SimplexState,
        x_wind: jnp.ndarray,
        reference_rad: jnp.ndarray,
        u_rl_rad: jnp.ndarray,
    ) -> Watch:
        del reference_rad, u_rl_rad
        sup = supervise(sup, x_wind, g.supervisor, dt_s)
        return Watch(sup, simplex, sup.fallback)

    return watch


def _unsupervised(
    sup: SupervisorState,
    simplex: SimplexState,
    x_wind: jnp.ndarray,
    reference_rad: jnp.ndarray,
    u_rl_rad: jnp.ndarray,
) -> Watch:
    del x_wind, reference_rad, u_rl_rad
    return Watch(sup, simplex, sup.fallback)


def _simplex_watch(g: HybridGains, dt_s: float) -> Callable[..., Watch]:
    s = g.simplex

    def watch(
        sup: SupervisorState,
        simplex: SimplexState,
        x_wind: jnp.ndarray,
        reference_rad: jnp.ndarray,
        u_rl_rad: jnp.ndarray,
    ) -> Watch:
        simplex = simplex_step(
            simplex,
            outside_box(x_wind, s.box_low, s.box_high),
            tracking_errors(x_wind, reference_rad),
            jnp.all(jnp.isfinite(u_rl_rad)),
            s,
            dt_s,
            vt_fps(x_wind),
            omega_norm_radps(x_wind),
        )
        return Watch(sup, simplex, sup.fallback | simplex.latched)

    return watch


def _no_info(simplex: SimplexState) -> dict[str, jnp.ndarray]:
    del simplex
    return {}


def _handover_info(simplex: SimplexState) -> dict[str, jnp.ndarray]:
    return {f"handover_{r}": simplex.reason == i for i, r in enumerate(SIMPLEX_REASONS) if i}


def _keep(sup: SupervisorState, intervened: jnp.ndarray) -> SupervisorState:
    del intervened
    return sup


def zeta_schedule(name: str, g: HybridGains, smc_cfg: SMCConfig, supervisor: bool) -> ZetaSchedule:
    """The schedule ``name`` (a ``hybrid.ZETA_SCHEDULES`` name) with the hybrid's gains.

    Args:
        name: schedule name.
        g: HybridGains.
        smc_cfg: SMCConfig of the feedback term (its step and switching).
        supervisor: run the supervisor (ignored by ``simplex``, which has its own monitor).
    """
    dt_s = smc_cfg.dt_s
    if name == "simplex":
        # the certificate of the fallback SMC's own reaching law (its eps and boundary layer), the law that
        # acts after a hand-over; the simplex monitor reads no intervention window
        smc = g.simplex.fallback_smc
        return ZetaSchedule(
            smc, default_gate_gains(smc), _simplex_watch(g, dt_s), _constant(0.0), _keep, _handover_info
        )
    weighs = {
        "hysteresis": lambda: _hysteresis(g, dt_s),
        "continuous": lambda: _continuous(g),
        "gated": lambda: _gated(g, smc_cfg),
        "always": lambda: _constant(1.0),
        "never": lambda: _constant(0.0),
    }
    watch = _supervised(g, dt_s) if supervisor else _unsupervised
    return ZetaSchedule(g.smc, g.gate, watch, weighs[name](), record_intervention, _no_info)
