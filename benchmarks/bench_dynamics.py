"""Dynamics throughput: RK4 aircraft-steps per second, vmapped JAX vs a per-aircraft numpy loop.

Usage::

    python benchmarks/bench_dynamics.py [--quick] [--machine NAME] [--x64] [--out-dir DIR]

For each batch size B in 1, 4, 16, ..., 65,536 it jits ``vmap`` over B aircraft (each with its own
parameters: mass, inertia and aero_scale varied) of a ``lax.scan`` of N steps of
``actuator_step`` + ``rk4_body_step`` (dt = 0.01 s), measures the compile time (``lower().compile()``)
and the best of a few timed runs (``block_until_ready``), and reports aircraft-steps/s = B * N / time.
In the same run it steps one aircraft at a time with the plain-numpy wind-axis model
(``benchmarks/numpy_harv.py``: RK4 + the same actuator, a Python loop as a Gym env does) and reports
the ratio best-batch / numpy. Results go to ``benchmarks/results/dynamics_<machine>.json``
(``dynamics_<machine>_quick.json`` with ``--quick``).

Runs on CPU or GPU (whatever ``jax.devices()[0]`` is); needs only jax, flax, numpy and harv_jax.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import platform
import sys
import time
from pathlib import Path

# allow `python benchmarks/bench_dynamics.py` from the repository root (benchmarks/ is not installed)
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.common import (  # noqa: E402
    cpu_cores,
    cpu_model,
    load_average_1min,
    machine_name,
    set_host_devices,
    write_json,
)


def _host_devices_from_argv(argv: list[str]) -> int:
    """--host-devices N (default: one XLA host device per CPU core), read before jax starts."""
    for i, a in enumerate(argv):
        if a == "--host-devices" and i + 1 < len(argv):
            return int(argv[i + 1])
        if a.startswith("--host-devices="):
            return int(a.split("=", 1)[1])
    return cpu_cores()


set_host_devices(_host_devices_from_argv(sys.argv))

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from jax.sharding import Mesh, NamedSharding, PartitionSpec  # noqa: E402

from benchmarks import numpy_harv  # noqa: E402
from harv_jax.aircraft import harv  # noqa: E402
from harv_jax.dynamics import actuator_step, from_wind, rk4_body_step  # noqa: E402

DT_S = 0.01
BATCH_SIZES = tuple(4**k for k in range(11))  # 1 ... 1,048,576 (default max 65,536)
DEFAULT_MAX_BATCH = 65536
TARGET_RATIO = 1000.0  # the first dynamics issue's target
TARGET_RATIO_ISSUE18 = 500.0  # speed target: >= 500x the numpy loop on the project's CPU
#: Reset bounds of the paper (docs/model.md), [V, alpha, beta, p, q, r, mu, gamma, chi, h].
RESET_LO = np.array([100, -0.175, -0.262, -2.094, -1.047, -0.524, -np.pi, -1.047, -np.pi, 20000.0])
RESET_HI = np.array([1500, 1.047, 0.262, 2.094, 1.047, 0.524, np.pi, 1.047, np.pi, 30000.0])


def make_fleet(seed: int, batch: int, dtype) -> tuple:
    """Initial BodyStates, surface deflections, commands and parameters of ``batch`` aircraft."""
    rng = np.random.default_rng(seed)
    x0 = rng.uniform(RESET_LO, RESET_HI, (batch, 10))
    cmd = rng.uniform(numpy_harv.NumpyParams().u_min_rad, numpy_harv.NumpyParams().u_max_rad, (batch, 3))
    base = harv(dtype=dtype)

    def batched(leaf):
        return np.broadcast_to(np.asarray(leaf), (batch,) + leaf.shape)

    params = jax.tree.map(batched, base)
    params = params.replace(
        mass_slug=params.mass_slug * rng.uniform(0.9, 1.1, batch),
        Ixx=params.Ixx * rng.uniform(0.9, 1.1, batch),
        Iyy=params.Iyy * rng.uniform(0.9, 1.1, batch),
        Izz=params.Izz * rng.uniform(0.9, 1.1, batch),
        aero_scale=params.aero_scale * rng.uniform(0.9, 1.1, (batch, params.aero_scale.shape[-1])),
    )
    params = jax.tree.map(lambda a: jnp.asarray(a, dtype=dtype), params)
    states = jax.jit(jax.vmap(from_wind))(jnp.asarray(x0, dtype=dtype))
    return states, jnp.zeros((batch, 3), dtype), jnp.asarray(cmd, dtype), params


def make_fly(n_steps: int):
    """jit(vmap(scan of n_steps of actuator + RK4)) -> final (BodyState, deflections)."""

    def fly_one(state, delta, cmd, params):
        def step(carry, _):
            s, d = carry
            d = actuator_step(d, cmd, params, DT_S)
            return (rk4_body_step(s, d, params, DT_S), d), None

        return jax.lax.scan(step, (state, delta), None, length=n_steps)[0]

    return jax.jit(jax.vmap(fly_one))


def bench_jax(batch: int, n_steps: int, repeats: int, dtype, seed: int) -> dict:
    """Compile time and best-of-``repeats`` throughput for one batch size."""
    args = make_fleet(seed, batch, dtype)
    devices = jax.local_devices()
    n_dev = len(devices) if batch % len(devices) == 0 else 1
    if n_dev > 1:  # one shard of the fleet per device (on a CPU: per core)
        sharding = NamedSharding(Mesh(np.array(devices), ("aircraft",)), PartitionSpec("aircraft"))
        args = jax.device_put(args, sharding)
    fly = make_fly(n_steps)
    t0 = time.perf_counter()
    compiled = fly.lower(*args).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(*args))  # warm-up (allocation, first-run effects)
    times, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = jax.block_until_ready(compiled(*args))
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    best = min(times)
    return {
        "batch": batch,
        "devices_used": n_dev,
        "n_steps": n_steps,
        "compile_s": round(compile_s, 4),
        "best_run_s": best,
        "median_run_s": float(np.median(times)),
        "aircraft_steps_per_s": batch * n_steps / best,
        "us_per_aircraft_step": 1e6 * best / (batch * n_steps),
        "best_cpu_s": min(cpu),
        "aircraft_steps_per_cpu_s": batch * n_steps / min(cpu),
        "finite_fraction": float(np.mean(np.all(np.isfinite(np.asarray(out[0].uvw_fps)), axis=-1))),
    }


def bench_numpy(n_steps: int, repeats: int, seed: int) -> dict:
    """One aircraft stepped n_steps times in a Python loop (numpy_harv, float64), best of ``repeats``."""
    rng = np.random.default_rng(seed)
    prm = numpy_harv.NumpyParams()
    x0 = rng.uniform(RESET_LO, RESET_HI)
    cmd = rng.uniform(prm.u_min_rad, prm.u_max_rad)
    numpy_harv.simulate(x0, cmd, prm, DT_S, 10)  # warm-up
    times, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        numpy_harv.simulate(x0, cmd, prm, DT_S, n_steps)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    best = min(times)
    return {
        "n_steps": n_steps,
        "best_run_s": best,
        "best_cpu_s": min(cpu),
        "steps_per_cpu_s": n_steps / min(cpu),
        "steps_per_s": n_steps / best,
        "us_per_step": 1e6 * best / n_steps,
    }


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer steps/repeats, batches up to 4096")
    ap.add_argument("--machine", default=None, help="name for the results file (default: from the device)")
    ap.add_argument("--x64", action="store_true", help="float64 instead of the default float32")
    ap.add_argument("--max-batch", type=int, default=None, help="largest batch size to run")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out-dir", type=Path, default=Path(__file__).resolve().parent / "results")
    ap.add_argument("--note", default="", help="free text stored in the JSON (e.g. 'machine shared')")
    ap.add_argument(
        "--host-devices", type=int, default=None,
        help="XLA host (CPU) devices to shard the fleet over; default one per core (read at start-up)",
    )  # fmt: skip
    args = ap.parse_args(argv)

    if args.x64:
        jax.config.update("jax_enable_x64", True)
    dtype = jnp.float64 if args.x64 else jnp.float32
    # steps per batch: about `work` aircraft-steps per timed run, within [min_steps, max_steps]
    work, min_steps, max_steps = (2**18, 10, 100) if args.quick else (2**22, 20, 400)
    repeats = 2 if args.quick else 5
    max_batch = args.max_batch or (4096 if args.quick else DEFAULT_MAX_BATCH)
    batches = [b for b in BATCH_SIZES if b <= max_batch]
    dev = jax.devices()[0]
    machine = machine_name(args.machine)

    load_before = load_average_1min()
    print(f"device {dev.platform}:{dev.device_kind}  jax {jax.__version__}  dtype {jnp.dtype(dtype).name}")
    np_res = bench_numpy(n_steps=200 if args.quick else 1000, repeats=3, seed=args.seed)
    print(f"numpy (1 aircraft, Python loop): {np_res['steps_per_s']:.0f} steps/s "
          f"({np_res['us_per_step']:.1f} us/step)")  # fmt: skip
    print(f"{'batch':>7} {'steps':>6} {'compile s':>10} {'run s':>9} {'aircraft-steps/s':>17} {'x numpy':>9} "
          f"{'x numpy CPU-s':>14}")  # fmt: skip
    rows = []
    for b in batches:
        r = bench_jax(b, int(np.clip(work // b, min_steps, max_steps)), repeats, dtype, args.seed)
        r["ratio_vs_numpy"] = r["aircraft_steps_per_s"] / np_res["steps_per_s"]
        r["ratio_vs_numpy_cpu_time"] = r["aircraft_steps_per_cpu_s"] / np_res["steps_per_cpu_s"]
        rows.append(r)
        print(f"{b:>7} {r['n_steps']:>6} {r['compile_s']:>10.2f} {r['best_run_s']:>9.4f} "
              f"{r['aircraft_steps_per_s']:>17.3e} {r['ratio_vs_numpy']:>9.1f} "
              f"{r['ratio_vs_numpy_cpu_time']:>14.1f}")  # fmt: skip
    best = max(rows, key=lambda r: r["aircraft_steps_per_s"])
    result = {
        "benchmark": "dynamics",
        "machine": machine,
        "timestamp_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "jax_version": jax.__version__,
        "jaxlib_version": _jaxlib_version(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "device": {"platform": dev.platform, "kind": dev.device_kind, "count": jax.local_device_count()},
        "cpu_count": os.cpu_count(),
        "cpu_model": cpu_model(),
        "load_average_1min_before_after": [load_before, load_average_1min()],
        "dtype": jnp.dtype(dtype).name,
        "dt_s": DT_S,
        "quick": args.quick,
        "seed": args.seed,
        "note": args.note,
        "steps_rule": {"work": work, "min_steps": min_steps, "max_steps": max_steps, "repeats": repeats},
        "method": (
            "jit(vmap(lax.scan of n_steps x [actuator_step + rk4_body_step])) over B aircraft with varied "
            "mass/inertia/aero_scale, the fleet sharded over the local devices (on a CPU one XLA host device "
            "per core) when the batch divides; time = best of repeats after a warm-up, block_until_ready; "
            "compile_s = lower().compile(). numpy: benchmarks/numpy_harv.py wind-axis RK4 + actuator, one "
            "aircraft in a Python loop, float64. ratio_vs_numpy = wall-clock throughputs (the target's "
            "measure; on a loaded machine the short numpy runs lose the CPU and the ratio inflates); "
            "ratio_vs_numpy_cpu_time = throughputs per CPU-second of the process (load-robust; on a quiet "
            "machine it is ~ratio_vs_numpy / devices_used)."
        ),
        "numpy": np_res,
        "jax": rows,
        "best": {
            "batch": best["batch"],
            "aircraft_steps_per_s": best["aircraft_steps_per_s"],
            "ratio_vs_numpy": best["ratio_vs_numpy"],
            "ratio_vs_numpy_cpu_time": best["ratio_vs_numpy_cpu_time"],
            "target_ratio": TARGET_RATIO,
            "meets_target": best["ratio_vs_numpy"] >= TARGET_RATIO,
            "target_ratio_issue18": TARGET_RATIO_ISSUE18,
            "meets_target_issue18": best["ratio_vs_numpy"] >= TARGET_RATIO_ISSUE18,
        },
    }
    name = f"dynamics_{machine}_quick.json" if args.quick else f"dynamics_{machine}.json"
    path = write_json(args.out_dir, name, result)
    print(f"best: batch {best['batch']}, {best['aircraft_steps_per_s']:.3e} aircraft-steps/s = "
          f"{best['ratio_vs_numpy']:.0f}x numpy (targets {TARGET_RATIO:.0f}x, speed target "
          f"{TARGET_RATIO_ISSUE18:.0f}x)")  # fmt: skip
    print(f"wrote {path}")
    print(markdown_table(result))
    return result


def _jaxlib_version() -> str | None:
    try:
        import jaxlib

        return jaxlib.__version__
    except Exception:  # pragma: no cover - informational only
        return None


def markdown_table(result: dict) -> str:
    """The README table: batch, aircraft-steps/s, ratio to numpy, compile s."""
    lines = [
        f"Dynamics throughput on {result['machine']} ({result['device']['kind']}, "
        f"jax {result['jax_version']}, "
        f"{result['dtype']}, RK4 dt = {result['dt_s']} s); numpy per-aircraft baseline "
        f"{result['numpy']['steps_per_s']:.0f} steps/s.",
        "",
        "| aircraft (batch) | aircraft-steps/s | x numpy | compile s |",
        "|---:|---:|---:|---:|",
    ]
    for r in result["jax"]:
        lines.append(
            f"| {r['batch']:,} | {r['aircraft_steps_per_s']:.3g} | {r['ratio_vs_numpy']:.0f} "
            f"| {r['compile_s']:.1f} |"
        )
    return "\n".join(lines)


if __name__ == "__main__":
    main()
