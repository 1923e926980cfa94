"""Print the tables of experiments/optimal/README.md from the committed results (summary.json files).

Usage: ``python experiments/optimal/table.py`` (reads results/mc256/ and results/spin/summary.json).
"""

from __future__ import annotations

import json
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main() -> None:
    mc = json.loads((HERE / "results/mc256/summary.json").read_text())
    o = mc["optimal"]
    print(f"Monte Carlo: {mc['runs']} runs, seed {mc['seed']}")
    print(f"recovered {o['recovered_fraction']:.1%}, never slower than the best controller: "
          f"{o['never_slower_than_best']}, faster on {o['strictly_faster_fraction']:.1%}")  # fmt: skip
    print("\n| controller | median time (s) | p95 (s) | time / optimal, median | p95 |")
    print("|---|---:|---:|---:|---:|")
    for name, r in o["ratio_to_optimal"].items():
        t = o["recovery_time_s"][name]
        print(f"| {name} | {t['median']:.2f} | {t['p95']:.2f} | {r['median']:.3f} | {r['p95']:.3f} |")
    t = o["recovery_time_s"]["optimal"]
    print(f"| optimal | {t['median']:.2f} | {t['p95']:.2f} | 1 | 1 |")
    print("\nsources:", o["source_counts"], " best controller:", o["best_controller_counts"])
    print("wall (s):", {k: round(v, 1) for k, v in o["wall_time_s"].items()})
    spin_path = HERE / "results/spin/summary.json"
    if spin_path.exists():
        spin = json.loads(spin_path.read_text())
        print("\nspin: recovery time after engagement (s):",
              {k: round(v["median"], 2) for k, v in spin["optimal"]["recovery_time_s"].items()},
              "source:", spin["optimal"]["source_counts"])  # fmt: skip


if __name__ == "__main__":
    main()
