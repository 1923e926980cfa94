"""The hybrid controller u = u_RL + zeta u_fb (paper Secs. IV-C and V) with a safety filter and supervisor.

One step, for the wind state x and the reference y_ref:

1. supervisor: fallback (SMC-only) if x left the trusted box or the filter intervened too often
   (``harv_jax.control.hybrid.supervisor``);
2. learned command: u_RL = action_to_command(policy(observation(x, y_ref))), capped to a fraction of
   each deflection range (``safety.cap_authority``); u_RL = 0 in fallback;
3. feedback term designed on the RL-compensated dynamics (``smc_command(..., u_offset_rad=u_RL)``):
   u_fb = (L_g L_f y)^-1 (nu - L_f^2 y - L_g L_f y u_RL), nu the SMC's (reaching law included);
4. zeta from the schedule (``harv_jax.control.hybrid.schedules``: one object per name, picked when the hybrid
   is built; 1 in fallback);
5. u = u_RL + zeta u_fb, then the position/rate box of the safety filter (``safety.filter_command``).

The ``simplex`` schedule (Simplex architecture; the default) lets the policy act alone (zeta = 0) and hands
over to the SMC for good (zeta = 1, u_RL = 0) on the first step the state leaves a box the SMC is shown to
recover from, the policy's command is non-finite, or, from a deadline on, a tracking error leaves a tube
while the aircraft is not slow and calm (``hybrid.zeta.simplex_step``; it replaces step 1's supervisor): the
policy's speed is kept where it recovers, and the SMC's recovery covers the rest. Its SMC flies with the
softer ``hybrid.zeta.simplex_fallback_gains`` (less control activity after the hand-over), or, for a policy
that flies behind a measurement path, with the default SMC gains (``path_hybrid_gains``); every other
schedule uses ``HybridGains.smc``.

The ``gated`` schedule replaces 4-5 by ``harv_jax.control.hybrid.gate``: a zeta per channel, the least that
keeps the reaching condition for the command that acts (clipped to this step's box), u = u_RL + A^-1 (zeta (.)
A u_fb) (= u_RL + zeta u_fb for equal zetas); the SMC's integral then runs at every step (s contains it,
and the gate drives s to 0, so the integral removes the learned law's bias instead of winding up).

Identity (exact where the solve is unguarded): u_RL + zeta u_fb = (1 - zeta) u_RL + zeta u_SMC, so
zeta = 1 is the SMC-only law for any policy and zeta = 0 the (filtered) RL-only law.

The SMC's integral runs only while zeta > 0 (with zeta = 0 the learned law is in charge and the
integral would wind up on its errors); its anti-windup saturation test is the SMC's (position limits of
the unfiltered command), so that with zeta = 1 the integrator states of both controllers are equal.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.control.hybrid.gate import certificate_holds, default_gate_gains
from harv_jax.control.hybrid.safety import cap_authority, filter_command, limit_box
from harv_jax.control.hybrid.schedules import ZetaInputs, zeta_schedule
from harv_jax.control.hybrid.settings import DEFAULT_ZETA, ZETA_SCHEDULES, HybridGains, ZetaScheduleName
from harv_jax.control.hybrid.supervisor import (
    SupervisorState,
    default_supervisor_gains,
    supervisor_init,
)
from harv_jax.control.hybrid.zeta import (
    SimplexGains,
    SimplexState,
    ZetaState,
    simplex_fallback_gains,
    simplex_init,
    zeta_init,
)
from harv_jax.control.smc import SMCConfig, default_gains, smc_command, update_integral
from harv_jax.task.spaces import action_to_command, observation
from harv_jax.task.spec import (
    RECOVERY_ALPHA_TOL_RAD,
    RECOVERY_BETA_TOL_RAD,
    RECOVERY_MU_TOL_RAD,
    V_MAX_FPS,
    V_MIN_FPS,
)

#: The paper's tube: e_on = 0.05 rad on every channel (e_off is not given; 0.02 rad here).
PAPER_E_ON_RAD = (0.05, 0.05, 0.05)
PAPER_E_OFF_RAD = (0.02, 0.02, 0.02)
#: Default tube, inside the recovery criterion (2, 1, 2 deg = 0.035, 0.017, 0.035 rad) so that drift of the
#: learned law inside the tube cannot fail the criterion. On 256 Monte Carlo runs with the shipped partial
#: policy the paper's tube recovered 0.4% with hysteresis (drift to 2.9 deg in mu), this one 100%
#: (``experiments/hybrid_sweep/README.md``).
DEFAULT_E_ON_RAD = (0.03, 0.015, 0.03)
DEFAULT_E_OFF_RAD = (0.01, 0.005, 0.01)
#: Default zeta floor: the SMC keeps 20% authority inside the tube, so its integral removes the learned
#: law's steady bias (full policy, 256 runs: terminal alpha error 0.76 deg -> 0.017 deg, recovery 99.2% ->
#: 100%; ``experiments/hybrid_sweep/README.md``). Set 0 for the paper's tube.
DEFAULT_ZETA_FLOOR = 0.2
#: ``simplex`` schedule: the policy must hold every tracking error inside twice the recovery criterion's
#: tolerance from 10 s after engagement on, or the SMC takes over (``experiments/hybrid_simplex/``).
DEFAULT_SIMPLEX_DEADLINE_S = 10.0
#: ``simplex`` box of [V, alpha, beta, p, q, r] (ft/s, rad, rad/s): inside the states the fallback SMC is
#: shown to recover from (``experiments/hybrid_simplex/box_probe.py``: 4000 states uniform over alpha
#: -0.5..1.8 rad, |beta| 0.8 rad, |p| 5, |q| 3.5, |r| 3 rad/s, V 100-1500 ft/s, any mu, |gamma| 60 deg; 99.8%
#: recovered, nominal and randomized aircraft), with a margin; V within the envelope.
DEFAULT_SIMPLEX_BOX_LOW = (V_MIN_FPS, -0.45, -0.6, -3.0, -3.0, -2.5)
DEFAULT_SIMPLEX_BOX_HIGH = (V_MAX_FPS, 1.6, 0.6, 3.0, 3.0, 2.5)
#: ``simplex`` deadline hold: below 250 ft/s with ||omega|| < 0.5 rad/s the deadline waits, until 30 s after
#: engagement (the box still trips). There the fast policy rides out the bottom of its braking (~130 ft/s,
#: errors just outside the tube, rates small), where the SMC has little authority: after such a hand-over it
#: spent 4.9 rad of TV where the policy spent 1.9 (Monte Carlo key 123, ``experiments/hybrid_simplex/``).
DEFAULT_SIMPLEX_HOLD_SPEED_FPS = 250.0
DEFAULT_SIMPLEX_HOLD_RATE_RADPS = 0.5
DEFAULT_SIMPLEX_HOLD_UNTIL_S = 30.0
DEFAULT_SIMPLEX_TUBE_RAD = tuple(
    2.0 * t for t in (RECOVERY_ALPHA_TOL_RAD, RECOVERY_BETA_TOL_RAD, RECOVERY_MU_TOL_RAD)
)


def default_hybrid_gains(dtype=None) -> HybridGains:
    """Default tube (DEFAULT_E_ON_RAD), zeta floor 0.2; 0.5 s dwell; no authority cap; default gate and
    supervisor."""
    dtype = jnp.result_type(float) if dtype is None else dtype
    smc = default_gains(dtype)
    return HybridGains(
        smc=smc,
        e_on_rad=jnp.asarray(DEFAULT_E_ON_RAD, dtype),
        e_off_rad=jnp.asarray(DEFAULT_E_OFF_RAD, dtype),
        zeta_min_dwell_s=jnp.asarray(0.5, dtype),
        zeta_floor=jnp.asarray(DEFAULT_ZETA_FLOOR, dtype),
        authority_frac=jnp.ones((3,), dtype),
        gate=default_gate_gains(smc),
        supervisor=default_supervisor_gains(dtype),
        simplex=SimplexGains(
            box_low=jnp.asarray(DEFAULT_SIMPLEX_BOX_LOW, dtype),
            box_high=jnp.asarray(DEFAULT_SIMPLEX_BOX_HIGH, dtype),
            deadline_s=jnp.asarray(DEFAULT_SIMPLEX_DEADLINE_S, dtype),
            tube_rad=jnp.asarray(DEFAULT_SIMPLEX_TUBE_RAD, dtype),
            fallback_smc=simplex_fallback_gains(dtype),
            hold_speed_fps=jnp.asarray(DEFAULT_SIMPLEX_HOLD_SPEED_FPS, dtype),
            hold_rate_radps=jnp.asarray(DEFAULT_SIMPLEX_HOLD_RATE_RADPS, dtype),
            hold_until_s=jnp.asarray(DEFAULT_SIMPLEX_HOLD_UNTIL_S, dtype),
        ),
    )


def path_hybrid_gains(dtype=None) -> HybridGains:
    """``default_hybrid_gains`` for a policy that flies behind a measurement path (the disturbed world):
    the ``simplex`` fallback SMC with the default SMC gains instead of the soft ones, which lose disturbed
    runs that these recover (``experiments/robust_policy/README.md``, "The hybrid's hand-over under
    disturbances")."""
    g = default_hybrid_gains(dtype)
    return g.replace(simplex=g.simplex.replace(fallback_smc=default_gains(g.smc.lambda1_ps.dtype)))


@dataclasses.dataclass(frozen=True)
class HybridConfig:
    """Static options (changing them recompiles).

    Attributes:
        schedule: zeta schedule: ``simplex`` (default, as the CLI: zeta = 0 until a monitor trips, then 1
            for good: ``hybrid.zeta.simplex_step``), ``continuous``, ``hysteresis`` (the paper's tube),
            ``gated`` (per channel, from the reaching condition: ``harv_jax.control.hybrid.gate``), ``always``
            (zeta = 1), ``never`` (zeta = 0, the filtered RL-only law).
        smc: SMCConfig of the feedback term.
        supervisor: enable the fallback supervisor.
        window_steps: length of the supervisor's intervention window, steps.
    """

    schedule: ZetaScheduleName = DEFAULT_ZETA
    smc: SMCConfig = SMCConfig()
    supervisor: bool = True
    window_steps: int = 100

    def __post_init__(self) -> None:
        if self.schedule not in ZETA_SCHEDULES:
            raise ValueError(f"schedule={self.schedule!r}; allowed: {', '.join(ZETA_SCHEDULES)}")
        if self.window_steps < 1:
            raise ValueError(f"window_steps={self.window_steps} must be >= 1")


@struct.dataclass
class HybridState:
    """Per-aircraft state of the hybrid controller.

    Attributes:
        params: aircraft of the controller model (and its limits).
        integral_rad_s: [3] SMC integral of e.
        u_prev_rad: [3] previous filtered command (the rate box is relative to it).
        zeta: ZetaState of the hysteresis schedule.
        zeta_gate: [3] zeta of the previous step (the ``gated`` schedule's release floor).
        supervisor: SupervisorState.
        simplex: SimplexState of the ``simplex`` schedule.
        interventions: int32 [3] per-channel count of steps the filter changed the command.
    """

    params: AircraftParams
    integral_rad_s: jnp.ndarray
    u_prev_rad: jnp.ndarray
    zeta: ZetaState
    zeta_gate: jnp.ndarray
    supervisor: SupervisorState
    simplex: SimplexState
    interventions: jnp.ndarray


def make_hybrid(
    act: Callable[[jax.Array], jax.Array],
    cfg: HybridConfig | None = None,
    gains: HybridGains | None = None,
) -> Controller:
    """Build the hybrid controller.

    Args:
        act: deterministic policy ``obs [11] -> action [3]`` in [-1, 1] (``policy.load(p).deterministic``).
        cfg: static options (default ``HybridConfig()``).
        gains: traced settings (default ``default_hybrid_gains()``).

    Returns:
        Controller whose ``info`` holds: zeta (mean over channels), zeta_channels [3], zeta_switched,
        policy_unmodified (the command that acts is the policy's, bit for bit), correction_rad [3]
        (|u - u_RL|), fallback, fallback_entered, fallback_reason, u_rl_rad [3], u_fb_rad [3],
        u_unfiltered_rad [3], cap_active [3], limit_active [3], intervened, e, e_dot, s [3], w_mu, saturated,
        integral_rad_s [3], the certificate (``control.hybrid.gate.certificate_holds``) of the command that
        acts, split by whether the box clipped it: cert_free_defined, cert_free_holds, cert_sat_defined,
        cert_sat_holds (bool [3]; defined: solve exact, channel in its sliding mode), and with the
        ``simplex`` schedule handover_box, handover_deadline, handover_nonfinite (it handed over to the SMC
        for that reason, at this step or before).
    """
    cfg = HybridConfig() if cfg is None else cfg
    g = default_hybrid_gains() if gains is None else gains
    dt_s = cfg.smc.dt_s
    sched = zeta_schedule(cfg.schedule, g, cfg.smc, cfg.supervisor)

    def init(params: AircraftParams) -> HybridState:
        dtype = jnp.result_type(params.mass_slug)
        z3 = jnp.zeros((3,), dtype)
        return HybridState(
            params=params,
            integral_rad_s=z3,
            u_prev_rad=z3,
            zeta=zeta_init(dtype),
            zeta_gate=z3,
            supervisor=supervisor_init(cfg.window_steps, dtype),
            simplex=simplex_init(dtype),
            interventions=jnp.zeros((3,), jnp.int32),
        )

    def apply(state: HybridState, x_wind: jnp.ndarray, reference_rad: jnp.ndarray, key: jax.Array):
        del key  # deterministic
        params = state.params
        obs = observation(x_wind, reference_rad)
        a = jnp.clip(act(obs), -1.0, 1.0)
        u_rl_raw = action_to_command(a, params.u_min_rad, params.u_max_rad).astype(state.u_prev_rad.dtype)
        u_rl, cap_active = cap_authority(u_rl_raw, params, g.authority_frac)
        # decided before u_fb: in fallback the SMC flies without the policy
        watch = sched.watch(state.supervisor, state.simplex, x_wind, reference_rad, u_rl)
        fallback = watch.fallback
        u_rl = jnp.where(fallback, 0.0, u_rl)

        smc_g = sched.smc_gains
        u_fb, terms = smc_command(
            x_wind, reference_rad, state.integral_rad_s, params, smc_g, cfg.smc, u_offset_rad=u_rl
        )
        box_lo, box_hi = limit_box(state.u_prev_rad, params, dt_s)
        mu_blended = jnp.stack([jnp.asarray(False), jnp.asarray(False), terms.w_mu < 1.0])
        z = sched.weigh(
            ZetaInputs(terms, u_rl, u_fb, box_lo, box_hi, mu_blended, fallback, state.zeta_gate, state.zeta)
        )

        u_raw = jnp.where(jnp.all(jnp.isfinite(z.u_raw_rad)), z.u_raw_rad, state.u_prev_rad)
        u, limit_active = filter_command(u_raw, state.u_prev_rad, params, dt_s)
        saturated = jnp.any(jnp.clip(u_raw, params.u_min_rad, params.u_max_rad) != u_raw)
        integral = update_integral(state.integral_rad_s, terms, saturated, smc_g, cfg.smc, z.integral_on)

        # the certificate of the command that acts, on the controller model (any schedule)
        holds = certificate_holds(
            terms.decoupling, u, u_rl + u_fb, terms.s, smc_g, sched.gate_gains, cfg.smc.switching, dt_s
        )
        defined = ~terms.solve.guard_active & ~mu_blended & jnp.all(jnp.isfinite(terms.s))
        boxed = jnp.any(limit_active)

        # interventions attributable to the learned command: its cap, or the box while it contributes
        cap_counted = cap_active & ~fallback
        chan = cap_counted | (limit_active & ~fallback & z.rl_acting)
        intervened = jnp.any(chan)
        sup = sched.record(watch.supervisor, intervened)

        new_state = state.replace(
            integral_rad_s=integral,
            u_prev_rad=u,
            zeta=z.zeta_state,
            zeta_gate=z.zeta,
            supervisor=sup,
            simplex=watch.simplex,
            interventions=state.interventions + chan.astype(jnp.int32),
        )
        info = {
            "zeta": jnp.mean(z.zeta),
            "zeta_channels": z.zeta,
            "zeta_switched": z.switched,
            "zeta_handed_over": zeta_handed_over(state.zeta_gate, z.zeta),
            "policy_unmodified": ~fallback & jnp.all(u == u_rl_raw),
            "correction_rad": jnp.abs(u - u_rl),
            "fallback": sup.fallback,
            "fallback_entered": sup.fallback & ~state.supervisor.fallback,
            "fallback_reason": sup.reason,
            "u_rl_rad": u_rl,
            "u_fb_rad": u_fb,
            "u_unfiltered_rad": u_raw,
            "cap_active": cap_counted,
            "limit_active": limit_active,
            "intervened": intervened,
            "e": terms.e,
            "e_dot": terms.e_dot,
            "s": terms.s,
            "w_mu": terms.w_mu,
            "saturated": saturated,
            "integral_rad_s": integral,
            "cert_free_defined": defined & ~boxed,
            "cert_free_holds": defined & ~boxed & holds,
            "cert_sat_defined": defined & boxed,
            "cert_sat_holds": defined & boxed & holds,
            **sched.info(watch.simplex),
        }
        return u, new_state, info

    return Controller(init=init, apply=apply)


def zeta_handed_over(zeta_prev: jnp.ndarray, zeta: jnp.ndarray) -> jnp.ndarray:
    """Whether the larger share of the command changed hands at this step: the mean zeta over the channels
    crossed 1/2 since the previous step (the hybrid starts from the policy alone, zeta = 0). Counts every
    schedule's hand-overs alike: a simplex hand-over, a fallback, a hysteresis tube switch."""
    return (jnp.mean(zeta) >= 0.5) != (jnp.mean(zeta_prev) >= 0.5)


def zero_policy_action(params: AircraftParams) -> jnp.ndarray:
    """The normalized action [3] that commands zero deflection (inverse of ``action_to_command``)."""
    return 2.0 * (0.0 - params.u_min_rad) / (params.u_max_rad - params.u_min_rad) - 1.0
