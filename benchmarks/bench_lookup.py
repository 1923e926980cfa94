"""Gather-free aero lookups vs the table gather, side by side in the plant step and the SMC step.

Usage::

    python benchmarks/bench_lookup.py [--batch 1000] [--steps 50] [--repeats 7] [--quick]

``harv_jax.aircraft.aero.lookup`` interpolates the [27, 33] alpha table with a gather of two rows. Two
gather-free forms of the same interpolation are built here and swapped in for the duration of a trace:

- ``tent_matmul``: tent (hat) weights over the 27 breakpoints, nonzero only at the segment's two ends
  (``1 - frac`` and ``frac``, from the same ``idx``/``frac`` as the gather, so the value at a breakpoint
  and the derivative in alpha are the gather's), times the table: one [27] x [27, 33] matmul;
- ``segment_select``: the segment's two rows picked by a chain of 26 selects (no gather, no matmul).

``gather_always_wrap`` is the gather with the ``mod`` of the wrap also in the plant's RK4 stages, where
alpha is an ``arctan2`` (the lookup before ``in_range``). ``bound_no_lookup`` replaces the interpolation
by one affine row in alpha (not the model; its outputs differ): the most that any lookup could save.
Before timing, every gather-free form is checked against the gather in float64 (breakpoints, random
angles, clamped and wrapped angles beyond the table, and the forward derivative in alpha); the largest
differences go into the JSON.

What is timed is ``bench_step.build``'s plant step (actuator + RK4 + guard) and closed-loop SMC step
(which evaluates the model and its forward derivatives) at ``--batch`` aircraft on one XLA device, each
variant compiled separately (compile times recorded) and run interleaved, best of ``--repeats``. Results go
to ``benchmarks/results/lookup_<machine>.json`` (``lookup_<machine>_quick.json`` with ``--quick``).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=1")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks.bench_step import build  # noqa: E402
from benchmarks.common import load_average_1min, machine_name, result_header, write_json  # noqa: E402
from harv_jax.aircraft import aero  # noqa: E402
from harv_jax.aircraft import data_harv as data  # noqa: E402
from harv_jax.units import DEG_PER_RAD  # noqa: E402

N_BREAKPOINTS = len(data.ALPHA_DEG_GRID)


def _segment(
    alpha_rad: jnp.ndarray, in_range: bool, table_per_rad: np.ndarray | None = None
) -> tuple[jnp.ndarray, ...]:
    """(table, float segment index, fraction in the segment), as ``aero.lookup`` computes them."""
    table_per_rad = data.AERO_TABLE_PER_RAD if table_per_rad is None else table_per_rad
    table = jnp.asarray(table_per_rad, dtype=jnp.result_type(alpha_rad, float))
    return (table, *aero.segment(alpha_rad, in_range))


def lookup_tent_matmul(
    alpha_rad: jnp.ndarray,
    aero_scale: jnp.ndarray | None = None,
    in_range: bool = False,
    table_per_rad: np.ndarray | None = None,
) -> jnp.ndarray:
    """``aero.lookup`` as tent weights [27] times the table [27, 33] (no gather)."""
    table, idx, frac = _segment(alpha_rad, in_range, table_per_rad)
    k = jnp.arange(N_BREAKPOINTS, dtype=table.dtype)
    weights = jnp.where(k == idx, 1.0 - frac, 0.0) + jnp.where(k == idx + 1.0, frac, 0.0)
    row = weights @ table
    return row if aero_scale is None else row * aero_scale


def lookup_segment_select(
    alpha_rad: jnp.ndarray,
    aero_scale: jnp.ndarray | None = None,
    in_range: bool = False,
    table_per_rad: np.ndarray | None = None,
) -> jnp.ndarray:
    """``aero.lookup`` with the segment's rows picked by a chain of selects (no gather)."""
    table, idx, frac = _segment(alpha_rad, in_range, table_per_rad)
    lo, hi = table[0], table[1]
    for i in range(1, N_BREAKPOINTS - 1):
        lo, hi = jnp.where(idx >= i, table[i], lo), jnp.where(idx >= i, table[i + 1], hi)
    row = lo * (1.0 - frac) + hi * frac
    return row if aero_scale is None else row * aero_scale


def lookup_bound(
    alpha_rad: jnp.ndarray,
    aero_scale: jnp.ndarray | None = None,
    in_range: bool = False,
    table_per_rad: np.ndarray | None = None,
) -> jnp.ndarray:
    """NOT the model: one affine row in alpha, the cost floor of any lookup (outputs differ)."""
    table, idx, frac = _segment(alpha_rad, in_range, table_per_rad)
    row = table[3] + (idx + frac) * table[4]
    return row if aero_scale is None else row * aero_scale


def lookup_always_wrap(
    alpha_rad: jnp.ndarray,
    aero_scale: jnp.ndarray | None = None,
    in_range: bool = False,
    table_per_rad: np.ndarray | None = None,
) -> jnp.ndarray:
    """The gather with the wrap also where alpha is an arctan2 (the lookup before ``in_range``)."""
    return _GATHER(alpha_rad, aero_scale, False, table_per_rad)


_GATHER = aero.lookup
VARIANTS: dict[str, Callable] = {
    "gather": aero.lookup,
    "gather_always_wrap": lookup_always_wrap,
    "tent_matmul": lookup_tent_matmul,
    "segment_select": lookup_segment_select,
    "bound_no_lookup": lookup_bound,
}


