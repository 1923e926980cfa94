"""Before/after of one closed-loop step: ``bench_step``'s steps built from two source trees in one process.

Usage::

    git worktree add /tmp/before <commit>
    python benchmarks/ab_step.py --trees /tmp/before,. --kinds smc,hybrid_gated [--repeats 11] [--policy P]

Each tree's ``benchmarks/bench_step.build`` compiles its own plant, controllers and step loops (batch 1000,
50 steps per call, the Monte Carlo's reset states); the compiled loops of both trees are then timed
interleaved, ``--repeats`` times each, and the best time is used, so a slow spell of the machine hits both
trees alike. With ``--copies N`` each tree is built N times (builds alternating between the trees) and the
median over the copies of each copy's best time is used: on a shared virtual machine two executables of
the same code differed by up to ~10% in best time, so one copy per tree cannot resolve changes that small.
Kinds: ``smc``, ``hybrid`` (continuous), and with any of ``hybrid_gated``, ``hybrid_simplex``,
``hybrid_simplex_zero_policy``, ``rl`` the whole gated set; ``dynamics`` adds ``bench_dynamics``' loop
(actuator + RK4 of 4,096 randomized aircraft, ``--steps`` steps per call). Results go to
``benchmarks/results/ab_step_<machine>.json``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=1")

from benchmarks.common import best_us_per_step, load_average_1min, machine_name, result_header, write_json  # noqa: E402

GATED_KINDS = ("hybrid_gated", "hybrid_simplex", "hybrid_simplex_zero_policy", "rl")
#: Aircraft in the ``dynamics`` kind's loop (``bench_dynamics --quick``'s largest batch).
DYNAMICS_BATCH = 4096


def build_tree(tree: Path, kinds: list[str], batch: int, n_steps: int, policy: str | None = None) -> dict:
    """Import ``harv_jax`` and ``benchmarks`` from ``tree`` (dropping any loaded copy) and build its steps."""
    for name in [m for m in sys.modules if m.split(".")[0] in ("harv_jax", "benchmarks")]:
        del sys.modules[name]
    sys.path.insert(0, str(tree))
    try:
        bench_step = importlib.import_module("benchmarks.bench_step")
        if not Path(bench_step.__file__).resolve().is_relative_to(tree):
            raise SystemExit(f"--trees: {tree} has no benchmarks/bench_step.py of its own")
        built = bench_step.build(
            batch,
            n_steps,
            policy,
            0,
            gated=any(k in GATED_KINDS for k in kinds),
            controllers=tuple(k for k in kinds if k in ("smc", "hybrid")),
        )
    finally:
        sys.path.remove(str(tree))
    out = {k: built[k] for k in ["plant", *kinds] if k != "dynamics"}
    if "dynamics" in kinds:
        out["dynamics"] = build_dynamics(tree, n_steps)
    return out


def build_dynamics(tree: Path, n_steps: int, batch: int = DYNAMICS_BATCH) -> dict:
    """``tree``'s ``bench_dynamics`` loop of ``batch`` aircraft, compiled with the loaded modules."""
    import jax.numpy as jnp

    sys.path.insert(0, str(tree))
    try:
        bench_dynamics = importlib.import_module("benchmarks.bench_dynamics")
        if not Path(bench_dynamics.__file__).resolve().is_relative_to(tree):
            raise SystemExit(f"--trees: {tree} has no benchmarks/bench_dynamics.py of its own")
        args = bench_dynamics.make_fleet(0, batch, jnp.float32)
        t0 = time.perf_counter()
        compiled = bench_dynamics.make_fly(n_steps).lower(*args).compile()
        return {"compiled": compiled, "args": args, "compile_s": time.perf_counter() - t0}
    finally:
        sys.path.remove(str(tree))


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trees", required=True, help="two source trees, before,after (e.g. a git worktree,.)")
    ap.add_argument("--kinds", default="smc,hybrid_gated", help="comma list of the steps to time")
    ap.add_argument("--batch", type=int, default=1000)
    ap.add_argument("--steps", type=int, default=50, help="steps per timed call")
    ap.add_argument("--repeats", type=int, default=11)
    ap.add_argument("--copies", type=int, default=1, help="builds per tree (median of their best times)")
    ap.add_argument(
        "--policy", default=None, help="the policy both trees fly (default: each tree's shipped default)"
    )
    ap.add_argument("--machine", default=None)
    ap.add_argument("--note", default="")
    ap.add_argument("--out-dir", type=Path, default=ROOT / "benchmarks" / "results")
    args = ap.parse_args(argv)
    trees = [Path(t).resolve() for t in args.trees.split(",")]
    kinds = [k.strip() for k in args.kinds.split(",") if k.strip()]
    allowed = ("smc", "hybrid", *GATED_KINDS, "dynamics")
    bad = [k for k in kinds if k not in allowed]
    if len(trees) != 2 or bad or "smc" not in kinds:
        ap.error(f"--trees needs two trees and --kinds smc plus any of {', '.join(allowed[1:])} (got {bad})")
    if args.copies < 1:
        ap.error(f"--copies {args.copies}: allowed: an integer >= 1")

    load_before = load_average_1min()
    built = {
        (t, c, k): b
        for c in range(args.copies)
        for t in trees
        for k, b in build_tree(t, kinds, args.batch, args.steps, args.policy).items()
    }
    per_copy = best_us_per_step(built, args.repeats, args.steps)
    us = {
        (t, k): statistics.median(per_copy[(t, c, k)] for c in range(args.copies))
        for t in trees
        for k in ["plant", *kinds]
    }
    rows = {}
    for label, tree in zip(("before", "after"), trees, strict=True):
        rows[label] = {
            "tree": str(tree),
            "us_per_step": {k: us[(tree, k)] for k in ["plant", *kinds]},
            "us_per_step_each_copy": {
                k: [per_copy[(tree, c, k)] for c in range(args.copies)] for k in ["plant", *kinds]
            },
            "compile_s": {k: built[(tree, 0, k)]["compile_s"] for k in ["plant", *kinds]},
            "over_smc": {k: us[(tree, k)] / us[(tree, "smc")] for k in kinds if k not in ("smc", "dynamics")},
        }
        print(label, {k: round(v, 1) for k, v in rows[label]["us_per_step"].items()}, flush=True)
    speedup = {k: us[(trees[0], k)] / us[(trees[1], k)] for k in ["plant", *kinds]}
    print("speed-up after / before:", {k: round(v, 3) for k, v in speedup.items()}, flush=True)
    result = {
        **result_header("ab_step", machine_name(args.machine), args.note, load_before),
        "config": {
            "batch": args.batch,
            "steps_per_call": args.steps,
            "repeats": args.repeats,
            "copies": args.copies,
            "kinds": kinds,
            "policy": args.policy,
        },
        "method": (
            "benchmarks.bench_step.build from each tree in one process (--copies builds each); interleaved "
            "best-of-repeats per build, median over the builds"
        ),
        "results": rows,
        "speedup_after_over_before": speedup,
    }
    path = write_json(args.out_dir, f"ab_step_{machine_name(args.machine)}.json", result)
    print(f"wrote {path}")
    return result


if __name__ == "__main__":
    main()
