"""RL-only and hybrid Monte Carlo of every seed of a set of training runs (mean +- std over seeds).

    python experiments/paper_reproduction/seed_eval.py --runs 256 \
        --out experiments/paper_reproduction/results/seed_eval.json
    python experiments/paper_reproduction/seed_eval.py \
        --runs-dir experiments/paper_reproduction/results/runs/cpu-2core --presets paper-partial \
        --out experiments/paper_reproduction/results/seed_eval_cpu.json

Policies: RUNS_DIR/{preset}/policy/policy_seed{0,1,...}.npz. Same initial states (paper reset bounds, seed 0,
nominal aircraft, alpha_d 0.349 rad, 60 s) for every policy and for the SMC-only baseline; the hybrid is the
default one (continuous zeta, tight tube, zeta floor 0.2).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.hybrid.law import HybridConfig, make_hybrid
from harv_jax.control.rl import make_rl_controller
from harv_jax.control.smc import make_smc
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.evaluation.summary import summarize_controller
from harv_jax.policy import load

RUNS_DIR = Path(__file__).resolve().parent / "results" / "runs" / "gpu-h100"
METRICS = {
    "recovery_rate": ("recovery_rate",),
    "alpha_err_deg": ("terminal_error_deg", "alpha", "mean"),
    "beta_err_deg": ("terminal_error_deg", "beta", "mean"),
    "mu_err_deg": ("terminal_error_deg", "mu", "mean"),
    "alpha_within_2": ("terminal_error_deg", "alpha", "within_2"),
    "control_tv_rad": ("control_tv", "mean"),
    "tv_elevator_rad": ("control_tv", "by_channel", "elevator"),
    "tv_aileron_rad": ("control_tv", "by_channel", "aileron"),
    "tv_rudder_rad": ("control_tv", "by_channel", "rudder"),
    "chatter_rad2": ("chatter_index", "mean"),
    "t_recover_p50_s": ("recovery_time_s", "p50"),
    "alpha_settled": ("alpha_recovery_time_s", "fraction"),
    "t_alpha_p50_s": ("alpha_recovery_time_s", "p50"),
}


N_STEPS = 6000  # 60 s at dt 0.01 s


def pick(d: dict, path: tuple[str, ...]):
    for k in path:
        d = d[k]
    return d


def evaluate(label: str, ctrl, inputs, ref) -> dict:
    """One Monte Carlo of ``ctrl``: the METRICS row (printed with 4 significant digits)."""
    out, wall = run_mc(ctrl, inputs, ref, N_STEPS, 0.01, 10, 256)
    summ = summarize_controller(out, wall, N_STEPS)
    row = {k: pick(summ, p) for k, p in METRICS.items()}
    print(label, {k: (float(f"{v:.4g}") if isinstance(v, float) else v) for k, v in row.items()}, flush=True)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=256)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--runs-dir", type=Path, default=RUNS_DIR, help="folder with one run folder per preset")
    ap.add_argument("--presets", default="paper-partial,paper-full", help="comma-separated run folders")
    args = ap.parse_args()
    if args.out.exists():
        raise SystemExit(f"{args.out} exists; remove it first")
    inputs = sample_mc_inputs(jax.random.key(args.seed), args.runs, harv(), randomize=False)
    ref = jnp.array([0.349, 0.0, 0.0])
    res: dict = {"runs": args.runs, "seed": args.seed, "runs_dir": str(args.runs_dir), "policies": {},
                 "over_seeds": {}}  # fmt: skip
    res["smc"] = evaluate("smc", make_smc(), inputs, ref)
    for preset in args.presets.split(","):
        files = sorted((args.runs_dir / preset / "policy").glob("policy_seed*.npz"))
        seeds = [int(f.stem.removeprefix("policy_seed")) for f in files]
        for s, f in zip(seeds, files, strict=True):
            act = load(f).deterministic
            for name, ctrl in (
                ("rl", make_rl_controller(act)),
                ("hybrid", make_hybrid(act, HybridConfig("continuous"))),
            ):
                key = f"{preset}/seed{s}/{name}"
                res["policies"][key] = evaluate(key, ctrl, inputs, ref)
        for name in ("rl", "hybrid"):
            agg = {}
            for k in METRICS:
                v = [res["policies"][f"{preset}/seed{s}/{name}"][k] for s in seeds]
                v = np.array([np.nan if x is None else x for x in v], float)
                agg[k] = {"mean": float(np.nanmean(v)) if np.isfinite(v).any() else None,
                          "std": float(np.nanstd(v)) if np.isfinite(v).any() else None}  # fmt: skip
            res["over_seeds"][f"{preset}/{name}"] = agg
    args.out.write_text(json.dumps(res, indent=2) + "\n")


if __name__ == "__main__":
    main()
