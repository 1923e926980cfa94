"""The cause of the CPU training deadlock, reproduced without harv_jax: batched QR factorizations that run
at the same time on XLA:CPU's intra-op thread pool.

    python experiments/train_stress/qr_deadlock.py [--attempts 5] [--timeout-s 30] [--out FILE.json]

Each attempt is a fresh interpreter (jax's defaults) that calls, 300 times, one jitted program holding six
independent QR factorizations of a [B, 64, 64] batch. ``batched`` (B = 3) is what a vmapped orthogonal
initialiser of six layers compiles to; ``one_at_a_time`` (B = 1) is the same work one matrix per call.
jaxlib's LAPACK kernel splits a batch whose cost passes a threshold into tasks on the intra-op pool and
blocks the calling pool worker until they are done; XLA runs independent factorizations on different
workers, so once every worker (2 on a 2-core machine) waits that way no worker is left to run the tasks.
An attempt that outlives ``--timeout-s`` counts as hung (its stacks: every ``tf_XLAEigen`` worker in
``lapack_sgeqrf_ffi -> ParallelBatchMap -> BlockingCounter::Wait``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from harv_jax.machine import cpu_model

PROGRAM = """
import sys
import jax, jax.numpy as jnp
B = int(sys.argv[1])

@jax.jit
def qrs(key):
    return [jnp.linalg.qr(jax.random.normal(k, (B, 64, 64)))[0] for k in jax.random.split(key, 6)]

for i in range(300):
    jax.block_until_ready(qrs(jax.random.key(i)))
"""


def attempt(batch: int, timeout_s: float) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    t0 = time.monotonic()
    try:
        r = subprocess.run([sys.executable, "-c", PROGRAM, str(batch)], env=env, capture_output=True,
                           timeout=timeout_s)  # fmt: skip
        return {"hung": False, "returncode": r.returncode, "wall_s": round(time.monotonic() - t0, 2)}
    except subprocess.TimeoutExpired:
        return {"hung": True, "returncode": None, "wall_s": round(time.monotonic() - t0, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--attempts", type=int, default=5)
    ap.add_argument("--timeout-s", type=float, default=30.0)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "qr_deadlock_cpu-2core.json"))
    args = ap.parse_args()
    if args.attempts < 1 or not args.timeout_s > 0:
        ap.error("--attempts must be >= 1 and --timeout-s > 0")
    import jax

    arms = {"batched": 3, "one_at_a_time": 1}
    records = {name: [attempt(b, args.timeout_s) for _ in range(args.attempts)] for name, b in arms.items()}
    result = {
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
        "cpu_model": cpu_model(),
        "cpu_cores": len(os.sched_getaffinity(0)),
        "jax": jax.__version__,
        "xla_flags": "unset",
        "arms": {
            name: f"6 independent QRs of [{b}, 64, 64] per program, 300 calls" for name, b in arms.items()
        },
        "summary": {
            name: {"attempts": len(r), "hung": sum(x["hung"] for x in r)} for name, r in records.items()
        },
        "records": records,
    }
    Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result["summary"]))


if __name__ == "__main__":
    main()
