"""Wall time of the default training command: `harv-jax train --seed S` (the default preset: 5 seeds),
compile, spin bank and per-period evaluation included, as a user runs it.

    python benchmarks/bench_train_default.py --seed 4817 \
        --out benchmarks/results/train_default_xeon-2core.json

Runs the command as a subprocess into a temporary folder, records its wall time, the load average before and
after, the CPU model and each seed's last evaluation (recovered fraction, mean recovery time), and writes one
JSON. Time it on a quiet machine: two cores shared with other jobs stretch it.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import cpu_cores, cpu_model, load_average_1min, write_json  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=4817)
    ap.add_argument("--out", default="benchmarks/results/train_default_cpu-2core.json")
    a = ap.parse_args()
    if a.seed < 0:
        ap.error(f"--seed {a.seed} must be >= 0")
    with tempfile.TemporaryDirectory(prefix="bench_train_") as tmp:
        cmd = [sys.executable, "-m", "harv_jax.cli", "train", "--seed", str(a.seed), "--out", f"{tmp}/run"]
        load0 = load_average_1min()
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            sys.exit(f"training failed (exit {r.returncode}): {r.stderr.strip().splitlines()[-1:]}")
        summary = json.loads(Path(f"{tmp}/run/summary.json").read_text())
    result = {
        "command": "harv-jax train --seed " + str(a.seed),
        "cpu_model": cpu_model(),
        "cpu_cores": cpu_cores(),
        "load_average_1min_before": load0,
        "load_average_1min_after": load_average_1min(),
        "wall_s": wall,
        "env_steps_per_seed": summary["env_steps_per_seed"],
        "seeds": summary.get("seeds"),
    }
    out = Path(a.out)
    write_json(out.parent, out.name, result)
    print(f"{result['command']}: {wall:.0f} s wall on {result['cpu_model']} ({result['cpu_cores']} cores)")


if __name__ == "__main__":
    main()
