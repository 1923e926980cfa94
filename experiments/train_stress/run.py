"""Stress test of training on the CPU: many consecutive runs, each with a time limit.

Usage::

    nice -n 10 python experiments/train_stress/run.py [--runs 30] [--api-runs 0] [--preset smoke] \
        [--seeds 1] [--steps 4096] [--num-envs 16] [--timeout-s 200] [--out results/NAME.json]

Each ``cli`` run is a subprocess ``python -m harv_jax.cli train --preset P --steps S --seeds K
[--num-envs N --minibatches 4] --seed i --out TMP/run_i``, started the way a user starts it. Each ``api``
run (``--api-runs``) is ``api_run.py``: the README's Python-API recipe (``load_preset`` -> ``make_harv_env``
-> ``make_train`` -> ``run_training``) in a fresh interpreter with ``XLA_FLAGS`` removed (jax's defaults).
The arms are interleaved.

A run that has not finished after ``--timeout-s`` (``timed_out``) has the native stacks of all its threads
written with ``gdb -p PID -batch -ex "thread apply all bt"`` (if gdb is installed) next to the JSON, and is
then given up to ``--watchdog-grace-s`` more: it counts as a hang (``hung``) if the training watchdog ends
it (exit code 3) or it is still running then (it is killed); a run that was merely slow finishes in that
time. The JSON records every run (arm, exit code, seconds, timed out, hang, watchdog exit, last stderr line,
periods finished), the totals per arm, the CPU model (/proc/cpuinfo), core count, load average, the jax and
jaxlib versions and the XLA_FLAGS of the parent.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from harv_jax.machine import cpu_model

REPO = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent


def cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def version(pkg: str) -> str:
    try:
        return importlib.metadata.version(pkg)
    except importlib.metadata.PackageNotFoundError:
        return "absent"


def native_stacks(pid: int, path: Path) -> bool:
    """All threads' native stacks of ``pid`` to ``path`` via gdb; False if gdb is missing or fails."""
    gdb = shutil.which("gdb")
    if gdb is None:
        return False
    try:
        r = subprocess.run([gdb, "-p", str(pid), "-batch", "-ex", "thread apply all bt"], capture_output=True,
                           text=True, timeout=120)  # fmt: skip
    except subprocess.TimeoutExpired:
        return False
    path.write_text(r.stdout + r.stderr)
    return r.returncode == 0


def one_run(i: int, arm: str, args: argparse.Namespace, tmp: Path, out_dir: Path) -> dict[str, Any]:
    """Run training ``i`` of ``arm`` ("cli" or "api"); returns its record."""
    run = tmp / f"run_{i:03d}"
    env = dict(os.environ)
    if arm == "cli":
        cmd = [sys.executable, "-m", "harv_jax.cli", "train", "--preset", args.preset]
        cmd += ["--steps", str(args.steps)]
        cmd += ["--seeds", str(args.seeds), "--seed", str(i), "--out", str(run)]
        if args.num_envs:
            cmd += ["--num-envs", str(args.num_envs), "--minibatches", "4"]
    else:
        cmd = [sys.executable, str(HERE / "api_run.py"), args.preset, str(args.steps), str(args.seeds)]
        cmd.append(str(i))
        env.pop("XLA_FLAGS", None)
    t0 = time.monotonic()
    err_path = tmp / f"run_{i:03d}.stderr"
    with open(err_path, "w") as err:
        proc = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=err,
                                start_new_session=True)  # fmt: skip
        timed_out, hung, stacks, watchdog_exit = False, False, None, False
        try:
            rc = proc.wait(timeout=args.timeout_s)
        except subprocess.TimeoutExpired:
            timed_out = True
            stack_file = out_dir / f"{Path(args.out).stem}_hang_{i:03d}_gdb.txt"
            stacks = str(stack_file.relative_to(REPO)) if native_stacks(proc.pid, stack_file) else None
            try:
                rc = proc.wait(timeout=args.watchdog_grace_s)
                watchdog_exit = hung = rc == 3
            except subprocess.TimeoutExpired:
                hung = True
                os.killpg(proc.pid, signal.SIGKILL)
                rc = proc.wait()
    wall = time.monotonic() - t0
    lines = err_path.read_text(errors="replace").strip().splitlines()
    periods = sum(1 for line in lines if line.startswith("period "))  # api_run.py prints one per period
    record = {"run": i, "arm": arm, "seed": i, "returncode": rc, "wall_s": round(wall, 2),
              "timed_out": timed_out, "hung": hung,
              "watchdog_exit": watchdog_exit, "periods_done": periods, "gdb_stacks": stacks,
              "last_stderr_line": lines[-1][:300] if lines else ""}  # fmt: skip
    if rc == 0 and not timed_out:
        shutil.rmtree(run, ignore_errors=True)
        err_path.unlink(missing_ok=True)
    return record


