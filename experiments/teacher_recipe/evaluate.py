"""Evaluate every seed of a training run against the SMC and the braking SMCs, on the criteria a user
compares by: recovered share, mean recovery time (not-recovered runs at 60 s), paired shares of runs
slower / faster than the SMC by more than 1 s, p95, control TV, and the 30 s developed spin.

    python experiments/teacher_recipe/evaluate.py RUN_DIR [RUN_DIR ...] --mc-seed 11 --out results/eval.json

For each run folder, each ``policy/policy_seed<i>.npz`` flies RL-only (``rl``) and in the default hybrid
(``hybrid``, simplex schedule) on the 1000-run Monte Carlo of ``harv-jax mc`` (``--runs``, nominal aircraft
and ``--randomize``), with the SMC and the braking SMCs (``smc-brake``, ``smc-brake-zoom``) on the same
runs (common random numbers), and on the 30 s spin of ``harv-jax compare``.
Writes JSON (every seed, IQM with a 95% bootstrap CI over seeds, which seeds pass each criterion)
and prints one table row per policy.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.evaluation.flight import fly
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.evaluation.montecarlo.paired import mean_nr_at_run_s, paired_vs_reference, times_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.evaluation.seed_stats import iqm_ci
from harv_jax.machine import cpu_model
from harv_jax.task.spec import ALPHA_TARGET_RAD

DURATION_S = 60.0
KNOWN_AIRCRAFT = DisturbanceSpec(model_error=1.0, controller_knows_aircraft=True)
N_STEPS = 6000
REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
#: The model-based controllers every policy is compared with, the SMC first.
BASELINES = ("smc", "smc-brake", "smc-brake-zoom")


def _key(name: str) -> str:
    """A controller name as a JSON key (``smc-brake-zoom`` -> ``smc_brake_zoom``)."""
    return name.replace("-", "_")


def mc_block(name: str, options: ControllerOptions, inputs: Any) -> dict[str, Any]:
    """One controller on the Monte Carlo: per-run times (NaN: not recovered), recovered flags, TV."""
    out, wall = run_mc(build_controller(name, options), inputs, REF, N_STEPS)
    m = out.metrics
    rec = np.asarray(m.recovered, bool)
    t = np.where(rec, np.asarray(m.t_recover_s, np.float64), np.nan)
    return {"t": t, "rec": rec, "tv": np.asarray(m.control_tv_rad, np.float64).sum(-1), "wall": wall}


def score(block: dict[str, Any], smc: dict[str, Any]) -> dict[str, Any]:
    """Summary numbers of one controller on the Monte Carlo, paired against the SMC's block."""
    t_nr = times_nr_at_run_s(block["t"], block["rec"], DURATION_S)
    vs = paired_vs_reference(block["t"], block["rec"], smc["t"], smc["rec"], DURATION_S)
    return {
        "recovered": float(block["rec"].mean()),
        "t_mean_nr_s": mean_nr_at_run_s(block["t"], block["rec"], DURATION_S),
        "t_median_nr_s": float(np.median(t_nr)),
        "t_p95_nr_s": float(np.percentile(t_nr, 95)),
        "tv_mean_rad": float(block["tv"].mean()),
        "mean_over_smc": vs["mean_ratio"],
        "slower_than_smc_by_1s": vs["slower_fraction"],
        "faster_than_smc_by_1s": vs["faster_fraction"],
    }


def spin_time(name: str, policy: str | None) -> float | None:
    res = fly("spin", ALPHA_TARGET_RAD, DURATION_S, 0, controller=name, policy=policy)
    t = res.metrics.get("t_recover_s")
    return float(t) if res.metrics.get("recovered") and t is not None else None


