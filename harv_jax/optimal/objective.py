"""The smooth surrogate of recovery time and the differentiable rollout it is computed on.

The rollout is the standard closed loop (``harv_jax.evaluation.closed_loop``'s step, operation for
operation: controller, non-finite command -> current deflection, ``plant_step``, non-finite state held)
written for reverse-mode differentiation: the aircraft is a constant of the scan, not part of its carry,
and the time loop is a scan over chunks of ``chunk_steps`` steps whose bodies are rematerialized
(``jax.checkpoint``), so the memory of a gradient is one carry per chunk plus one chunk of residuals.

Surrogate (per run, over the optimization horizon of n_steps steps, t_k = k dt_s, T = n_steps dt_s):

    n_k = sum_i (e_i(t_k) / tol_i)^2 + (||omega(t_k)|| / tol_omega)^2
    c_k = log(1 + n_k)
    J   = (1 / n_steps) sum_k w(t_k) c_k,   w(t) = t / T + hold_weight [t >= T - hold_s]

with i = alpha, beta, mu and the criterion's tolerances (``task.criteria``); c is smoothly clipped: about n
inside the criterion, logarithmic far out, so far-off runs still get gradients of a sane size.

The recovery time is the last time the criterion fails; log(1 + n) is a smooth count of "the criterion
fails here" and w grows with t, so late failures cost most, and failures inside the final hold window
(the criterion's 10 s) cost ``hold_weight`` more: a reference that recovers but does not hold is penalized.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.dynamics.plant import plant_step
from harv_jax.dynamics.state import BodyState, is_finite, to_wind
from harv_jax.task.criteria import omega_norm_radps, tracking_errors
from harv_jax.task.spec import (
    DT_S,
    RECOVERY_ALPHA_TOL_RAD,
    RECOVERY_BETA_TOL_RAD,
    RECOVERY_HOLD_S,
    RECOVERY_MU_TOL_RAD,
    RECOVERY_OMEGA_TOL_RADPS,
)


@dataclasses.dataclass(frozen=True)
class SurrogateConfig:
    """Static settings of the surrogate and its rollout.

    Attributes:
        n_steps: optimization horizon, plant steps.
        chunk_steps: steps per rematerialized chunk (n_steps must be a multiple of it).
        hold_s: length of the final hold window of the horizon, s (the criterion's).
        hold_weight: extra weight of the hold window.
        dt_s: plant step, s.
    """

    n_steps: int
    chunk_steps: int = 100
    hold_s: float = RECOVERY_HOLD_S
    hold_weight: float = 2.0
    dt_s: float = DT_S


def step_cost(x_wind: jnp.ndarray, reference_rad: jnp.ndarray) -> jnp.ndarray:
    """c = log(1 + n): n the squared criterion errors in units of their tolerances (module docstring)."""
    tol = jnp.asarray([RECOVERY_ALPHA_TOL_RAD, RECOVERY_BETA_TOL_RAD, RECOVERY_MU_TOL_RAD], x_wind.dtype)
    e = tracking_errors(x_wind, reference_rad) / tol
    w = omega_norm_radps(x_wind) / RECOVERY_OMEGA_TOL_RADPS
    n = jnp.sum(e * e, axis=-1) + w * w
    return jnp.log1p(jnp.where(jnp.isfinite(n), n, 1e12))


def time_weight(t_s: jnp.ndarray, cfg: SurrogateConfig) -> jnp.ndarray:
    """w(t) = t / T + hold_weight inside the final hold window."""
    horizon_s = cfg.n_steps * cfg.dt_s
    return t_s / horizon_s + cfg.hold_weight * (t_s >= horizon_s - cfg.hold_s - 1e-9)


def surrogate(
    controller: Controller,
    params: AircraftParams,
    body0: BodyState,
    delta0_rad: jnp.ndarray,
    reference_rad: jnp.ndarray,
    cfg: SurrogateConfig,
) -> jnp.ndarray:
    """J of one run (scalar): ``controller`` flown from (body0, delta0_rad) for cfg.n_steps steps.

    The closed-loop step is ``closed_loop``'s; the controller's key is unused (deterministic controllers).
    Differentiate with respect to whatever ``controller`` closes over.
    """
    if cfg.n_steps % cfg.chunk_steps:
        raise ValueError(f"n_steps={cfg.n_steps} is not a multiple of chunk_steps={cfg.chunk_steps}")
    dtype = body0.uvw_fps.dtype
    reference_rad = jnp.asarray(reference_rad, dtype)
    cstate0 = controller.init(params)
    if hasattr(cstate0, "u_prev_rad"):
        cstate0 = cstate0.replace(u_prev_rad=delta0_rad.astype(cstate0.u_prev_rad.dtype))
    has_params = hasattr(cstate0, "params")
    if has_params:  # the aircraft is a constant of the scan, not carried (no per-step copies of its tables)
        cstate0 = cstate0.replace(params=None)
    key = jax.random.key(0)

    def step(carry, k):
        state, delta, cstate, cost = carry
        cs = cstate.replace(params=params) if has_params else cstate
        x = to_wind(state)
        u, cs_new, _ = controller.apply(cs, x, reference_rad, key)
        u = jnp.where(jnp.all(jnp.isfinite(u)), u, delta)
        state_new, delta_new, _ = plant_step(state, delta, u, params, cfg.dt_s)
        ok = is_finite(state_new)
        state_new = jax.tree.map(lambda a, b: jnp.where(ok, a, b), state_new, state)
        w = time_weight(k.astype(dtype) * cfg.dt_s, cfg)
        cost = cost + w * step_cost(x, reference_rad)
        cs_new = cs_new.replace(params=None) if has_params else cs_new
        return (state_new, delta_new, cs_new, cost), None

    @jax.checkpoint
    def chunk(carry, ks):
        carry, _ = jax.lax.scan(step, carry, ks)
        return carry, None

    ks = jnp.arange(cfg.n_steps, dtype=jnp.int32).reshape(-1, cfg.chunk_steps)
    carry0 = (body0, delta0_rad.astype(dtype), cstate0, jnp.zeros((), dtype))
    (_, _, _, cost), _ = jax.lax.scan(chunk, carry0, ks)
    return cost / cfg.n_steps
