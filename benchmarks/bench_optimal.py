"""Wall time of ``harv-jax optimal`` on the standard Monte Carlo: baselines, search, re-simulation.

Usage::

    python benchmarks/bench_optimal.py --runs 256 --seed 2027 --study-dir experiments/optimal/results/mc256
    python benchmarks/bench_optimal.py --quick          # 8 runs, 2 steps: a sanity run of the script

What is timed: ``harv_jax.optimal.study.optimal_study`` exactly as the command calls it (the four registry
controllers flown on every run, the warm start, the vmapped search with its re-simulations, the final
re-simulation and acceptance), then the command's files written to ``--study-dir`` (if given). Everything is
one process and includes every compile (each phase compiles once); ``wall_s`` splits it by phase. On a CPU,
like the CLI, one XLA host device is created per core, and the runs are sharded over them. The target is
256 runs in <= 15 minutes on the 2-core CPU; the load average before and after is recorded (the machine may
be shared). Results go to ``benchmarks/results/optimal_<machine>.json`` (``_quick`` with ``--quick``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root, for benchmarks.*

from benchmarks.common import (  # noqa: E402
    cpu_cores,
    load_average_1min,
    machine_name,
    result_header,
    set_host_devices,
    write_json,
)

#: The time budget for 256 runs on the 2-core CPU, s.
TARGET_S = 15 * 60


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=256)
    ap.add_argument("--seed", type=int, default=2027)
    ap.add_argument("--iterations", type=int, default=None, help="default: the command's")
    ap.add_argument("--quick", action="store_true", help="8 runs, 2 gradient steps")
    ap.add_argument("--study-dir", type=Path, default=None, help="also write the command's files here")
    ap.add_argument("--host-devices", type=int, default=cpu_cores())
    ap.add_argument("--machine", default=None)
    ap.add_argument("--out-dir", type=Path, default=Path(__file__).resolve().parent / "results")
    args = ap.parse_args()
    set_host_devices(args.host_devices)
    load_before = load_average_1min()

    from harv_jax.optimal.outputs import build_summary, write_optimal
    from harv_jax.optimal.search import SearchConfig, rounds_for
    from harv_jax.optimal.study import mc_scenario, optimal_study
    from harv_jax.report.optimal_section import optimal_markdown
    from harv_jax.task.spec import ALPHA_TARGET_RAD

    runs = 8 if args.quick else args.runs
    iterations = 2 if args.quick else (args.iterations or SearchConfig().iterations)
    cfg = SearchConfig(iterations=iterations, rounds=rounds_for(iterations))
    command = "python benchmarks/bench_optimal.py " + " ".join(sys.argv[1:])
    t0 = time.perf_counter()
    study = optimal_study(mc_scenario(args.seed, runs), ALPHA_TARGET_RAD, cfg, progress=print)
    wall_total = time.perf_counter() - t0
    summary = build_summary(study, cfg, ALPHA_TARGET_RAD, args.seed, command, "mc")
    if args.study_dir is not None:
        args.study_dir.mkdir(parents=True, exist_ok=True)
        write_optimal(args.study_dir, study, summary, cfg)
        (args.study_dir / "optimal_report.md").write_text(optimal_markdown(summary))
    machine = machine_name(args.machine)
    o = summary["optimal"]
    result = {
        **result_header("optimal", machine, "harv-jax optimal's study, all compiles included", load_before),
        "command": command,
        "runs": runs,
        "seed": args.seed,
        "search": o["search"],
        "wall_s": {"total": wall_total, **o["wall_time_s"]},
        "target_s": TARGET_S if runs == 256 else None,
        "within_target": (wall_total <= TARGET_S) if runs == 256 else None,
        "results": {
            k: o[k]
            for k in (
                "recovered_fraction",
                "never_slower_than_best",
                "strictly_faster_fraction",
                "ratio_to_optimal",
            )
        },  # fmt: skip
    }
    name = f"optimal_{machine}{'_quick' if args.quick else ''}.json"
    print(f"wrote {write_json(args.out_dir, name, result)} (total {wall_total:.0f} s)")


if __name__ == "__main__":
    main()
