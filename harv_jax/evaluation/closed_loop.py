"""Closed-loop rollouts of a ``Controller`` on the flight model (pure, ``lax.scan`` over time).

One step (dt_s, controller at the plant rate):

    x_k      = to_wind(state_k)                               (the controller sees wind-axis states)
    u_k      = controller.apply(ctrl_state, x_k, reference, key_k)
    state_k+1, delta_k+1 = plant_step(state_k, delta_k, u_k, params, dt_s)  (actuator, RK4: dynamics.plant)

With disturbances (``disturbance``: ``harv_jax.dynamics.disturbances``) every step is the training env's
own, ``dynamics.disturbed_step.disturbed_plant_step``: the controller sees the air data plus sensor noise,
the plant flies the command ``delay_steps`` old in the body-axis gust and the Dryden turbulence
(``dynamics.turbulence``: its draws from each step's disturbance key folded with a tag, so turning it on
changes no other draw; its frame is the initial heading's; its scales follow the altitude and airspeed at
the start of each step), and the next gust, noise and turbulence come from the step's key of
``disturbance_key``'s split. The recorded and scored states are the true ones relative to the air mass
(``air_relative``: the angles the aerodynamics see; the inertial ones differ from them by up to gust / V,
~2 deg for 10 ft/s at 300 ft/s). ``model_params`` builds the controller on another aircraft than the
plant's (model error: e.g. the nominal aircraft while the plant flies a randomized one).

Everything is vmappable over aircraft (``params``), initial states, references and keys; the number
of steps is static. A non-finite command is replaced by the current deflection; a non-finite state
is never propagated: the last finite state is held and ``nonfinite`` is set (the metrics turn it
into ``Outcome.NONFINITE``). Nothing raises inside jit.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.control.base import Controller
from harv_jax.dynamics import disturbances as dist
from harv_jax.dynamics import turbulence as turb
from harv_jax.dynamics.disturbed_step import (
    air_data,
    disturbance_init,
    disturbed_plant_step,
    initial_heading,
    measured,
)
from harv_jax.dynamics.plant import plant_step
from harv_jax.dynamics.state import BodyState, from_wind, is_finite, to_wind
from harv_jax.evaluation.metrics import RunMetrics, compute_metrics
from harv_jax.task.criteria import Envelope, RecoveryCriterion
from harv_jax.task.spec import DT_S
from harv_jax.task.turbulent_criterion import TurbulentCriterion

#: ``Trajectory.info`` key of the air's body-axis velocity [3], ft/s (gust and turbulence), with disturbances.
WIND_INFO_KEY = "wind_body_fps"


class Trajectory(struct.PyTreeNode):
    """Recorded closed-loop samples (leading axis: time; extra leading axes under vmap).

    Attributes:
        t_s: [T] time of each sample from engagement, s.
        x_wind: [T, 10] wind state at t_s (before the step).
        delta_rad: [T, 3] deflections applied over the step starting at t_s.
        u_cmd_rad: [T, 3] controller command at t_s.
        info: controller diagnostics, each [T, ...].
    """

    t_s: jnp.ndarray
    x_wind: jnp.ndarray
    delta_rad: jnp.ndarray
    u_cmd_rad: jnp.ndarray
    info: dict[str, jnp.ndarray]


class ClosedLoopResult(struct.PyTreeNode):
    """Result of ``closed_loop``.

    Attributes:
        traj: Trajectory of n_steps samples (every ``record_every``-th step if decimated).
        final_state: BodyState after n_steps.
        x_final_wind: [10] wind state after n_steps (t = n_steps dt_s).
        final_delta_rad: [3] deflections after n_steps.
        final_ctrl_state: controller state after n_steps.
        nonfinite: bool, a non-finite state or command occurred (the state was then held).
    """

    traj: Trajectory
    final_state: BodyState
    x_final_wind: jnp.ndarray
    final_delta_rad: jnp.ndarray
    final_ctrl_state: Any
    nonfinite: jnp.ndarray


def _as_body(x0: BodyState | jnp.ndarray) -> BodyState:
    return x0 if isinstance(x0, BodyState) else from_wind(x0)


def closed_loop(
    controller: Controller,
    params: AircraftParams,
    x0: BodyState | jnp.ndarray,
    reference_rad: jnp.ndarray,
    key: jax.Array,
    n_steps: int,
    dt_s: float = DT_S,
    delta0_rad: jnp.ndarray | None = None,
    record_every: int = 1,
    ctrl_state: Any = None,
    disturbance: dist.DisturbanceParams | None = None,
    disturbance_key: jax.Array | None = None,
    max_delay_steps: int = 0,
    model_params: AircraftParams | None = None,
) -> ClosedLoopResult:
    """Fly ``controller`` for ``n_steps`` plant steps.

    Args:
        controller: Controller(init, apply).
        params: aircraft (plant and, through ``init``, the controller's model).
        x0: initial BodyState or wind-axis state [10].
        reference_rad: [3] [alpha_d, beta_d, mu_d], rad, held constant.
        key: PRNG key, split once per step for ``apply``.
        n_steps: number of plant steps (static).
        dt_s: plant step, s (must equal the controller's own step, e.g. ``SMCConfig.dt_s``).
        delta0_rad: [3] initial deflections (default 0; e.g. the pro-spin controls).
        record_every: keep every k-th sample (static; n_steps must be a multiple of it).
        ctrl_state: initial controller state (default ``controller.init(model_params)``, with its
            ``u_prev_rad`` set to ``delta0_rad`` if it has one).
        disturbance: sensor noise, command delay and gust levels (None: none, the undisturbed loop).
        disturbance_key: PRNG key of the disturbance draws (required with ``disturbance``; the same key
            gives every controller the same noise sequence and gust).
        max_delay_steps: static size of the command FIFO minus one; ``disturbance.delay_steps`` is
            clipped to it.
        model_params: the aircraft the controller is built on (default ``params``, the plant's).

    Returns:
        ClosedLoopResult.
    """
    if n_steps % record_every:
        raise ValueError(f"n_steps={n_steps} is not a multiple of record_every={record_every}")
    body0 = _as_body(x0)
    dtype = body0.uvw_fps.dtype
    delta0 = jnp.zeros((3,), dtype=dtype) if delta0_rad is None else jnp.asarray(delta0_rad, dtype=dtype)
    if disturbance is not None and disturbance_key is None:
        raise ValueError("closed_loop: a disturbance needs a disturbance_key")
    if max_delay_steps < 0:
        raise ValueError(f"closed_loop: max_delay_steps={max_delay_steps}; allowed: >= 0")
    model = params if model_params is None else model_params
    cstate0 = controller.init(model) if ctrl_state is None else ctrl_state
    if ctrl_state is None and hasattr(cstate0, "u_prev_rad"):
        # the controller's memory of its last command starts at the actual deflections (the hybrid's
        # rate box is relative to it; the SMC holds it if a command is non-finite)
        cstate0 = cstate0.replace(u_prev_rad=delta0.astype(cstate0.u_prev_rad.dtype))
    reference_rad = jnp.asarray(reference_rad, dtype=dtype)

    def step(carry, key_k):
        state, delta, cstate, bad = carry
        x = to_wind(state)
        u, cstate_new, info = controller.apply(cstate, x, reference_rad, key_k)
        u_ok = jnp.all(jnp.isfinite(u))
        u = jnp.where(u_ok, u, delta)
        state_new, delta_new, _ = plant_step(state, delta, u, params, dt_s)
        s_ok = is_finite(state_new)
        state_new = jax.tree.map(lambda a, b: jnp.where(s_ok, a, b), state_new, state)
        rec = (x, delta_new, u, info)
        return (state_new, delta_new, cstate_new, bad | ~u_ok | ~s_ok), rec

    def disturbed_step(carry, keys_k):
        (state, delta, cstate, bad), dstate = carry
        key_k, dkey_k = keys_k
        air = air_data(state, dstate, levels)
        u, cstate_new, info = controller.apply(
            cstate, measured(air.x_wind, dstate, levels), reference_rad, key_k
        )
        u_ok = jnp.all(jnp.isfinite(u))
        u = jnp.where(u_ok, u, delta)
        ps, dstate = disturbed_plant_step(state, delta, dstate, u, air, params, levels, dt_s, dkey_k)
        s_ok = is_finite(ps.body)
        state_new = jax.tree.map(lambda a, b: jnp.where(s_ok, a, b), ps.body, state)
        info = {**info, WIND_INFO_KEY: air.wind_fps}  # the air mass the plant flew in (fly writes it out)
        rec = (air.x_wind, ps.delta_rad, u, info)
        return ((state_new, ps.delta_rad, cstate_new, bad | ~u_ok | ~s_ok), dstate), rec

    keys = jax.random.split(key, n_steps)
    carry0 = (body0, delta0, cstate0, jnp.asarray(False))
    if disturbance is None:
        body_fn, xs = step, keys
    else:
        delay_steps = jnp.clip(jnp.asarray(disturbance.delay_steps, jnp.int32), 0, max_delay_steps)
        levels = disturbance.replace(delay_steps=delay_steps)
        dkeys = jax.random.split(disturbance_key, n_steps + 1)
        dstate0 = disturbance_init(
            dist.step_normals(dkeys[0], dtype),
            levels,
            delta0,
            initial_heading(body0),
            max_delay_steps,
            dkeys[0],
        )
        carry0 = (carry0, dstate0)
        body_fn, xs = disturbed_step, (keys, dkeys[1:])

    def chunk(carry, xs_chunk):
        carry, recs = jax.lax.scan(body_fn, carry, xs_chunk)
        return carry, jax.tree.map(lambda r: r[0], recs)

    if record_every == 1:
        carry, recs = jax.lax.scan(body_fn, carry0, xs)
    else:
        carry, recs = jax.lax.scan(
            chunk,
            carry0,
            jax.tree.map(lambda a: a.reshape((n_steps // record_every, record_every) + a.shape[1:]), xs),
        )
    x_final = None
    if disturbance is not None:
        carry, dstate_final = carry
        x_final = air_data(carry[0], dstate_final, levels).x_wind
    state, delta, cstate, bad = carry
    x_rec, delta_rec, u_rec, info_rec = recs
    n_rec = n_steps // record_every
    traj = Trajectory(
        t_s=jnp.arange(n_rec, dtype=dtype) * (record_every * dt_s),
        x_wind=x_rec,
        delta_rad=delta_rec,
        u_cmd_rad=u_rec,
        info=info_rec,
    )
    return ClosedLoopResult(
        traj=traj,
        final_state=state,
        x_final_wind=to_wind(state) if x_final is None else x_final,
        final_delta_rad=delta,
        final_ctrl_state=cstate,
        nonfinite=bad,
    )


def evaluate(
    controller: Controller,
    params: AircraftParams,
    x0: BodyState | jnp.ndarray,
    reference_rad: jnp.ndarray,
    key: jax.Array,
    n_steps: int,
    dt_s: float = DT_S,
    delta0_rad: jnp.ndarray | None = None,
    record_every: int = 1,
    criterion: RecoveryCriterion | None = None,
    envelope: Envelope | None = None,
    disturbance: dist.DisturbanceParams | None = None,
    disturbance_key: jax.Array | None = None,
    max_delay_steps: int = 0,
    model_params: AircraftParams | None = None,
) -> tuple[RunMetrics, Trajectory]:
    """Closed-loop run scored by ``compute_metrics`` (full-rate data), trajectory decimated.

    The metrics see the n_steps + 1 states (final state appended) and the n_steps deflections.
    Jit with ``n_steps``/``record_every``/``max_delay_steps`` static and vmap over
    aircraft/states/references/keys. The disturbance arguments are ``closed_loop``'s.

    Returns:
        (RunMetrics, Trajectory with every ``record_every``-th sample).
    """
    res = closed_loop(
        controller,
        params,
        x0,
        reference_rad,
        key,
        n_steps,
        dt_s,
        delta0_rad,
        1,
        disturbance=disturbance,
        disturbance_key=disturbance_key,
        max_delay_steps=max_delay_steps,
        model_params=model_params,
    )
    tparams = None if disturbance is None else disturbance.turbulence
    m, _ = score(res, reference_rad, params, dt_s, criterion, envelope, tparams)
    traj = jax.tree.map(lambda a: a[::record_every], res.traj)
    return m, traj


def score(
    res: ClosedLoopResult,
    reference_rad: jnp.ndarray,
    params: AircraftParams,
    dt_s: float = DT_S,
    criterion: RecoveryCriterion | None = None,
    envelope: Envelope | None = None,
    turbulence: turb.TurbulenceParams | None = None,
) -> tuple[RunMetrics, jnp.ndarray]:
    """Metrics of a full-rate ``closed_loop`` result; with the run's ``turbulence`` they follow the
    criterion in turbulence (``harv_jax.task.turbulent_criterion``).

    Returns:
        (RunMetrics, x_all [n_steps + 1, 10]: the recorded states with the final state appended).
    """
    x_all = jnp.concatenate([res.traj.x_wind, res.x_final_wind[None]], axis=0)
    m = compute_metrics(
        x_all,
        res.traj.delta_rad,
        jnp.asarray(reference_rad, x_all.dtype),
        params,
        dt_s,
        res.nonfinite,
        criterion,
        envelope,
        None if turbulence is None else TurbulentCriterion(turbulence),
    )
    return m, x_all
