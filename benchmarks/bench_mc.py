"""Monte Carlo wall time (compile and run separately), FLOPs per run-step and the share of the machine's
ceiling; optionally the 10,000-run recovery envelope map.

Usage::

    python benchmarks/bench_mc.py                        # 1000 runs x 60 s, smc and hybrid, local devices
    python benchmarks/bench_mc.py --envelope             # + the 100 x 100 envelope map per controller
    python benchmarks/bench_mc.py --quick                # 64 runs x 5 s (+ 8 x 8 map): a sanity run
    python benchmarks/bench_mc.py --envelope --compare-chunk 250  # + chunks of 250 runs (the old default)

What is timed: ``harv_jax.evaluation.montecarlo.rollout.run_mc`` exactly as ``harv-jax mc`` calls it (common
random initial states from the paper's reset bounds, nominal aircraft, alpha_d = 0.349 rad, dt 0.01 s,
decimated bands every 10 steps, chunks of ``--chunk`` runs sharded over the local devices; by default the
CLI's automatic chunk, ``guards.auto_chunk``). ``compile`` is
``lower().compile()`` of the chunk function, ``run`` the loop over all chunks including the transfer of
the results to the host (best of ``--repeats`` calls; each call compiles again, and the best compile is
reported, as the first call of a process also pays one-time warm-up; the envelope map is one call, its
compile includes it). On a CPU, like the CLI, one XLA host device is created per core (``--host-devices``).
Controllers come from ``harv_jax.control.registry.build_controller`` (``hybrid`` and ``rl`` fly ``--policy``,
default the shipped policy); one that cannot be built is recorded as skipped. With ``--compare-chunk N``
every study is also timed in chunks of N runs, the two settings alternating call by call (``chunk_comparison``
lists the run seconds and the speed-up; the outcomes of the two settings are compared run by run).

FLOPs per run-step come from XLA's cost analysis (``jit(...).lower(...).compile().cost_analysis()``) of one
closed-loop step of one run, the body of ``closed_loop``'s scan: wind state, controller (policy forward,
SMC, filter, whatever the controller does), actuator, RK4 of the body-axis dynamics. (The cost analysis of
a whole rollout counts a ``while`` body once, so the step is lowered on its own.) Achieved FLOP/s =
FLOPs/step x runs x steps / run time; the ceiling is the best fp32 square matmul measured in the same run
(the approach of ``bench_train.py``). Results go to ``benchmarks/results/mc_<machine>.json``
(``mc_<machine>_quick.json`` with ``--quick``).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import platform
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root, for benchmarks.*

from benchmarks.common import (  # noqa: E402
    cpu_cores,
    cpu_model,
    load_average_1min,
    set_host_devices,
    write_json,
)

RESULTS_DIR = Path(__file__).resolve().parent / "results"
DT_S = 0.01
TARGET_ALPHA_RAD = 0.349
RECORD_EVERY = 10
#: Targets (run time after compilation).
TARGETS_S = {
    "mc_1000_hybrid_cpu_2core": 15.0,
    "mc_1000_hybrid_gpu_h100": 1.0,
    "envelope_10000_cpu_2core": 180.0,
}


def _timed(fn) -> float:
    import jax

    t0 = time.perf_counter()
    jax.block_until_ready(fn())
    return time.perf_counter() - t0


def matmul_ceiling(n: int, repeats: int = 5) -> dict[str, float]:
    """Best fp32 square-matmul FLOP/s on the default device (as ``bench_train.matmul_ceiling``)."""
    import jax
    import jax.numpy as jnp

    a = jax.random.normal(jax.random.key(0), (n, n), jnp.float32)
    b = jax.random.normal(jax.random.key(1), (n, n), jnp.float32)
    f = jax.jit(jnp.dot)
    f(a, b).block_until_ready()
    best = min(_timed(lambda: f(a, b)) for _ in range(repeats))
    return {"flops_per_s": 2.0 * n**3 / best, "n": n}


def step_cost(controller, params, reference_rad) -> dict[str, float]:
    """XLA cost analysis of one closed-loop step of one run (the body of ``closed_loop``'s scan)."""
    import jax
    import jax.numpy as jnp

    from harv_jax.dynamics.actuators import actuator_step
    from harv_jax.dynamics.integrate import rk4_body_step
    from harv_jax.dynamics.state import from_wind, is_finite, to_wind
    from harv_jax.task.scenarios import spin_entry_state

    def step(state, delta, cstate, key):
        x = to_wind(state)
        u, cstate_new, _ = controller.apply(cstate, x, reference_rad, key)
        u = jnp.where(jnp.all(jnp.isfinite(u)), u, delta)
        delta_new = actuator_step(delta, u, params, DT_S)
        state_new = rk4_body_step(state, delta_new, params, DT_S)
        ok = is_finite(state_new)
        state_new = jax.tree.map(lambda a, b: jnp.where(ok, a, b), state_new, state)
        return state_new, delta_new, cstate_new

    state0 = from_wind(spin_entry_state())
    args = (state0, jnp.zeros(3), controller.init(params), jax.random.key(0))
    cost = jax.jit(step).lower(*args).compile().cost_analysis()
    cost = cost[0] if isinstance(cost, list | tuple) else cost
    return {k: float(cost[k]) for k in ("flops", "transcendentals", "bytes accessed") if k in cost}


def policy_forward_cost(policy: str | None) -> dict[str, float] | None:
    """Cost analysis of one deterministic policy forward (obs [11] -> action [3]); None if unavailable."""
    import jax
    import jax.numpy as jnp

    try:
        from harv_jax.policy import resolve_policy

        act = resolve_policy(policy).deterministic
    except Exception:  # a missing policy only removes this line of the report
        return None
    cost = jax.jit(act).lower(jnp.zeros(11, jnp.float32)).compile().cost_analysis()
    cost = cost[0] if isinstance(cost, list | tuple) else cost
    return {k: float(cost[k]) for k in ("flops", "transcendentals") if k in cost}


def bench_controller(
    name: str,
    ctrl,
    runs: int,
    n_steps: int,
    chunks: list[int | None],
    seed: int,
    ceiling: float,
    repeats: int,
) -> list[dict]:
    """Time the Monte Carlo of one controller with each chunk setting (``None``: the automatic chunk):
    ``repeats`` calls of ``run_mc`` per setting, the settings alternating; best compile time, best run time.
    Also counts its FLOPs per run-step. One row per setting."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from harv_jax.aircraft import harv
    from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
    from harv_jax.task.criteria import OUTCOME_NAMES

    reference = jnp.array([TARGET_ALPHA_RAD, 0.0, 0.0])
    cost = step_cost(ctrl, harv(), reference)
    inputs = sample_mc_inputs(jax.random.key(seed), runs, harv())
    walls: dict[int, list[dict]] = {i: [] for i in range(len(chunks))}
    outs = {}
    for _ in range(repeats):  # each call compiles again; the first run also pays one-time warm-up costs
        for i, chunk in enumerate(chunks):
            outs[i], wall = run_mc(ctrl, inputs, reference, n_steps, DT_S, RECORD_EVERY, chunk)
            walls[i].append(wall)
    rows = []
    for i, chunk in enumerate(chunks):
        # the best compile: the first call of a process also pays one-time warm-up (the controller built
        # first would otherwise be charged for it)
        ws = walls[i]
        wall = {"compile": min(w["compile"] for w in ws), "run": min(w["run"] for w in ws)}
        out = outs[i]
        rec = np.asarray(out.metrics.recovered)
        outcome = np.asarray(out.metrics.outcome)
        run_steps = runs * n_steps
        achieved = cost.get("flops", float("nan")) * run_steps / wall["run"]
        rows.append({
            "controller": name,
            "runs": runs,
            "steps_per_run": n_steps,
            "chunk": ws[0]["chunk_runs"],
            "chunk_setting": "auto" if chunk is None else chunk,
            "compile_s": wall["compile"],
            "run_s": wall["run"],
            "run_s_each_call": [w["run"] for w in ws],
            "compile_s_each_call": [w["compile"] for w in ws],
            "run_steps_per_s": run_steps / wall["run"],
            "step_cost": cost,
            "achieved_flops_per_s": achieved,
            "fraction_of_matmul_ceiling": achieved / ceiling,
            "recovery_rate": float(rec.mean()),
            "outcomes": {name: int((outcome == code).sum()) for code, name in enumerate(OUTCOME_NAMES)},
            "_outcome": outcome,
        })  # fmt: skip
    for r in rows[1:]:  # the same runs in other chunks: equal outcomes (the floats differ by rounding)
        r["outcomes_equal_to_first_setting"] = bool(np.array_equal(r["_outcome"], rows[0]["_outcome"]))
    for r in rows:
        del r["_outcome"]
    return rows


def bench_envelope(name: str, ctrl, n: int, n_steps: int, chunk: int | None, seed: int) -> dict:
    """Time the n x n alpha0 x r0 envelope map of one controller."""
    import jax
    import jax.numpy as jnp

    from harv_jax.aircraft import harv
    from harv_jax.evaluation.envelope.grid import envelope_inputs, make_grid, run_envelope

    grid = make_grid("alpha0", "r0", n, n)
    inputs = envelope_inputs(jax.random.key(seed), grid, harv())
    emap, _, wall = run_envelope(
        ctrl, inputs, grid, jnp.array([TARGET_ALPHA_RAD, 0.0, 0.0]), n_steps, DT_S, chunk
    )
    return {
        "controller": name,
        "grid": f"alpha0 x r0, {n} x {n} (reset bounds; other states envelope.grid.DEFAULT_FIXED_STATE)",
        "runs": grid.n_runs,
        "steps_per_run": n_steps,
        "chunk": wall["chunk_runs"],
        "chunk_setting": "auto" if chunk is None else chunk,
        "compile_s": wall["compile"],
        "run_s": wall["run"],
        "run_steps_per_s": grid.n_runs * n_steps / wall["run"],
        "recovery_rate": float(emap.recovered.mean()),
    }


def _pairs(
    rows: list[dict], env_rows: list[dict], base: str, is_other: Callable[[str], bool]
) -> Iterator[tuple[str, dict, dict]]:
    """Per study (``mc``, ``envelope``) and controller: (``<study>_<controller>``, the row of implementation
    ``base``, a row whose implementation passes ``is_other``)."""
    for study, items in (("mc", rows), ("envelope", env_rows)):
        by = {(r["controller"], r["implementation"]): r for r in items}
        for (name, impl), other in by.items():
            first = by.get((name, base))
            if first is not None and impl != base and is_other(impl):
                yield f"{study}_{name}", first, other


def chunk_comparison(rows: list[dict], env_rows: list[dict]) -> dict[str, dict[str, float]]:
    """Per controller and study: run seconds with ``--compare-chunk`` and with ``--chunk`` (same process,
    alternating), and the speed-up = compare / chunk."""
    return {
        key: {
            "chunk_compared": r["chunk"],
            "chunk": cur["chunk"],
            "run_s_compared": r["run_s"],
            "run_s": cur["run_s"],
            "run_speedup": r["run_s"] / cur["run_s"],
            "compile_s_compared": r["compile_s"],
            "compile_s": cur["compile_s"],
        }
        for key, cur, r in _pairs(rows, env_rows, "current", lambda impl: impl.startswith("current_chunk_"))
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--controllers", default="smc,hybrid", help="comma list of smc, rl, hybrid")
    ap.add_argument("--policy", default=None, help="rl/hybrid policy (default: the shipped policy)")
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--duration", type=float, default=60.0, help="seconds per run")
    ap.add_argument(
        "--chunk", type=int, default=None, help="runs per compiled call (default: automatic, as the CLI)"
    )
    ap.add_argument(
        "--compare-chunk",
        type=int,
        default=None,
        help="also time every study with this chunk, alternating with --chunk (e.g. 250, the pre-session-12 "
        "default)",
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeats", type=int, default=2, help="run_mc calls per controller (best run time)")
    ap.add_argument("--envelope", action="store_true", help="also time the n x n envelope map")
    ap.add_argument("--envelope-n", type=int, default=100, help="points per envelope axis")
    ap.add_argument("--envelope-chunk", type=int, default=None, help="runs per call (default: automatic)")
    ap.add_argument("--matmul-n", type=int, default=None, help="matmul size (CPU 2048, GPU 8192)")
    ap.add_argument("--host-devices", type=int, default=cpu_cores(), help="XLA host devices on a CPU")
    ap.add_argument("--quick", action="store_true", help="64 runs x 5 s (+ 8 x 8 map): a sanity run")
    ap.add_argument("--machine", default=None)
    ap.add_argument("--note", default="", help="free text stored in the JSON (e.g. 'machine shared')")
    ap.add_argument("--out-dir", type=Path, default=RESULTS_DIR)
    args = ap.parse_args()
    set_host_devices(args.host_devices)

    import jax

    from benchmarks.common import machine_name
    from harv_jax.control.registry import ControllerOptions, build_controller
    from harv_jax.policies import DEFAULT_POLICY_SPEC

    dev = jax.devices()[0]
    gpu = dev.platform != "cpu"
    runs, duration, env_n = args.runs, args.duration, args.envelope_n
    if args.quick:
        runs, duration, env_n = 64, 5.0, 8
    n_steps = int(round(duration / DT_S))
    n_steps -= n_steps % RECORD_EVERY
    chunks = [args.chunk] + ([args.compare_chunk] if args.compare_chunk else [])
    env_chunks = [args.envelope_chunk] + ([args.compare_chunk] if args.compare_chunk else [])
    machine = machine_name(args.machine)
    print(
        f"device {dev.platform}:{dev.device_kind} x{jax.local_device_count()}  jax {jax.__version__}",
        flush=True,
    )

    load_before = load_average_1min()
    matmul_n = args.matmul_n or (8192 if gpu else (1024 if args.quick else 2048))
    ceiling = matmul_ceiling(matmul_n)
    print(f"fp32 matmul ceiling: {ceiling['flops_per_s'] / 1e9:,.1f} GFLOP/s (n = {matmul_n})", flush=True)
    rows, env_rows, skipped = [], [], {}
    for name in [c.strip() for c in args.controllers.split(",") if c.strip()]:
        try:
            ctrl = build_controller(name, ControllerOptions(policy=args.policy))
        except Exception as e:  # e.g. a policy that cannot be loaded: record and go on
            skipped[name] = f"{type(e).__name__}: {e}"
            print(f"{name}: skipped ({skipped[name]})", flush=True)
            continue
        mc_rows = bench_controller(
            name, ctrl, runs, n_steps, chunks, args.seed, ceiling["flops_per_s"], args.repeats
        )
        for i, r in enumerate(mc_rows):  # the settings after the first are a comparison
            r["implementation"] = "current" if i == 0 else f"current_chunk_{r['chunk_setting']}"
            r["load_average_1min_after"] = load_average_1min()
        es = []
        for i, c in enumerate(env_chunks if args.envelope else []):
            e = bench_envelope(name, ctrl, env_n, n_steps, c, args.seed)
            e["implementation"] = "current" if i == 0 else f"current_chunk_{e['chunk_setting']}"
            e["load_average_1min_after"] = load_average_1min()
            es.append(e)
        again = matmul_ceiling(matmul_n)  # re-measured next to every timing; the best value is used
        ceiling["flops_per_s"] = max(ceiling["flops_per_s"], again["flops_per_s"])
        rows.extend(mc_rows)
        env_rows.extend(es)
        for r in mc_rows:
            print(
                f"{name:>7} ({r['implementation']}): {runs} runs x {n_steps} steps in chunks of "
                f"{r['chunk']}: compile {r['compile_s']:.1f} s, run {r['run_s']:.2f} s "
                f"({r['run_steps_per_s']:,.0f} run-steps/s), {r['step_cost'].get('flops', 0):,.0f} "
                f"FLOPs/step = {100 * r['fraction_of_matmul_ceiling']:.2f}% of the matmul ceiling, "
                f"recovery {r['recovery_rate']:.3f}",
                flush=True,
            )
        for e in es:
            print(
                f"{name:>7} ({e['implementation']}): envelope {env_n} x {env_n} = {e['runs']} runs in "
                f"chunks of {e['chunk']}: compile {e['compile_s']:.1f} s, run {e['run_s']:.1f} s, "
                f"recovered {100 * e['recovery_rate']:.1f}%",
                flush=True,
            )
    rows_current = [r for r in rows if r["implementation"] == "current"]
    for r in rows:  # against the best ceiling of the whole run (a busy machine otherwise inflates it)
        r["fraction_of_matmul_ceiling"] = r["achieved_flops_per_s"] / ceiling["flops_per_s"]
    policy_cost = (
        policy_forward_cost(args.policy) if {"rl", "hybrid"} & {r["controller"] for r in rows} else None
    )
    full = not args.quick and runs == 1000 and n_steps == 6000
    targets = {}
    hybrid = next((r for r in rows_current if r["controller"] == "hybrid"), None)
    if full and hybrid is not None:
        key = "mc_1000_hybrid_gpu_h100" if gpu else "mc_1000_hybrid_cpu_2core"
        targets[key] = {"target_run_s": TARGETS_S[key], "run_s": hybrid["run_s"],
                        "met": hybrid["run_s"] <= TARGETS_S[key]}  # fmt: skip
    if args.envelope and not args.quick and env_n == 100 and n_steps == 6000 and not gpu:
        key = "envelope_10000_cpu_2core"
        for e in (e for e in env_rows if e["implementation"] == "current"):
            targets[f"{key}_{e['controller']}"] = {"target_run_s": TARGETS_S[key], "run_s": e["run_s"],
                                                   "met": e["run_s"] <= TARGETS_S[key]}  # fmt: skip
    result = {
        "benchmark": "mc",
        "machine": machine,
        "quick": args.quick,
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "note": args.note,
        "jax": jax.__version__,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "device": {"platform": dev.platform, "kind": dev.device_kind, "count": jax.local_device_count()},
        "cpu_affinity": cpu_cores(),
        "load_average_1min_before_after": [load_before, load_average_1min()],
        "cpu_model": cpu_model(),
        "config": {
            "runs": runs,
            "duration_s": n_steps * DT_S,
            "dt_s": DT_S,
            "steps_per_run": n_steps,
            "record_every": RECORD_EVERY,
            "chunk": "auto" if args.chunk is None else args.chunk,
            "compare_chunk": args.compare_chunk,
            "target_alpha_rad": TARGET_ALPHA_RAD,
            "aircraft": "nominal",
            "initial_states": "paper reset bounds (V, alpha, beta, p, q, r)",
            "policy": args.policy or DEFAULT_POLICY_SPEC,
            "seed": args.seed,
            "dtype": "float32",
        },  # fmt: skip
        "matmul_ceiling_flops_per_s": ceiling,
        "policy_forward_cost": policy_cost,
        "results": rows,
        "envelope": env_rows or None,
        "skipped": skipped,
        "targets": targets,
        "chunk_comparison": chunk_comparison(rows, env_rows),
    }
    name = f"mc_{machine}_quick.json" if args.quick else f"mc_{machine}.json"
    path = write_json(args.out_dir, name, result)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
