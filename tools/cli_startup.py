"""Start-up cost of the ``harv-jax`` command line: what importing it costs, and what the heaviest modules add.

Every ``harv-jax`` command, bad input included, pays for the modules ``harv_jax.cli`` imports (the command
modules import at their top). This measures that cost for one or more checkouts side by side, and what the
modules that pull optax add to a checkout that imports them inside its functions::

    python tools/cli_startup.py --out tools/results/house/cli_startup.json --repo DIR [--repo DIR2]

Times are the minimum over ``--repeats`` fresh interpreters (wall, s), the checkouts interleaved; each
``--repo`` root goes first on ``PYTHONPATH`` (the interpreters start in ``/``, so the current folder's
package does not shadow it).
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

#: The modules the commands import inside their functions (they pull optax or matplotlib), by command.
HEAVY = {
    "evaluate": "harv_jax.evaluation.seeds.flow",
    "optimal": "harv_jax.optimal.study",
    "train": "harv_jax.ppo.runner",
    "simulate": "harv_jax.plots.time_histories",
}


def wall_s(code: str, env: dict[str, str], repeats: int) -> float:
    """Minimum wall time of ``python -c code`` over ``repeats`` fresh interpreters, s."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True, env=env, capture_output=True, cwd="/")
        best = min(best, time.perf_counter() - t0)
    return best


def new_modules(module: str, env: dict[str, str]) -> int:
    """Modules ``import module`` adds to those ``import harv_jax.cli`` loaded."""
    code = (
        f"import sys, harv_jax.cli; a = set(sys.modules); import {module}; print(len(set(sys.modules) - a))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], check=True, env=env, capture_output=True, text=True, cwd="/"
    )
    return int(out.stdout.strip())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--repo", type=Path, action="append", required=True, help="a checkout (repeatable)")
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    envs = {str(r): {**os.environ, "PYTHONPATH": str(r.resolve())} for r in args.repo}
    codes = {"cli": "import harv_jax.cli"} | {c: f"import harv_jax.cli, {m}" for c, m in HEAVY.items()}
    best = {(r, c): float("inf") for r in envs for c in codes}
    for _ in range(args.repeats):  # interleaved: a load change hits every checkout and module alike
        for repo, env in envs.items():
            for c, code in codes.items():
                best[repo, c] = min(best[repo, c], wall_s(code, env, 1))
    checkouts = []
    for repo, env in envs.items():
        commit = subprocess.run(
            ["git", "-C", repo, "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        )
        heavy = {
            c: {
                "module": m,
                "new_modules": new_modules(m, env),
                "added_s": round(best[repo, c] - best[repo, "cli"], 3),
            }
            for c, m in HEAVY.items()
        }
        checkouts.append(
            {
                "repo": repo,
                "commit": commit.stdout.strip(),
                "import_harv_jax_cli_s": round(best[repo, "cli"], 3),
                "heavy": heavy,
            }
        )
    doc = {
        "cpu_model": cpu_model(),
        "repeats": args.repeats,
        "bytecode_cache": not os.environ.get("PYTHONDONTWRITEBYTECODE"),  # without it every import compiles
        "checkouts": checkouts,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(json.dumps(doc, indent=1))


if __name__ == "__main__":
    main()
