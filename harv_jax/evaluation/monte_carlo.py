"""Monte Carlo evaluation: many closed-loop runs as one jitted, vmapped rollout per controller.

Common random numbers: every controller flies the same sampled aircraft and initial states
(``sample_mc_inputs``), so per-run differences between controllers are paired. Runs are processed
in chunks of a fixed size by one compiled function (memory stays bounded: full-rate data exist
only for one chunk; only the decimated alpha/beta/mu histories of every run are kept for the
percentile bands). With several local devices the runs of a chunk are sharded over them.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from harv_jax.aircraft.params import AircraftParams
from harv_jax.aircraft.randomize import (
    NUM_AIRCRAFT_UNIFORMS,
    SAMPLE_UNIFORMS,
    default_aircraft_randomization,
    sample_aircraft,
    uniform16,
)
from harv_jax.control.base import Controller
from harv_jax.control.scheduling import SIMPLEX_REASONS
from harv_jax.dynamics.disturbances import DEFAULT_GUST_TAU_S, DEFAULT_NOISE_STD_MAX, DisturbanceParams
from harv_jax.dynamics.state import TRACKED_INDEX, WIND_INDEX
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.disturbance_spec import DisturbanceSpec
from harv_jax.evaluation.metrics import RunMetrics
from harv_jax.guards import AUTO_CHUNK_RUNS_PER_CPU_DEVICE, auto_chunk
from harv_jax.task.criteria import tracking_errors
from harv_jax.task.scenarios import sample_table_states
from harv_jax.task.spec import DT_S, H0_FT

#: State components the paper's Monte Carlo samples (the others start at 0 / h0).
MC_SAMPLED_STATES = ("V", "alpha", "beta", "p", "q", "r")
#: Per-channel [3] controller diagnostics averaged over time per run (the hybrid's zeta and certificate).
PER_CHANNEL_INFO = (
    "zeta_channels", "correction_rad", "cert_free_defined", "cert_free_holds", "cert_sat_defined",
    "cert_sat_holds",
)  # fmt: skip
CHANNELS = ("alpha", "beta", "mu")
TERMINAL_WINDOW_S = 1.0
#: mu and gamma in the wind state (not sampled by default).
_MU_GAMMA = slice(WIND_INDEX["mu"], WIND_INDEX["gamma"] + 1)


class MCInputs(struct.PyTreeNode):
    """What every controller of one Monte Carlo shares (leading axis: run).

    Attributes:
        x0_wind: [N, 10] initial wind states.
        params: AircraftParams with [N]-batched leaves: the plant.
        keys: [N] PRNG keys for the controllers (stochastic policies).
        model_params: the aircraft the controllers are built on ([N]-batched; None: the plant's).
        disturbance: [N]-batched noise, delay and gust levels (None: no disturbance in the loop).
        disturbance_keys: [N] PRNG keys of the noise and gust draws (with ``disturbance``).
        max_delay_steps: static size of the command FIFO minus one.
    """

    x0_wind: jnp.ndarray
    params: AircraftParams
    keys: jax.Array
    model_params: AircraftParams | None = None
    disturbance: DisturbanceParams | None = None
    disturbance_keys: jax.Array | None = None
    max_delay_steps: int = struct.field(pytree_node=False, default=0)


#: fold_in tag of the disturbance keys (leaves the draws of the undisturbed Monte Carlo unchanged).
_DISTURBANCE_KEY_TAG = 0x6469_7374


def sample_mc_inputs(
    key: jax.Array,
    n_runs: int,
    nominal: AircraftParams,
    randomize: bool = False,
    sample_all_states: bool = False,
    h0_ft: float = H0_FT,
    disturbances: DisturbanceSpec | None = None,
) -> MCInputs:
    """Sample initial states (paper's reset bounds), aircraft and disturbances for ``n_runs`` runs.

    Args:
        key: PRNG key (split into aircraft, initial-state and controller keys; the disturbance keys are
            folded from it, so adding disturbances changes no other draw).
        n_runs: number of runs.
        nominal: nominal aircraft.
        randomize: draw mass, inertia and aero-table multipliers per run (``aircraft.randomize`` at its
            default ranges, the env's) and build the controllers on the nominal aircraft; the same as
            ``disturbances.model_error = 1`` (a spec's own level wins).
        sample_all_states: also sample mu and gamma (default: as the paper, only V, alpha, beta,
            p, q, r are sampled; mu = gamma = 0).
        h0_ft: initial altitude, ft.
        disturbances: noise, delay, gust, model error and actuator lag (``disturbance_spec``; None: none).
    """
    spec = disturbances or DisturbanceSpec()
    if randomize and spec.model_error == 0:
        spec = dataclasses.replace(spec, model_error=1.0)
    key_aircraft, key_init, key_ctrl = jax.random.split(key, 3)
    x0 = sample_table_states(key_init, n_runs, h0_ft=h0_ft)
    if not sample_all_states:
        x0 = x0.at[:, _MU_GAMMA].set(0.0)
    dtype = x0.dtype
    nominal_n = jax.tree.map(lambda a: jnp.broadcast_to(a, (n_runs,) + jnp.shape(a)), nominal)
    aircraft_keys = jax.random.split(key_aircraft, n_runs)
    if spec.model_error > 0:
        rand = _scaled_randomization(spec.model_error, dtype)
        params = jax.vmap(lambda k: sample_aircraft(k, nominal, rand))(aircraft_keys)
    else:
        params = nominal_n
    model_params = None
    if spec.actuator_lag_s > 0:
        params = params.replace(act_tau_s=jnp.full((n_runs,), spec.actuator_lag_s, dtype))
    if (spec.model_error > 0 or spec.actuator_lag_s > 0) and not spec.controller_knows_aircraft:
        model_params = nominal_n
    disturbance = disturbance_keys = None
    if spec.in_loop:
        # the gust's correlation time: the env's draw of the same per-run key (``aircraft.randomize``)
        u_tau = jax.vmap(lambda k: uniform16(k, SAMPLE_UNIFORMS, dtype)[NUM_AIRCRAFT_UNIFORMS + 2])(
            aircraft_keys
        )
        tau_lo, tau_hi = DEFAULT_GUST_TAU_S
        tau = (
            tau_lo + (tau_hi - tau_lo) * u_tau
            if spec.gust_tau_s is None
            else jnp.full((n_runs,), spec.gust_tau_s)
        )
        disturbance = DisturbanceParams(
            noise_std=jnp.broadcast_to(
                jnp.asarray(spec.noise_scale * DEFAULT_NOISE_STD_MAX, dtype), (n_runs, 8)
            ),
            delay_steps=jnp.full((n_runs,), spec.delay_steps, jnp.int32),
            gust_std_fps=jnp.full((n_runs,), spec.gust_fps, dtype),
            gust_tau_s=tau.astype(dtype),
        )
        disturbance_keys = jax.random.split(jax.random.fold_in(key, _DISTURBANCE_KEY_TAG), n_runs)
    return MCInputs(
        x0_wind=x0,
        params=params,
        keys=jax.random.split(key_ctrl, n_runs),
        model_params=model_params,
        disturbance=disturbance,
        disturbance_keys=disturbance_keys,
        max_delay_steps=spec.delay_steps,
    )


def with_full_structure(inputs: MCInputs, max_delay_steps: int) -> MCInputs:
    """``inputs`` with every optional part present (zero disturbance levels, the nominal model) and the
    command FIFO sized for ``max_delay_steps``: the same closed loop for every level of a sweep, so one
    compiled rollout serves them all (zero levels act as none: zero noise, zero gust, zero delay)."""
    n = int(inputs.x0_wind.shape[0])
    dtype = inputs.x0_wind.dtype
    if max_delay_steps < inputs.max_delay_steps:
        raise ValueError(f"max_delay_steps={max_delay_steps} < the inputs' {inputs.max_delay_steps}")
    model = inputs.params if inputs.model_params is None else inputs.model_params
    disturbance, dkeys = inputs.disturbance, inputs.disturbance_keys
    if disturbance is None:
        zero = jnp.zeros((n,), dtype)
        disturbance = DisturbanceParams(
            noise_std=jnp.zeros((n, 8), dtype), delay_steps=jnp.zeros((n,), jnp.int32), gust_std_fps=zero,
            gust_tau_s=jnp.ones((n,), dtype),
        )  # fmt: skip
        dkeys = jax.random.split(jax.random.key(0), n)
    return inputs.replace(
        model_params=model, disturbance=disturbance, disturbance_keys=dkeys, max_delay_steps=max_delay_steps
    )


def _scaled_randomization(scale: float, dtype):
    """The aircraft randomization at ``scale`` times its default ranges (scale 1: the defaults, exactly)."""
    rand = default_aircraft_randomization(enabled=True, dtype=dtype)
    if scale == 1.0:
        return rand
    fracs = ("mass_frac", "inertia_frac", "aero_damping_frac", "aero_control_frac", "aero_static_frac",
             "aero_basic_frac")  # fmt: skip
    return rand.replace(**{f: getattr(rand, f) * scale for f in fracs})


class MCRunOutput(struct.PyTreeNode):
    """Per-run results (leading axis: run).

    Attributes:
        metrics: RunMetrics.
        terminal_error_rad: [3] mean tracking error over the last ``TERMINAL_WINDOW_S`` of the run.
        history: [T_rec, 3] decimated alpha, beta, mu (rad) for the percentile bands.
        info_means: controller diagnostics averaged over time (scalars per run; [3] for
            ``PER_CHANNEL_INFO``).
    """

    metrics: RunMetrics
    terminal_error_rad: jnp.ndarray
    history: jnp.ndarray
    info_means: dict[str, jnp.ndarray]


def _one_run(
    controller: Controller,
    run: MCInputs,
    reference_rad: jnp.ndarray,
    n_steps: int,
    dt_s: float,
    record_every: int,
) -> MCRunOutput:
    """One run (``run``: the MCInputs of one run, unbatched)."""
    params, x0, key = run.params, run.x0_wind, run.keys
    res = closed_loop(
        controller,
        params,
        x0,
        reference_rad,
        key,
        n_steps,
        dt_s,
        disturbance=run.disturbance,
        disturbance_key=run.disturbance_keys,
        max_delay_steps=run.max_delay_steps,
        model_params=run.model_params,
    )
    m, x_all = score(res, reference_rad, params, dt_s)
    n_term = max(1, int(round(TERMINAL_WINDOW_S / dt_s)))
    term = jnp.mean(tracking_errors(x_all[-n_term:], reference_rad), axis=0)
    hist = x_all[:-1:record_every][:, jnp.array(TRACKED_INDEX)]
    info_means = {
        k: jnp.mean(v.astype(x_all.dtype), axis=0)
        for k, v in res.traj.info.items()
        if v.ndim == 1 or k in PER_CHANNEL_INFO  # per-step scalars (flags, weights), per-channel [3] flags
    }
    return MCRunOutput(metrics=m, terminal_error_rad=term, history=hist, info_means=info_means)


def make_mc_chunk_fn(
    controller: Controller, n_steps: int, dt_s: float, record_every: int
) -> Callable[[MCInputs, jnp.ndarray], MCRunOutput]:
    """A jitted function mapping a chunk of MCInputs (and the reference [3]) to MCRunOutput."""

    def chunk(inputs: MCInputs, reference_rad: jnp.ndarray) -> MCRunOutput:
        return jax.vmap(lambda run: _one_run(controller, run, reference_rad, n_steps, dt_s, record_every))(
            inputs
        )

    return jax.jit(chunk)


def _shard(tree: Any, n_dev: int) -> Any:
    if n_dev <= 1:
        return tree
    mesh = Mesh(np.array(jax.local_devices()[:n_dev]), ("runs",))
    sharding = NamedSharding(mesh, PartitionSpec("runs"))
    return jax.device_put(tree, sharding)


def run_mc(
    controller: Controller,
    inputs: MCInputs,
    reference_rad: jnp.ndarray,
    n_steps: int,
    dt_s: float = DT_S,
    record_every: int = 10,
    chunk_size: int | None = None,
    compiled_cache: dict | None = None,
) -> tuple[MCRunOutput, dict[str, float]]:
    """Fly ``controller`` on every run of ``inputs``.

    Args:
        controller: Controller(init, apply).
        inputs: MCInputs (N runs).
        reference_rad: [3] [alpha_d, beta_d, mu_d], rad.
        n_steps: plant steps per run (static).
        dt_s: plant step, s.
        record_every: decimation of the stored alpha/beta/mu histories.
        chunk_size: runs per compiled call (bounds memory); N is padded to a multiple of it. ``None``:
            ``guards.auto_chunk`` (512 runs per device on a CPU, all runs on a GPU, within 1/8 of memory).
            Results depend on it at float rounding (the compiled batch differs), not beyond.
        compiled_cache: a dict kept across calls: a call with the same controller object, settings and input
            structure reuses the compiled rollout (a sweep over traced levels compiles once).

    Returns:
        (MCRunOutput with numpy leaves of leading size N, {"compile": s, "run": s, "chunk_runs": runs per
        call}).
    """
    n = int(inputs.x0_wind.shape[0])
    n_dev = jax.local_device_count()
    if chunk_size is None:
        per_device = AUTO_CHUNK_RUNS_PER_CPU_DEVICE if jax.default_backend() == "cpu" else None
        chunk_size = auto_chunk(n, n_steps, n_dev, per_device)
    chunk_size = max(1, min(chunk_size, n))
    if n_dev > 1:
        chunk_size = max(n_dev, chunk_size - chunk_size % n_dev)
    n_chunks = -(-n // chunk_size)
    pad = n_chunks * chunk_size - n
    padded = jax.tree.map(
        lambda a: jnp.concatenate([a, jnp.repeat(a[:1], pad, axis=0)]) if pad else a, inputs
    )
    fn = make_mc_chunk_fn(controller, n_steps, dt_s, record_every)
    reference_rad = jnp.asarray(reference_rad, dtype=inputs.x0_wind.dtype)

    def take(i):
        return _shard(jax.tree.map(lambda a: a[i * chunk_size : (i + 1) * chunk_size], padded), n_dev)

    first = take(0)
    cache_key = (
        id(controller), n_steps, dt_s, record_every, chunk_size,
        jax.tree.structure(first), tuple(jnp.shape(a) for a in jax.tree.leaves(first)),
    )  # fmt: skip
    t0 = time.perf_counter()
    if compiled_cache is not None and cache_key in compiled_cache:
        compiled = compiled_cache[cache_key][1]
    else:
        compiled = fn.lower(first, reference_rad).compile()
        if compiled_cache is not None:  # the controller is kept alive with its compiled rollout (its id)
            compiled_cache[cache_key] = (controller, compiled)
    t_compile = time.perf_counter() - t0
    outs = []
    t0 = time.perf_counter()
    for i in range(n_chunks):
        outs.append(jax.device_get(compiled(take(i), reference_rad)))
    t_run = time.perf_counter() - t0
    out = jax.tree.map(lambda *xs: np.concatenate(xs, axis=0)[:n], *outs)
    return out, {"compile": t_compile, "run": t_run, "chunk_runs": chunk_size}


def gate_summary(info: dict[str, Any]) -> dict[str, Any]:
    """The hybrid's per-channel zeta, how often the policy acted unmodified, the corrections and the
    certificate of the command that acts (steps pooled over runs; saturated = the box clipped the command).
    Empty for controllers without these diagnostics."""
    if "zeta_channels" not in info:
        return {}

    def by_channel(a: np.ndarray) -> dict[str, float]:
        return {c: float(v) for c, v in zip(CHANNELS, np.asarray(a, np.float64), strict=True)}

    def pooled(holds: str, defined: str) -> dict[str, float | None]:
        h = np.sum(np.asarray(info[holds], np.float64), axis=0)
        d = np.sum(np.asarray(info[defined], np.float64), axis=0)
        return {c: (float(hc / dc) if dc > 0 else None) for c, hc, dc in zip(CHANNELS, h, d, strict=True)}

    n_def = np.asarray(info["cert_free_defined"], np.float64) + np.asarray(info["cert_sat_defined"])
    sat_share = np.sum(np.asarray(info["cert_sat_defined"], np.float64)) / max(float(np.sum(n_def)), 1e-300)
    return {
        "zeta_mean_by_channel": by_channel(np.mean(info["zeta_channels"], axis=0)),
        "policy_unmodified_fraction": float(np.mean(info["policy_unmodified"])),
        "correction_mean_rad": {
            s: v
            for s, v in zip(
                ("elevator", "aileron", "rudder"),
                by_channel(np.mean(info["correction_rad"], axis=0)).values(),
                strict=True,
            )
        },  # fmt: skip
        "certificate": {
            "holds_unsaturated": pooled("cert_free_holds", "cert_free_defined"),
            "holds_saturated": pooled("cert_sat_holds", "cert_sat_defined"),
            "saturated_step_fraction": float(sat_share),
            "note": "harv_jax.control.gate's condition (outside the band: s*s_dot <= -eta |s| |sw(s)|) on "
            "the controller model for the command that acts; steps with an exact solve and the channel in "
            "its sliding mode",
        },
    }


#: The ``simplex`` schedule's reasons to hand over to the SMC (without "none").
HANDOVER_REASONS = SIMPLEX_REASONS[1:]


def simplex_summary(info: dict[str, Any]) -> dict[str, Any]:
    """Fraction of runs in which the ``simplex`` schedule handed over to the SMC, in all and by reason.
    Empty for controllers without these diagnostics."""
    keys = [f"handover_{r}" for r in HANDOVER_REASONS]
    if not all(k in info for k in keys):
        return {}
    handed = {r: np.asarray(info[k]) > 0 for r, k in zip(HANDOVER_REASONS, keys, strict=True)}
    return {
        "handover_run_fraction": {
            "any": float(np.mean(np.any(np.stack(list(handed.values())), axis=0))),
            **{r: float(np.mean(h)) for r, h in handed.items()},
        }
    }