def criteria(
    rl: dict, rl_rand: dict, hyb: dict, smc: dict, spin_rl: float | None, spin_smc: float | None
) -> dict:
    """The reliable-recipe bars for one policy (RL-only nominal and randomized, hybrid nominal)."""
    return {
        "rl_recovered_ge_99.5": rl["recovered"] >= 0.995 and rl_rand["recovered"] >= 0.995,
        "rl_mean_le_0.8_smc": rl["mean_over_smc"] <= 0.8,
        "rl_slower_le_20pct": rl["slower_than_smc_by_1s"] <= 0.20,
        "rl_p95_le_smc": rl["t_p95_nr_s"] <= smc["t_p95_nr_s"],
        "rl_tv_le_smc": rl["tv_mean_rad"] <= smc["tv_mean_rad"],
        "spin_no_slower_than_smc": spin_rl is not None and (spin_smc is None or spin_rl <= spin_smc),
        "hybrid_recovered_ge_99.9": hyb["recovered"] >= 0.999,
        "hybrid_mean_le_0.8_smc": hyb["mean_over_smc"] <= 0.8,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="training run folders")
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--n", type=int, default=1000, help="Monte Carlo runs")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    t0 = time.perf_counter()
    nominal = harv()
    key = jax.random.key(a.mc_seed)
    inputs = {
        "nominal": sample_mc_inputs(key, a.n, nominal),
        # the randomized aircraft with the SMCs built on each run's own aircraft (as measured; the Monte
        # Carlo's --randomize builds them on the nominal one, --controller-knows-aircraft on the run's)
        "randomized": sample_mc_inputs(key, a.n, nominal, disturbances=KNOWN_AIRCRAFT),
    }
    base = {c: {k: mc_block(c, ControllerOptions(), v) for k, v in inputs.items()} for c in BASELINES}
    scores = {c: {k: score(base[c][k], base["smc"][k]) for k in inputs} for c in BASELINES}
    spins = {c: spin_time(c, None) for c in BASELINES}
    for c in BASELINES:
        print(f"{c} {scores[c]['nominal']} spin {spins[c]}", flush=True)
    smc, spin_smc = scores["smc"], spins["smc"]
    policies = []
    for run in a.runs:
        for path in sorted((run / "policy").glob("policy_seed*.npz"), key=lambda p: int(p.stem[11:])):
            opts = ControllerOptions(policy=str(path))
            rl = {k: score(mc_block("rl", opts, v), base["smc"][k]) for k, v in inputs.items()}
            hyb = score(mc_block("hybrid", opts, inputs["nominal"]), base["smc"]["nominal"])
            spin_rl, spin_hyb = spin_time("rl", str(path)), spin_time("hybrid", str(path))
            row = {
                "policy": str(path),
                "rl": rl,
                "hybrid": hyb,
                "spin_rl_s": spin_rl,
                "spin_hybrid_s": spin_hyb,
            }
            row["criteria"] = criteria(
                rl["nominal"], rl["randomized"], hyb, smc["nominal"], spin_rl, spin_smc
            )
            row["all_criteria"] = all(row["criteria"].values())
            policies.append(row)
            r = rl["nominal"]
            line = f"{path}: rl {r['recovered']:.3f} mean/smc {r['mean_over_smc']:.3f}"
            line += f" slower {r['slower_than_smc_by_1s']:.3f} p95 {r['t_p95_nr_s']:.1f}"
            line += f" tv {r['tv_mean_rad']:.2f}"
            line += f" rand {rl['randomized']['recovered']:.3f} | hybrid {hyb['recovered']:.3f}"
            line += f" {hyb['mean_over_smc']:.3f} | spin {spin_rl} / {spin_hyb}"
            print(line + f" | pass {sum(row['criteria'].values())}/{len(row['criteria'])}", flush=True)
    getters = {
        "rl_recovered": lambda p: p["rl"]["nominal"]["recovered"],
        "rl_recovered_randomized": lambda p: p["rl"]["randomized"]["recovered"],
        "rl_mean_over_smc": lambda p: p["rl"]["nominal"]["mean_over_smc"],
    }
    for c in BASELINES[1:]:
        t_brake_s = scores[c]["nominal"]["t_mean_nr_s"]
        getters[f"rl_mean_over_{_key(c)}"] = lambda p, t=t_brake_s: p["rl"]["nominal"]["t_mean_nr_s"] / t
    getters["rl_slower_than_smc_by_1s"] = lambda p: p["rl"]["nominal"]["slower_than_smc_by_1s"]
    getters["rl_tv_mean_rad"] = lambda p: p["rl"]["nominal"]["tv_mean_rad"]
    getters["hybrid_mean_over_smc"] = lambda p: p["hybrid"]["mean_over_smc"]
    over = {}
    for label, get in getters.items():
        over[label] = {"per_seed": [get(p) for p in policies], **iqm_ci([get(p) for p in policies])}
    result = {
        "command": " ".join(["python", *os.sys.argv]),
        "cpu_model": cpu_model(),
        "mc_seed": a.mc_seed,
        "runs": a.n,
        "duration_s": DURATION_S,
        "smc": smc,
        "spin_smc_s": spin_smc,
        **{_key(c): scores[c] for c in BASELINES[1:]},
        **{f"spin_{_key(c)}_s": spins[c] for c in BASELINES[1:]},
        "policies": policies,
        "over_seeds": over,
        "seeds_passing_all": sum(p["all_criteria"] for p in policies),
        "wall_s": time.perf_counter() - t0,
    }
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({k: (v["iqm"], v["ci_low"], v["ci_high"]) for k, v in over.items()}, indent=1))


if __name__ == "__main__":
    main()
