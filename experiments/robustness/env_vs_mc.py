"""The training env's episode end against the Monte Carlo's recovery criterion, run by run.

    python experiments/robustness/env_vs_mc.py --runs 1000 --seed 2027

Draws the initial states of ``harv-jax mc --runs N --seed S`` (nominal aircraft, no disturbance:
``evaluation.montecarlo.inputs.sample_mc_inputs``) and flies the SMC from each of them twice, for the Monte
Carlo's 60 s:

(a) through the env: ``make_env(EnvConfig(domain_randomization=False, episode_steps=6000))``,
    ``reset_to`` at the run's x0 and the Monte Carlo's target [alpha_d, 0, 0]; each step the controller
    sees the env state's ``wind`` and its command becomes the action through ``task.spaces.command_to_action``
    (clipped to [-1, 1]). The controller starts as the Monte Carlo starts it (``controller.init`` of the
    aircraft, ``u_prev_rad`` at the initial deflections, 0) with the Monte Carlo's controller keys. The
    episode is not reset at a termination (``step_no_reset``): the first termination's step and flags are
    recorded and the aircraft flies on, so the whole 60 s can be compared too.
(b) through the Monte Carlo's ``evaluation.closed_loop.closed_loop``, scored by its ``score``.

Per run: whether and at which step the env terminated and by which flags, the Monte Carlo's outcome,
``left_envelope`` and first step outside its envelope (``task.criteria.within_envelope``), and how far
the two trajectories are apart up to the env's termination (and over the whole run): the largest
difference of a wind-state component divided by that component's scale (``SCALE``; mu and chi wrapped).
Writes ``results/env_vs_mc/seed<S>_n<N>.json`` and prints the cross-tabulation.

    python experiments/robustness/env_vs_mc.py --runs 1000 --seed 4099 --disturbances default

flies the same comparison in the Monte Carlo's disturbed world (``make_compare_disturbed``: the env with
turbulence set to each run's aircraft, levels, disturbance state and keys) and writes
``results/env_vs_mc/<disturbances>_seed<S>_n<N>.json``: the env's terminations, the trajectories' agreement up
to them, and the recovered fractions of both flights scored by the Monte Carlo's criterion.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft.registry import resolve_aircraft
from harv_jax.control.registry import build_controller
from harv_jax.dynamics.disturbances import step_normals
from harv_jax.dynamics.disturbed_step import air_data, disturbance_init, initial_heading, measured
from harv_jax.dynamics.state import WIND_INDEX, from_wind, to_wind
from harv_jax.env.config import EnvConfig
from harv_jax.env.randomize import EpisodeParams
from harv_jax.env.recovery import make_env
from harv_jax.env.termination import TerminationFlags, termination_flags
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.metrics import compute_metrics
from harv_jax.evaluation.montecarlo.disturbances import parse_disturbances
from harv_jax.evaluation.montecarlo.inputs import sample_mc_inputs, with_full_structure
from harv_jax.optimal.outputs import cpu_model
from harv_jax.task.criteria import OUTCOME_NAMES, within_envelope
from harv_jax.task.spaces import command_to_action
from harv_jax.task.spec import (
    ALPHA_MAX_RAD,
    ALPHA_MIN_RAD,
    ALPHA_TARGET_RAD,
    DT_S,
    H0_FT,
    RATE_MAX_RADPS,
    V_MAX_FPS,
)
from harv_jax.task.turbulent_criterion import TurbulentCriterion

RESULTS = Path(__file__).parent / "results" / "env_vs_mc"
FLAGS = TerminationFlags._fields
#: Scale of each wind-state component [V, alpha, beta, p, q, r, mu, gamma, chi, h] for the trajectory
#: difference: the envelope's half-width for V and the rates, one radian for the angles, the initial
#: altitude for h.
SCALE = np.array(
    [V_MAX_FPS / 2, 1.0, 1.0, RATE_MAX_RADPS, RATE_MAX_RADPS, RATE_MAX_RADPS, 1.0, 1.0, 1.0, H0_FT]
)
_WRAPPED = (WIND_INDEX["mu"], WIND_INDEX["chi"])


def draw_runs(seed: int, n_runs: int, target_alpha_rad: float):
    """The Monte Carlo's runs of ``harv-jax mc --runs n_runs --seed seed``: (x0 [N, 10], controller keys [N],
    nominal aircraft, reference [3])."""
    _, nominal = resolve_aircraft(None)
    inputs = sample_mc_inputs(jax.random.key(seed), n_runs, nominal, h0_ft=H0_FT)
    reference = jnp.array([target_alpha_rad, 0.0, 0.0], dtype=inputs.x0_wind.dtype)
    return inputs.x0_wind, inputs.keys, nominal, reference


def wind_difference(x_a: jnp.ndarray, x_b: jnp.ndarray) -> jnp.ndarray:
    """|x_a - x_b| / SCALE per sample and component [..., 10] (mu and chi wrapped to (-pi, pi])."""
    d = x_a - x_b
    for i in _WRAPPED:
        d = d.at[..., i].set(jnp.remainder(d[..., i] + math.pi, 2 * math.pi) - math.pi)
    return jnp.abs(d) / jnp.asarray(SCALE, d.dtype)


def make_compare(controller, env, n_steps: int):
    """(params, env_params, x0, key, reference) -> per-run record of both flights (jit and vmap it)."""

    def fly_env(params, env_params, x0, key, reference):
        _, state0 = env.reset_to(jax.random.key(0), x0, reference, env_params)
        cstate0 = controller.init(params)
        cstate0 = cstate0.replace(u_prev_rad=state0.delta_rad.astype(cstate0.u_prev_rad.dtype))
        ac = env_params.aircraft
        no_flags = TerminationFlags(*(jnp.asarray(False) for _ in FLAGS))

        def step(carry, key_k):
            state, cstate, k_term, flags_term = carry
            x = state.wind
            u, cstate, _ = controller.apply(cstate, x, reference, key_k)
            action = jnp.clip(command_to_action(u, ac.u_min_rad, ac.u_max_rad), -1.0, 1.0)
            _, state, _, terminated, _, info = env.step_no_reset(key_k, state, action, env_params)
            first = terminated & (k_term < 0)
            k_term = jnp.where(first, state.step, k_term)
            flags = TerminationFlags(**info["termination"])
            flags_term = jax.tree.map(lambda new, old: jnp.where(first, new, old), flags, flags_term)
            return (state, cstate, k_term, flags_term), (x, jnp.all(jnp.isfinite(u)))

        keys = jax.random.split(key, n_steps)
        carry0 = (state0, cstate0, jnp.asarray(-1, jnp.int32), no_flags)
        (state, _, k_term, flags_term), (xs, u_finite) = jax.lax.scan(step, carry0, keys)
        x_all = jnp.concatenate([xs, state.wind[None]], axis=0)
        return x_all, k_term, flags_term, jnp.all(u_finite)

    def compare(params, env_params, x0, key, reference):
        x_env, k_term, flags_term, env_u_finite = fly_env(params, env_params, x0, key, reference)
        res = closed_loop(controller, params, x0, reference, key, n_steps, DT_S)
        m, x_mc = score(res, reference, params, DT_S)
        outside = ~within_envelope(x_mc, env_params.envelope)
        n = x_mc.shape[0]
        k_out = jnp.min(jnp.where(outside, jnp.arange(n), n))
        k_out = jnp.where(k_out < n, k_out, -1)
        diff = jnp.max(wind_difference(x_env, x_mc), axis=-1)  # [T + 1]
        upto = jnp.where(k_term >= 0, k_term, n - 1)
        diff_upto = jnp.max(jnp.where(jnp.arange(n) <= upto, diff, 0.0))
        steps = jnp.arange(n)

        def first_above(th):
            k = jnp.min(jnp.where(diff > th, steps, n))
            return jnp.where(k < n, k, -1)

        alpha_mc = x_mc[:, WIND_INDEX["alpha"]]
        # the env's envelope flags on the Monte Carlo's states: does the MC trajectory trip the same rule?
        env_rule_on_mc = jax.vmap(lambda x: _env_flags_any(x, env_params))(x_mc)
        k_env_rule_mc = jnp.min(jnp.where(env_rule_on_mc, jnp.arange(n), n))
        return {
            "env_terminated": k_term >= 0,
            "env_term_step": k_term,
            "env_term_flags": flags_term._asdict(),
            "env_commands_finite": env_u_finite,
            "mc_outcome": m.outcome,
            "mc_recovered": m.recovered,
            "mc_left_envelope": m.left_envelope,
            "mc_t_left_envelope_s": m.t_left_envelope_s,
            "mc_first_outside_step": k_out,
            "mc_first_env_rule_step": jnp.where(k_env_rule_mc < n, k_env_rule_mc, -1),
            "mc_nonfinite": m.nonfinite,
            "rel_diff_upto_term": diff_upto,
            "rel_diff_full": jnp.max(diff),
            "rel_diff_x0": diff[0],
            "first_step_rel_diff_above_1e-6": first_above(1e-6),
            "first_step_rel_diff_above_1e-4": first_above(1e-4),
            "env_term_alpha_rad": jnp.where(
                k_term >= 0, x_env[jnp.maximum(k_term, 0), WIND_INDEX["alpha"]], jnp.nan
            ),
            "mc_alpha_min_rad": jnp.min(alpha_mc),
            "mc_alpha_max_rad": jnp.max(alpha_mc),
        }

    return compare


def make_compare_disturbed(controller, env, n_steps: int, max_delay: int):
    """As ``make_compare``, in a disturbed world: (plant, model, levels, dkey, env_params, x0, key,
    reference) -> per-run record. The env (turbulence on) is set to the Monte Carlo run's conditions: its
    episode is the run's plant aircraft and disturbance levels, its disturbance state the run's initial one
    (``disturbance_init`` on the run's first disturbance key) and each step's key the run's disturbance key
    of that step; the controller sees the env's measurement (``measured``: air data plus noise) and is
    built on the run's model aircraft. Both flights are scored by the Monte Carlo's ``score``: the env's
    whole flight (it flies on after a termination) and the Monte Carlo's."""
    no_flags = TerminationFlags(*(jnp.asarray(False) for _ in FLAGS))

    def compare(plant, model, levels, dkey, env_params, x0, key, reference):
        _, state0 = env.reset_to(jax.random.key(0), x0, reference, env_params)
        body0 = from_wind(x0)
        dkeys = jax.random.split(dkey, n_steps + 1)
        delta0 = jnp.zeros((3,), x0.dtype)
        dist0 = disturbance_init(
            step_normals(dkeys[0], x0.dtype), levels, delta0, initial_heading(body0), max_delay, dkeys[0]
        )
        episode = EpisodeParams(
            plant,
            levels.delay_steps,
            levels.gust_std_fps,
            levels.gust_tau_s,
            levels.noise_std,
            levels.turbulence,
        )
        x_air0 = air_data(body0, dist0, levels).x_wind
        state0 = state0.replace(aircraft=body0, wind=x_air0, disturbance=dist0, episode=episode)
        cstate0 = controller.init(model).replace(u_prev_rad=delta0)

        def step(carry, keys_k):
            state, cstate, k_term, flags_term = carry
            key_k, dkey_k = keys_k
            x = state.wind
            u, cstate, _ = controller.apply(
                cstate, measured(x, state.disturbance, state.episode.levels), reference, key_k
            )
            ac = state.episode.aircraft
            action = jnp.clip(command_to_action(u, ac.u_min_rad, ac.u_max_rad), -1.0, 1.0)
            _, state, _, terminated, _, info = env.step_no_reset(dkey_k, state, action, env_params)
            first = terminated & (k_term < 0)
            k_term = jnp.where(first, state.step, k_term)
            flags = TerminationFlags(**info["termination"])
            flags_term = jax.tree.map(lambda new, old: jnp.where(first, new, old), flags, flags_term)
            return (state, cstate, k_term, flags_term), (x, state.delta_rad)

        keys = jax.random.split(key, n_steps)
        carry0 = (state0, cstate0, jnp.asarray(-1, jnp.int32), no_flags)
        (state, _, k_term, flags_term), (xs, deltas) = jax.lax.scan(step, carry0, (keys, dkeys[1:]))
        x_env = jnp.concatenate([xs, state.wind[None]], axis=0)
        res = closed_loop(
            controller,
            plant,
            x0,
            reference,
            key,
            n_steps,
            DT_S,
            disturbance=levels,
            disturbance_key=dkey,
            max_delay_steps=max_delay,
            model_params=model,
        )
        m, x_mc = score(res, reference, plant, DT_S, turbulence=levels.turbulence)
        tc = None if levels.turbulence is None else TurbulentCriterion(levels.turbulence)
        m_env = compute_metrics(x_env, deltas, reference, plant, DT_S, False, None, None, tc)
        n = x_mc.shape[0]
        outside = ~within_envelope(x_mc, env_params.envelope)
        k_out = jnp.min(jnp.where(outside, jnp.arange(n), n))
        diff = jnp.max(wind_difference(x_env, x_mc), axis=-1)
        upto = jnp.where(k_term >= 0, k_term, n - 1)
        return {
            "env_terminated": k_term >= 0,
            "env_term_step": k_term,
            "env_term_flags": flags_term._asdict(),
            "mc_outcome": m.outcome,
            "mc_recovered": m.recovered,
            "env_flight_recovered": m_env.recovered,
            "mc_left_envelope": m.left_envelope,
            "mc_first_outside_step": jnp.where(k_out < n, k_out, -1),
            "rel_diff_upto_term": jnp.max(jnp.where(jnp.arange(n) <= upto, diff, 0.0)),
            "rel_diff_full": jnp.max(diff),
        }

    return compare


def run_disturbed(seed: int, n_runs: int, target_alpha_rad: float, duration_s: float, chunk: int, names: str):
    """``run`` in the disturbed world of ``--disturbances names`` (the Monte Carlo's draws of seed)."""
    n_steps = int(round(duration_s / DT_S))
    _, nominal = resolve_aircraft(None)
    spec = parse_disturbances(names)
    inputs = with_full_structure(
        sample_mc_inputs(jax.random.key(seed), n_runs, nominal, h0_ft=H0_FT, disturbances=spec),
        spec.delay_steps,
    )
    reference = jnp.array([target_alpha_rad, 0.0, 0.0], dtype=inputs.x0_wind.dtype)
    max_delay = inputs.max_delay_steps
    env = make_env(
        EnvConfig(
            domain_randomization=True,
            turbulence=inputs.disturbance.turbulence is not None,
            episode_steps=n_steps,
            max_delay_steps=max_delay,
        )
    )
    env_params = env.default_params()
    compare = make_compare_disturbed(build_controller("smc"), env, n_steps, max_delay)
    fn = jax.jit(jax.vmap(compare, in_axes=(0, 0, 0, 0, None, 0, 0, None)))
    per = (
        inputs.params,
        inputs.model_params,
        inputs.disturbance,
        inputs.disturbance_keys,
        inputs.x0_wind,
        inputs.keys,
    )
    chunk = max(1, min(chunk, n_runs))
    if n_runs % chunk:
        raise SystemExit(f"--runs {n_runs} must be a multiple of --chunk {chunk}")
    outs, t0 = [], time.perf_counter()
    for i in range(0, n_runs, chunk):
        p, mdl, lv, dk, x0, k = jax.tree.map(lambda a, i=i: a[i : i + chunk], per)
        outs.append(jax.device_get(fn(p, mdl, lv, dk, env_params, x0, k, reference)))
    per_run = jax.tree.map(lambda *xs: np.concatenate(xs), *outs)
    return {
        "n_steps": n_steps,
        "disturbances": spec.as_dict(),
        "reference_rad": np.asarray(reference).tolist(),
        "wall_s": {"total": round(time.perf_counter() - t0, 2)},
        "per_run": per_run,
    }


def summarize_disturbed(per_run: dict) -> dict:
    """Terminations, trajectory agreement and the recovered fractions of the two flights."""
    term = np.asarray(per_run["env_terminated"])
    rec_mc = np.asarray(per_run["mc_recovered"])
    rec_env = np.asarray(per_run["env_flight_recovered"])
    d_upto = np.asarray(per_run["rel_diff_upto_term"])
    kept = ~term
    return {
        "runs": int(term.size),
        "env_terminated": int(term.sum()),
        "env_terminated_mc_recovered": int(np.sum(term & rec_mc)),
        "env_termination_flags": {
            f: int(np.sum(np.asarray(per_run["env_term_flags"][f]) & term)) for f in FLAGS
        },
        "mc_left_envelope": int(np.sum(per_run["mc_left_envelope"])),
        "mc_recovered_share": float(rec_mc.mean()),
        "env_flight_recovered_share": float(rec_env.mean()),
        "not_terminated": {
            "runs": int(kept.sum()),
            "mc_recovered_share": float(rec_mc[kept].mean()) if kept.any() else None,
            "env_flight_recovered_share": float(rec_env[kept].mean()) if kept.any() else None,
            "verdicts_differ": int(np.sum(rec_mc[kept] != rec_env[kept])),
        },
        "rel_diff_upto_term": {
            "max": float(d_upto.max()),
            "p99": float(np.percentile(d_upto, 99)),
            "median": float(np.median(d_upto)),
        },
    }


def _env_flags_any(x_wind: jnp.ndarray, env_params) -> jnp.ndarray:
    """The env's termination rule on a wind state [10] (finite: its components are)."""
    return termination_flags(x_wind, jnp.all(jnp.isfinite(x_wind)), env_params.envelope).any


def run(seed: int, n_runs: int, target_alpha_rad: float, duration_s: float, chunk: int) -> dict:
    n_steps = int(round(duration_s / DT_S))
    x0, keys, nominal, reference = draw_runs(seed, n_runs, target_alpha_rad)
    env = make_env(EnvConfig(domain_randomization=False, episode_steps=n_steps))
    env_params = env.default_params()
    same_aircraft = all(
        bool(jnp.all(a == b))
        for a, b in zip(jax.tree.leaves(env_params.aircraft), jax.tree.leaves(nominal), strict=True)
    )
    controller = build_controller("smc")
    compare = make_compare(controller, env, n_steps)
    fn = jax.jit(jax.vmap(compare, in_axes=(None, None, 0, 0, None)))
    chunk = max(1, min(chunk, n_runs))
    pad = (-n_runs) % chunk
    x0_p = jnp.concatenate([x0, jnp.repeat(x0[:1], pad, axis=0)]) if pad else x0
    keys_p = jnp.concatenate([keys, jnp.repeat(keys[:1], pad, axis=0)]) if pad else keys
    t0 = time.perf_counter()
    compiled = fn.lower(nominal, env_params, x0_p[:chunk], keys_p[:chunk], reference).compile()
    t_compile = time.perf_counter() - t0
    outs = []
    t0 = time.perf_counter()
    for i in range(0, n_runs + pad, chunk):
        outs.append(
            jax.device_get(
                compiled(nominal, env_params, x0_p[i : i + chunk], keys_p[i : i + chunk], reference)
            )
        )
    t_run = time.perf_counter() - t0
    per_run = jax.tree.map(lambda *xs: np.concatenate(xs)[:n_runs], *outs)
    return {
        "n_steps": n_steps,
        "reference_rad": np.asarray(reference).tolist(),
        "same_aircraft": same_aircraft,
        "x0_roundtrip_rel_diff_max": float(
            jnp.max(wind_difference(jax.vmap(lambda x: to_wind(from_wind(x)))(x0), x0))
        ),
        "wall_s": {"compile": round(t_compile, 2), "run": round(t_run, 2)},
        "per_run": per_run,
    }


def _share(mask: np.ndarray) -> float:
    return float(np.mean(mask)) if mask.size else float("nan")


def _earliest(first_steps) -> float | None:
    """Earliest time over the runs, s, of a per-run first step (-1: never); None if no run has one."""
    k = np.asarray(first_steps)
    return float(k[k >= 0].min() * DT_S) if np.any(k >= 0) else None


def summarize(per_run: dict) -> dict:
    """Shares, cross-tabulation and agreement from the per-run arrays."""
    term = np.asarray(per_run["env_terminated"])
    left = np.asarray(per_run["mc_left_envelope"])
    rec = np.asarray(per_run["mc_recovered"])
    k_term = np.asarray(per_run["env_term_step"])
    k_out = np.asarray(per_run["mc_first_outside_step"])
    k_rule = np.asarray(per_run["mc_first_env_rule_step"])
    outcome = np.asarray(per_run["mc_outcome"])
    n = term.size
    cross = []
    for t in (True, False):
        for lft in (True, False):
            for r in (True, False):
                sel = (term == t) & (left == lft) & (rec == r)
                cross.append(
                    {"env_terminated": t, "mc_left_envelope": lft, "mc_recovered": r, "runs": int(sel.sum())}
                )
    flags = {f: int(np.sum(np.asarray(per_run["env_term_flags"][f]) & term)) for f in FLAGS}
    both = term & left
    d_upto = np.asarray(per_run["rel_diff_upto_term"])
    a_term = np.asarray(per_run["env_term_alpha_rad"])
    d_full = np.asarray(per_run["rel_diff_full"])

    def stats(d, sel=None):
        d = d if sel is None else d[sel]
        if not d.size:
            return None
        return {"max": float(np.max(d)), "p99": float(np.percentile(d, 99)), "median": float(np.median(d))}

    return {
        "runs": int(n),
        "env_terminated_share": _share(term),
        "mc_left_envelope_share": _share(left),
        "mc_recovered_share": _share(rec),
        "mc_outcomes": {name: int(np.sum(outcome == i)) for i, name in enumerate(OUTCOME_NAMES)},
        "env_like_recovered_share": _share(rec & ~left),
        "cross_tab": cross,
        "env_termination_flags": flags,
        "term_step_equals_mc_first_outside": int(np.sum(both & (k_term == k_out))),
        "term_step_differs": int(np.sum(both & (k_term != k_out))),
        "env_terminated_only": int(np.sum(term & ~left)),
        "mc_left_only": int(np.sum(~term & left)),
        "term_step_equals_env_rule_on_mc": int(np.sum(term & (k_term == k_rule))),
        "env_term_time_s": stats(k_term * DT_S, term),
        "mc_left_time_s": stats(k_out * DT_S, left),
        "rel_diff_upto_term": stats(d_upto),
        "rel_diff_upto_term_terminated_runs": stats(d_upto, term),
        "env_terminations_alpha_below_min": int(np.sum(term & (a_term < ALPHA_MIN_RAD))),
        "env_terminations_alpha_above_max": int(np.sum(term & (a_term > ALPHA_MAX_RAD))),
        "env_term_time_s_alpha_below_min": stats(k_term * DT_S, term & (a_term < ALPHA_MIN_RAD)),
        "env_term_time_s_alpha_above_max": stats(k_term * DT_S, term & (a_term > ALPHA_MAX_RAD)),
        "mc_alpha_min_rad_terminated_runs": stats(np.asarray(per_run["mc_alpha_min_rad"]), term),
        "earliest_time_rel_diff_above_1e-6_s": _earliest(per_run["first_step_rel_diff_above_1e-6"]),
        "earliest_time_rel_diff_above_1e-4_s": _earliest(per_run["first_step_rel_diff_above_1e-4"]),
        "runs_rel_diff_above_1e-4_before_term": int(
            np.sum(
                (np.asarray(per_run["first_step_rel_diff_above_1e-4"]) >= 0)
                & ((np.asarray(per_run["first_step_rel_diff_above_1e-4"]) <= k_term) | ~term)
            )
        ),
        "rel_diff_full_run": stats(d_full),
        "env_commands_finite_all": bool(np.all(per_run["env_commands_finite"])),
        "mc_nonfinite_runs": int(np.sum(per_run["mc_nonfinite"])),
    }


def _finite(v):
    """JSON-safe: NaN and infinities -> None, recursively."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _finite(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_finite(x) for x in v]
    return v


def to_json(doc: dict) -> str:
    """The document with one top-level key per line block; the per-run lists compact (one line each)."""
    doc = _finite(doc)
    per_run = doc.pop("per_run")
    head = json.dumps(doc, indent=1)[:-2]
    rows = ",\n".join(
        f"  {json.dumps(k)}: {json.dumps(v, separators=(',', ':'))}" for k, v in per_run.items()
    )
    return f'{head},\n "per_run": {{\n{rows}\n }}\n}}\n'


def print_table(s: dict, duration_s: float) -> None:
    n = s["runs"]
    print(
        f"runs {n}: env terminated {100 * s['env_terminated_share']:.1f}%, MC left envelope "
        f"{100 * s['mc_left_envelope_share']:.1f}%, MC recovered {100 * s['mc_recovered_share']:.1f}%, "
        f"env-like (recovered and never left) {100 * s['env_like_recovered_share']:.1f}%"
    )
    print("| env terminated | MC left envelope | MC recovered | runs | share |")
    print("|---|---|---|---:|---:|")
    for row in s["cross_tab"]:
        if row["runs"]:
            cells = (
                "yes" if row[k] else "no" for k in ("env_terminated", "mc_left_envelope", "mc_recovered")
            )
            print(f"| {' | '.join(cells)} | {row['runs']} | {100 * row['runs'] / n:.1f}% |")
    print(f"termination flags: {s['env_termination_flags']}")
    print(
        f"env termination step == MC first step outside: {s['term_step_equals_mc_first_outside']}, differs: "
        f"{s['term_step_differs']}, env only: {s['env_terminated_only']}, MC only: {s['mc_left_only']}"
    )
    print(
        f"env terminations with alpha below its minimum: {s['env_terminations_alpha_below_min']} "
        f"(time s {s['env_term_time_s_alpha_below_min']}), above its maximum: "
        f"{s['env_terminations_alpha_above_max']} (time s {s['env_term_time_s_alpha_above_max']})"
    )
    print(f"trajectory difference / scale up to the env's termination (all runs): {s['rel_diff_upto_term']}")
    print(f"  terminated runs: {s['rel_diff_upto_term_terminated_runs']}")
    print(f"whole {duration_s:g} s run: {s['rel_diff_full_run']}")
    print(
        f"earliest time the difference exceeds 1e-6: {s['earliest_time_rel_diff_above_1e-6_s']} s, 1e-4: "
        f"{s['earliest_time_rel_diff_above_1e-4_s']} s"
    )


def per_run_lists(per_run: dict) -> dict:
    """The per-run arrays as JSON lists (the termination flags one list per flag)."""
    return {
        k: {f: np.asarray(v[f]).tolist() for f in FLAGS} if k == "env_term_flags" else np.asarray(v).tolist()
        for k, v in per_run.items()
    }


def command_text(argv: list[str] | None) -> str:
    """The command line that ran this script."""
    return "python " + " ".join(shlex.quote(a) for a in [sys.argv[0], *(argv or sys.argv[1:])])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=2027)
    ap.add_argument("--target-alpha", type=float, default=ALPHA_TARGET_RAD, help="alpha_d, rad")
    ap.add_argument("--duration", type=float, default=60.0, help="s (the Monte Carlo's run length)")
    ap.add_argument("--chunk", type=int, default=250, help="runs per compiled call")
    ap.add_argument("--out", type=Path, default=None, help="JSON path (default results/env_vs_mc/...)")
    ap.add_argument(
        "--disturbances", default="none", help="as harv-jax mc (e.g. default: the env with turbulence)"
    )
    args = ap.parse_args(argv)
    if args.disturbances != "none":
        main_disturbed(args, argv)
        return
    res = run(args.seed, args.runs, args.target_alpha, args.duration, args.chunk)
    per_run = res.pop("per_run")
    summary = summarize(per_run)
    doc = {
        "command": command_text(argv),
        "seed": args.seed,
        "runs": args.runs,
        "target_alpha_rad": args.target_alpha,
        "duration_s": args.duration,
        "cpu": cpu_model(),
        "jax": jax.__version__,
        "backend": jax.default_backend(),
        "dtype": str(jnp.result_type(float)),
        "scale": dict(zip(WIND_INDEX, SCALE.tolist(), strict=True)),
        **res,
        "summary": summary,
        "per_run": per_run_lists(per_run),
    }
    out = args.out or RESULTS / f"seed{args.seed}_n{args.runs}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json(doc))
    print_table(summary, args.duration)
    print(f"compile {res['wall_s']['compile']} s, run {res['wall_s']['run']} s; wrote {out}")


def main_disturbed(args: argparse.Namespace, argv: list[str] | None) -> None:
    res = run_disturbed(args.seed, args.runs, args.target_alpha, args.duration, args.chunk, args.disturbances)
    per_run = res.pop("per_run")
    summary = summarize_disturbed(per_run)
    doc = {
        "command": command_text(argv),
        "seed": args.seed,
        "runs": args.runs,
        "duration_s": args.duration,
        "cpu": cpu_model(),
        "jax": jax.__version__,
        **res,
        "summary": summary,
        "per_run": per_run_lists(per_run),
    }
    out = args.out or RESULTS / f"{args.disturbances}_seed{args.seed}_n{args.runs}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(to_json(doc))
    print(json.dumps(summary, indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