def summarize(records: list[dict[str, Any]]) -> dict[str, Any]:
    walls = sorted(r["wall_s"] for r in records)
    return {
        "runs": len(records),
        "ok": sum(r["returncode"] == 0 and not r["hung"] for r in records),
        "timed_out": sum(r["timed_out"] for r in records),
        "hangs": sum(r["hung"] for r in records),
        "watchdog_exits": sum(r["watchdog_exit"] for r in records),
        "other_failures": sum(r["returncode"] != 0 and not r["hung"] for r in records),
        "wall_s_min": walls[0] if walls else None,
        "wall_s_median": walls[len(walls) // 2] if walls else None,
        "wall_s_max": walls[-1] if walls else None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=30, help="runs of harv-jax train")
    ap.add_argument("--api-runs", type=int, default=0, help="interleaved runs through the Python API")
    ap.add_argument("--preset", default="smoke", help="preset name or .toml path")
    ap.add_argument("--seeds", type=int, default=1, help="training seeds per run")
    ap.add_argument("--steps", type=int, default=4096)
    ap.add_argument("--num-envs", type=int, default=16, help="0: the preset's (cli arm only)")
    ap.add_argument("--timeout-s", type=float, default=200.0, help="a run longer than this is a hang")
    ap.add_argument("--watchdog-grace-s", type=float, default=240.0,
                    help="after a hang, wait this long for the watchdog (exit 3) before SIGKILL")  # fmt: skip
    ap.add_argument("--out", default="experiments/train_stress/results/stress_train_cpu-2core.json")
    args = ap.parse_args()
    for name, low in (("runs", 0), ("api_runs", 0), ("seeds", 1), ("steps", 1), ("num_envs", 0)):
        if getattr(args, name) < low:
            ap.error(f"--{name.replace('_', '-')} {getattr(args, name)} must be an integer >= {low}")
    if not args.timeout_s > 0 or not args.watchdog_grace_s >= 0:
        ap.error("--timeout-s must be > 0 and --watchdog-grace-s >= 0")
    out = (REPO / args.out) if not Path(args.out).is_absolute() else Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    # interleave: one api run after every runs/api_runs cli runs
    arms = ["cli"] * args.runs
    for k in range(args.api_runs):
        arms.insert(round((k + 1) * len(arms) / (args.api_runs + 1)), "api")
    started = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    load_start = os.getloadavg()
    records = []
    with tempfile.TemporaryDirectory(prefix="stress_train_") as tmp:
        for i, arm in enumerate(arms):
            rec = one_run(i, arm, args, Path(tmp), out.parent)
            records.append(rec)
            print(json.dumps(rec), flush=True)
            if rec["timed_out"] or rec["returncode"] != 0:  # keep what a failed or slow run left
                keep = out.parent / f"{out.stem}_run_{i:03d}.stderr"
                src = Path(tmp) / f"run_{i:03d}.stderr"
                if src.is_file():
                    keep.write_text(src.read_text(errors="replace")[-20000:])
    result = {
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
        "started_utc": started,
        "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "cpu_model": cpu_model(),
        "cpu_cores": cores(),
        "loadavg_start": load_start,
        "loadavg_end": os.getloadavg(),
        "python": platform.python_version(),
        "jax": version("jax"),
        "jaxlib": version("jaxlib"),
        "parent_xla_flags": os.environ.get("XLA_FLAGS", ""),
        "settings": {
            "preset": args.preset,
            "seeds": args.seeds,
            "steps": args.steps,
            "num_envs": args.num_envs or "preset",
            "timeout_s": args.timeout_s,
            "watchdog_grace_s": args.watchdog_grace_s,
        },
        "arms": {
            "cli": "harv-jax train as shipped",
            "api": "the README's Python-API recipe (api_run.py), XLA_FLAGS unset: jax's defaults",
        },
        "summary": {arm: summarize([r for r in records if r["arm"] == arm]) for arm in sorted(set(arms))},
        "records": records,
    }
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result["summary"], indent=2))


if __name__ == "__main__":
    main()
