"""Time to a recovering policy: wall clock from `harv-jax train --preset recovery --seeds 3` to the first
evaluated period whose policies ALL recover >= 99% RL-only in the 1000-run Monte Carlo.

    python benchmarks/bench_time_to_policy.py                  # 3 seeds, base seed 0
    python benchmarks/bench_time_to_policy.py --seed 200 --out /tmp/ttp.json

The training command runs as a subprocess exactly as a user runs it; it keeps every evaluated period's
policies (``policy/period_<N>/``). The wall time of a period is the modification time of its policy files
minus the command's start (so it includes start-up, the spin bank and compilation). Afterwards, outside the
timed span, each period's policies fly the Monte Carlo (``harv-jax mc`` sampling: seed ``--mc-seed``, nominal
aircraft, alpha_d 0.349 rad, 60 s) in order, starting at the first period whose training evaluation already
recovered everything, until one passes for every seed. In the same run the SMC's Monte Carlo on the same
1000 runs is timed (compile and run), for scale. Writes one JSON (CPU model, jax version, load average).
"""

from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import cpu_cores, cpu_model, load_average_1min, write_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def mc(controller, runs: int, seed: int) -> dict:
    """Monte Carlo of one controller (nominal aircraft): recovery rate, median time, TV, wall times."""
    import jax
    import jax.numpy as jnp

    from harv_jax.aircraft import harv
    from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
    from harv_jax.evaluation.summary import summarize_controller
    from harv_jax.task.spec import ALPHA_TARGET_RAD as DEFAULT_ALPHA_TARGET_RAD

    inputs = sample_mc_inputs(jax.random.key(seed), runs, harv())
    ref = jnp.asarray([DEFAULT_ALPHA_TARGET_RAD, 0.0, 0.0])
    out, wall = run_mc(controller, inputs, ref, 6000, 0.01, 10, 250)
    s = summarize_controller(out, wall, 6000)
    return {"recovery_rate": s["recovery_rate"], "t_recover_p50_s": s["recovery_time_s"]["p50"],
            "control_tv_rad": s["control_tv"]["mean"], "compile_s": wall["compile"],
            "run_s": wall["run"]}  # fmt: skip


def mc_rl(policy_path: Path, runs: int, seed: int) -> dict:
    """RL-only Monte Carlo of one policy file."""
    from harv_jax.control.rl import make_rl_controller
    from harv_jax.policy import load

    return mc(make_rl_controller(load(policy_path).deterministic), runs, seed)


def mc_smc(runs: int, seed: int) -> dict:
    """The SMC's Monte Carlo on the same runs (timed)."""
    from harv_jax.control.smc import make_smc

    return mc(make_smc(), runs, seed)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--preset", default="recovery")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mc-runs", type=int, default=1000)
    ap.add_argument("--mc-seed", type=int, default=0)
    ap.add_argument("--target", type=float, default=0.99)
    ap.add_argument("--run-dir", type=Path, default=Path("/tmp/harv_jax_time_to_policy"))
    ap.add_argument(
        "--out", type=Path, default=ROOT / "benchmarks" / "results" / "time_to_policy_cpu-2core.json"
    )
    ap.add_argument("--train-arg", action="append", default=[], help="extra argument for harv-jax train")
    args = ap.parse_args()

    load0 = load_average_1min()
    cmd = [sys.executable, "-m", "harv_jax.cli", "train", "--preset", args.preset, "--seeds", str(args.seeds),
           "--seed", str(args.seed), "--out", str(args.run_dir), "--force", *args.train_arg]  # fmt: skip
    t_start = time.time()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    t_train = time.time() - t_start
    if proc.returncode:
        raise SystemExit(f"training failed ({proc.returncode}): {proc.stderr[-2000:]}")
    rows = list(csv.DictReader((args.run_dir / "metrics.csv").open()))
    evals = {int(r["period"]): r for r in rows if r.get("eval/recovered")}
    periods = sorted(int(p.name.split("_")[1]) for p in (args.run_dir / "policy").glob("period_*"))
    first_clean = next((p for p in periods if float(evals[p]["eval/recovered"]) >= 1.0), None)
    checked, reached = [], None
    for p in periods:
        if first_clean is None or p < first_clean:
            continue
        pdir = args.run_dir / "policy" / f"period_{p:04d}"
        files = [pdir / f"policy_seed{s}.npz" for s in range(args.seeds)]
        t_p = max(f.stat().st_mtime for f in files) - t_start
        per_seed = [mc_rl(f, args.mc_runs, args.mc_seed) for f in files]
        checked.append({"period": p, "env_steps_per_seed": int(evals[p]["env_steps"]), "wall_s": t_p,
                        "seeds": per_seed})  # fmt: skip
        print(json.dumps(checked[-1]), flush=True)
        if all(r["recovery_rate"] >= args.target for r in per_seed):
            reached = checked[-1]
            break
    smc = mc_smc(args.mc_runs, args.mc_seed)
    result = {
        "benchmark": "time_to_policy",
        "command": " ".join(["harv-jax", *cmd[3:]]),
        "target_recovery": args.target,
        "mc_runs": args.mc_runs,
        "mc_seed": args.mc_seed,
        "train_total_wall_s": t_train,
        "time_to_policy_s": None if reached is None else reached["wall_s"],
        "reached": reached,
        "checked_periods": checked,
        "training_eval_by_period": {
            p: {k: float(v) for k, v in r.items() if k.startswith("eval/") and v} for p, r in evals.items()
        },  # fmt: skip
        "smc_mc": smc,
        "cpu_cores": cpu_cores(),
        "cpu_model": cpu_model(),
        "jax_version": __import__("jax").__version__,
        "load_average_1min_start": load0,
        "load_average_1min_end": load_average_1min(),
        "train_stdout_tail": proc.stdout[-1500:],
    }
    write_json(args.out.parent, args.out.name, result)
    print(f"time to policy: {result['time_to_policy_s']} s; training {t_train:.0f} s; SMC MC {smc}")


if __name__ == "__main__":
    main()
