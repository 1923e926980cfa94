"""Env throughput: steps/s of the vectorized recovery env vs num_envs, randomization on and off, and the
gymnasium adapter's single-env steps/s in the same run (with the ratio).

    python benchmarks/bench_env.py                       # CPU defaults, JSON to benchmarks/results/
    python benchmarks/bench_env.py --num-envs 1024,16384 --steps 500 --machine h100

Each point jits ``lax.scan`` over ``--steps`` steps of ``vmap(env.step)`` (auto-reset, random actions
in [-1, 1]^3 drawn inside the scan), compiles it once (``lower().compile()``: the timed calls cannot
recompile), runs it once to warm up and then ``--repeats`` times; steps/s = num_envs * steps / best
time. "Randomization off" is ``EnvConfig(domain_randomization=False)`` (none of that code is traced).
The gymnasium part (skipped where gymnasium is absent, e.g. on a bare GPU machine) steps
``HarvRecoveryEnv`` with numpy actions in a Python loop, resetting on termination or truncation.
Results go to ``benchmarks/results/env_<machine>.json``; the machine's load average is recorded, since
a shared CPU makes the numbers noisy.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root, for benchmarks.*

from benchmarks.common import cpu_model, machine_name  # noqa: E402
from harv_jax.env import EnvConfig, default_randomization_params, make_env

RESULTS_DIR = Path(__file__).resolve().parent / "results"
CPU_NUM_ENVS = (1, 16, 256, 1024, 4096)
GPU_NUM_ENVS = (256, 1024, 4096, 16384, 65536)


def bench_vectorized(
    num_envs: int, steps: int, repeats: int, randomization: bool, seed: int, mode: str = "vmap_step"
) -> dict:
    """Steps/s of ``steps`` auto-reset steps of ``num_envs`` envs under one jit.

    ``mode``: "vmap_step" = ``jax.vmap(env.step)``; "batch_step" = ``env.batch_step`` (resets only on
    steps where some env is done).
    """
    env = make_env(EnvConfig(domain_randomization=randomization))
    params = env.default_params()
    if not randomization:
        params = params.replace(randomization=default_randomization_params(enabled=False))
    vreset = jax.vmap(env.reset, in_axes=(0, None))
    vstep = jax.vmap(env.step, in_axes=(0, 0, 0, None)) if mode == "vmap_step" else env.batch_step

    def run(key, state):
        def body(carry, k):
            st, total = carry
            k_act, k_env = jax.random.split(k)
            actions = jax.random.uniform(k_act, (num_envs, 3), minval=-1.0, maxval=1.0)
            _, st, reward, done, _ = vstep(jax.random.split(k_env, num_envs), st, actions, params)
            return (st, total + jnp.sum(reward)), jnp.sum(done)

        (state, total), n_done = jax.lax.scan(body, (state, jnp.zeros(())), jax.random.split(key, steps))
        return state, total, jnp.sum(n_done)

    key = jax.random.key(seed)
    k_reset, key = jax.random.split(key)
    _, state = jax.jit(vreset)(jax.random.split(k_reset, num_envs), params)
    t0 = time.perf_counter()
    compiled = jax.jit(run).lower(key, state).compile()
    compile_s = time.perf_counter() - t0
    state, total, n_done = jax.block_until_ready(compiled(key, state))  # warm-up
    times = []
    finite = bool(jnp.isfinite(total))
    for _ in range(repeats):
        key, k = jax.random.split(key)
        t0 = time.perf_counter()
        state, total, n_done = jax.block_until_ready(compiled(k, state))
        times.append(time.perf_counter() - t0)
        finite &= bool(jnp.isfinite(total))
    best = min(times)
    return {
        "num_envs": num_envs,
        "randomization": randomization,
        "mode": mode,
        "steps_per_call": steps,
        "compile_s": round(compile_s, 3),
        "best_s": round(best, 5),
        "times_s": [round(t, 5) for t in times],
        "steps_per_s": num_envs * steps / best,
        "episodes_ended_last_call": int(n_done),
        "rewards_finite": finite,
    }


def bench_gym(n_steps: int, seed: int) -> dict | None:
    """Single-env steps/s of the gymnasium adapter (None where gymnasium is absent)."""
    try:
        from harv_jax.env.gym_env import HarvRecoveryEnv
    except ImportError:
        return None
    env = HarvRecoveryEnv(EnvConfig(domain_randomization=True))
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    env.reset(seed=seed)
    env.step(np.zeros(3, dtype=np.float32))  # compile
    compile_s = time.perf_counter() - t0
    actions = rng.uniform(-1.0, 1.0, size=(n_steps, 3)).astype(np.float32)
    episodes = 0
    env.reset(seed=seed + 1)
    t0 = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
            episodes += 1
    elapsed = time.perf_counter() - t0
    return {
        "steps": n_steps,
        "compile_s": round(compile_s, 3),
        "elapsed_s": round(elapsed, 4),
        "steps_per_s": n_steps / elapsed,
        "resets": episodes,
    }


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--num-envs", default=None, help="comma-separated env counts (default by device)")
    parser.add_argument("--steps", type=int, default=100, help="env steps per timed call")
    parser.add_argument("--repeats", type=int, default=3, help="timed calls per point (best is kept)")
    parser.add_argument("--gym-steps", type=int, default=2000, help="gymnasium adapter steps")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--with-batch-step", action="store_true", help="also time env.batch_step (randomization on)"
    )
    parser.add_argument("--machine", default=None, help="label in the output name (default: from device)")
    parser.add_argument("--out-dir", type=Path, default=RESULTS_DIR)
    args = parser.parse_args(argv)

    dev = jax.devices()[0]
    if args.num_envs:
        num_envs = tuple(int(v) for v in args.num_envs.split(","))
    else:
        num_envs = CPU_NUM_ENVS if dev.platform == "cpu" else GPU_NUM_ENVS
    machine = machine_name(args.machine)
    load_before = os.getloadavg() if hasattr(os, "getloadavg") else None

    results = []
    for randomization in (True, False):
        for n in num_envs:
            r = bench_vectorized(n, args.steps, args.repeats, randomization, args.seed)
            results.append(r)
            print(
                f"num_envs={n:6d} randomization={'on ' if randomization else 'off'} "
                f"{r['steps_per_s']:12.0f} steps/s  (compile {r['compile_s']:.1f} s)",
                flush=True,
            )
    if args.with_batch_step:
        for n in num_envs:
            r = bench_vectorized(n, args.steps, args.repeats, True, args.seed, mode="batch_step")
            results.append(r)
            print(f"num_envs={n:6d} batch_step        {r['steps_per_s']:12.0f} steps/s", flush=True)
    gym_result = bench_gym(args.gym_steps, args.seed)
    best_on = max(r["steps_per_s"] for r in results if r["randomization"] and r["mode"] == "vmap_step")
    out = {
        "benchmark": "env_steps_per_s",
        "machine": machine,
        "device": {"platform": dev.platform, "kind": dev.device_kind, "count": jax.device_count()},
        "host": {
            "cpu_count": os.cpu_count(),
            "cpu_model": cpu_model(),
            "python": platform.python_version(),
            "node": platform.node(),
        },
        "jax_version": jax.__version__,
        "dtype": str(jnp.result_type(float)),
        "seed": args.seed,
        "load_average_before": load_before,
        "load_average_after": os.getloadavg() if hasattr(os, "getloadavg") else None,
        "vectorized": results,
        "gym_single_env": gym_result,
        "best_vectorized_steps_per_s_randomization_on": best_on,  # vmap(step)
        "ratio_best_vectorized_to_gym": (best_on / gym_result["steps_per_s"]) if gym_result else None,
    }
    if gym_result:
        print(
            f"gymnasium single env {gym_result['steps_per_s']:.0f} steps/s; best vectorized / gym = "
            f"{out['ratio_best_vectorized_to_gym']:.0f}x"
        )
    else:
        print("gymnasium not installed: adapter benchmark skipped")
    args.out_dir.mkdir(parents=True, exist_ok=True)
    path = args.out_dir / f"env_{machine}.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")
    return out


if __name__ == "__main__":
    main()
