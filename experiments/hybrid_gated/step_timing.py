"""Side-by-side cost of one closed-loop step: SMC vs hybrid (continuous, gated), batch of aircraft.

    python experiments/hybrid_gated/step_timing.py --batch 1000 --steps 200 --repeats 3 --out FILE.json

Each controller flies ``--steps`` plant steps (controller + actuator + RK4) for ``--batch`` aircraft in one
jitted, vmapped ``closed_loop``; the best of ``--repeats`` timed calls after compilation is reported per
aircraft-step. Guidance only (shared CPU): the ratio matters, not the absolute time.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import jax
import jax.numpy as jnp

from harv_jax.aircraft import harv
from harv_jax.control.hybrid.law import HybridConfig, make_hybrid
from harv_jax.control.smc import make_smc
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.montecarlo.rollout import sample_mc_inputs
from harv_jax.policy import resolve_policy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=1000)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--policy", default="shipped:full")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    inputs = sample_mc_inputs(jax.random.key(0), args.batch, harv())
    ref = jnp.array([0.349, 0.0, 0.0])
    act = resolve_policy(args.policy).deterministic
    ctrls = {
        "smc": make_smc(),
        "hybrid_continuous": make_hybrid(act, HybridConfig(schedule="continuous")),
        "hybrid_gated": make_hybrid(act, HybridConfig(schedule="gated")),
    }
    res = {}
    for name, c in ctrls.items():

        def fly(params, x0, c=c):
            r = closed_loop(c, params, x0, ref, jax.random.key(0), args.steps, 0.01)
            return r.x_final_wind

        f = jax.jit(jax.vmap(fly))
        t0 = time.perf_counter()
        jax.block_until_ready(f(inputs.params, inputs.x0_wind))
        compile_s = time.perf_counter() - t0
        best = float("inf")
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            jax.block_until_ready(f(inputs.params, inputs.x0_wind))
            best = min(best, time.perf_counter() - t0)
        res[name] = {
            "compile_s": compile_s,
            "best_s": best,
            "us_per_aircraft_step": 1e6 * best / (args.batch * args.steps),
        }
        print(name, res[name], flush=True)
    for name in ("hybrid_continuous", "hybrid_gated"):
        res[name]["ratio_to_smc"] = res[name]["best_s"] / res["smc"]["best_s"]
    out = {
        "batch": args.batch, "steps": args.steps, "repeats": args.repeats, "policy": args.policy,
        "devices": [str(d) for d in jax.local_devices()], "jax": jax.__version__,
        "machine": platform.processor() or platform.machine(), "results": res,
    }  # fmt: skip
    print(json.dumps({k: v.get("ratio_to_smc") for k, v in res.items()}))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