@contextlib.contextmanager
def use_lookup(fn: Callable) -> Iterator[None]:
    """Trace with ``aero.lookup = fn`` (jax caches cleared on entry and exit)."""
    old = aero.lookup
    aero.lookup = fn
    jax.clear_caches()
    try:
        yield
    finally:
        aero.lookup = old
        jax.clear_caches()


def check_equal(fn: Callable) -> dict[str, float]:
    """Largest |fn - gather| in float64: values (breakpoints, random, beyond the table) and d/d alpha."""
    with jax.enable_x64(True):
        rng = np.random.default_rng(0)
        grid = data.ALPHA_DEG_GRID / DEG_PER_RAD
        beyond = np.radians([-90.0, -30.0, -14.5, 90.5, 120.0, 179.9, 180.0, -179.9, 270.0, -400.0])
        angles = {
            "breakpoints": grid,
            "random": rng.uniform(-0.3, 1.6, 500),
            "beyond_table": beyond,
            "near_breakpoints": np.concatenate([grid[1:-1] - 1e-9, grid[1:-1] + 1e-9]),
        }
        scale = jnp.asarray(rng.uniform(0.9, 1.1, len(data.AERO_COLUMNS)))
        out = {}
        for name, a in angles.items():
            a = jnp.asarray(a)
            ref = jax.vmap(lambda x: aero.lookup(x, scale))(a)
            got = jax.vmap(lambda x, f=fn: f(x, scale))(a)
            out[f"value_{name}"] = float(jnp.max(jnp.abs(got - ref)))
            d_ref = jax.vmap(lambda x: jax.jvp(lambda y: aero.lookup(y, scale), (x,), (1.0,))[1])(a)
            d_got = jax.vmap(lambda x, f=fn: jax.jvp(lambda y: f(y, scale), (x,), (1.0,))[1])(a)
            out[f"d_dalpha_{name}"] = float(jnp.max(jnp.abs(d_got - d_ref)))
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--batch", type=int, default=1000, help="aircraft per call")
    ap.add_argument("--steps", type=int, default=50, help="steps per timed call")
    ap.add_argument("--repeats", type=int, default=7, help="interleaved timed calls per variant")
    ap.add_argument("--quick", action="store_true", help="20 steps, 3 repeats")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--machine", default=None)
    ap.add_argument("--note", default="", help="free text stored in the JSON (e.g. 'machine shared')")
    ap.add_argument("--out-dir", type=Path, default=ROOT / "benchmarks" / "results")
    args = ap.parse_args(argv)
    if args.quick:
        args.steps, args.repeats = 20, 3
    load_before = load_average_1min()
    checks = {k: check_equal(fn) for k in ("tent_matmul", "segment_select") for fn in [VARIANTS[k]]}
    for k, c in checks.items():
        print(f"{k}: max |diff| vs gather (float64) {max(c.values()):.2e}", flush=True)
    built = {}
    for k, fn in VARIANTS.items():
        with use_lookup(fn):
            built[k] = build(args.batch, args.steps, None, args.seed, controllers=("smc",))
    times = {(k, s): [] for k in built for s in built[k]}
    cpu_times = {(k, s): [] for k in built for s in built[k]}
    for _ in range(args.repeats):
        for k, steps in built.items():
            for s, b in steps.items():
                t0, c0 = time.perf_counter(), time.process_time()
                jax.block_until_ready(b["compiled"](*b["args"]))
                times[(k, s)].append(time.perf_counter() - t0)
                cpu_times[(k, s)].append(time.process_time() - c0)
    rows = {}
    for k, steps in built.items():
        rows[k] = {
            s: {
                "us_per_step": 1e6 * min(times[(k, s)]) / args.steps,
                "cpu_us_per_step": 1e6 * min(cpu_times[(k, s)]) / args.steps,
                "compile_s": b["compile_s"],
                "step_cost_one_aircraft": b["step_cost"],
            }
            for s, b in steps.items()
        }
    for k in rows:
        for s in rows[k]:
            r, g = rows[k][s], rows["gather"][s]
            r["time_over_gather"] = r["us_per_step"] / g["us_per_step"]
            r["cpu_time_over_gather"] = r["cpu_us_per_step"] / g["cpu_us_per_step"]
        print(f"{k:>18}: " + ", ".join(
            f"{s} {r['us_per_step']:.0f} us/step ({r['time_over_gather']:.2f}x gather; CPU time "
            f"{r['cpu_time_over_gather']:.2f}x; compile {r['compile_s']:.1f} s)" for s, r in rows[k].items()),
            flush=True)  # fmt: skip
    machine = machine_name(args.machine)
    result = {
        **result_header("lookup", machine, args.note, load_before),
        "config": {
            "batch": args.batch,
            "steps_per_call": args.steps,
            "repeats": args.repeats,
            "seed": args.seed,
            "dtype": "float32",
            "devices_used": 1,
        },
        "method": (
            "interleaved best-of-repeats of bench_step.build's plant and SMC step loops per lookup; wall "
            "time and the process's CPU time (time.process_time, less sensitive to other processes on a "
            "shared machine than wall time)"
        ),
        "equality_vs_gather_float64": checks,
        "results": rows,
    }
    name = f"lookup_{machine}_quick.json" if args.quick else f"lookup_{machine}.json"
    print(f"wrote {write_json(args.out_dir, name, result)}")
    return result


if __name__ == "__main__":
    main()
