"""Monte Carlo evaluation: many closed-loop runs as one jitted, vmapped rollout per controller.

Common random numbers: every controller flies the same sampled aircraft and initial states
(``mc_inputs.sample_mc_inputs``), so per-run differences between controllers are paired. Runs are processed
in chunks of a fixed size by one compiled function (memory stays bounded: full-rate data exist
only for one chunk; only the decimated alpha/beta/mu histories of every run are kept for the
percentile bands). With several local devices the runs of a chunk are sharded over them.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from harv_jax.control.base import Controller
from harv_jax.control.hybrid.zeta import SIMPLEX_REASONS
from harv_jax.dynamics.state import TRACKED_INDEX
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.metrics import RunMetrics
from harv_jax.evaluation.montecarlo.inputs import MC_SAMPLED_STATES as MC_SAMPLED_STATES
from harv_jax.evaluation.montecarlo.inputs import MCInputs
from harv_jax.evaluation.montecarlo.inputs import sample_mc_inputs as sample_mc_inputs
from harv_jax.evaluation.montecarlo.inputs import with_full_structure as with_full_structure
from harv_jax.guards import AUTO_CHUNK_RUNS_PER_CPU_DEVICE, auto_chunk
from harv_jax.task.criteria import tracking_errors
from harv_jax.task.spec import DT_S

#: Per-channel [3] controller diagnostics averaged over time per run (the hybrid's zeta and certificate).
PER_CHANNEL_INFO = (
    "zeta_channels",
    "correction_rad",
    "cert_free_defined",
    "cert_free_holds",
    "cert_sat_defined",
    "cert_sat_holds",
)
CHANNELS = ("alpha", "beta", "mu")
TERMINAL_WINDOW_S = 1.0


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
    tparams = None if run.disturbance is None else run.disturbance.turbulence
    m, x_all = score(res, reference_rad, params, dt_s, turbulence=tparams)
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


def shard_runs(tree: Any, n_dev: int) -> Any:
    """``tree`` with its leading (run) axis sharded over the first ``n_dev`` local devices (1: as is)."""
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
        return shard_runs(jax.tree.map(lambda a: a[i * chunk_size : (i + 1) * chunk_size], padded), n_dev)

    first = take(0)
    cache_key = (
        id(controller),
        n_steps,
        dt_s,
        record_every,
        chunk_size,
        jax.tree.structure(first),
        tuple(jnp.shape(a) for a in jax.tree.leaves(first)),
    )
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
        },
        "certificate": {
            "holds_unsaturated": pooled("cert_free_holds", "cert_free_defined"),
            "holds_saturated": pooled("cert_sat_holds", "cert_sat_defined"),
            "saturated_step_fraction": float(sat_share),
            "note": "harv_jax.control.hybrid.gate's condition (outside the band: s*s_dot <= -eta |s| "
            "|sw(s)|) on the controller model for the command that acts; steps with an exact solve and the "
            "channel in its sliding mode",
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
