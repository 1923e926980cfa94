"""PPO training throughput at the paper's network: env-steps/s, compile time, share of the matmul ceiling.

Usage::

    python benchmarks/bench_train.py [--num-envs 64,256,1024] [--updates 2] [--machine NAME] [--quick]
    python benchmarks/bench_train.py --host-devices 2    # the envs sharded over 2 XLA host devices

On a CPU the trainer uses one XLA device by default (``ppo.sharding.default_devices``: XLA's intra-op
thread pool is meant to use every core); ``--host-devices N`` shards the envs over N host devices instead
(one seed), to check on a quiet machine whether that uses the cores better (under load, side by side in one
process at 1,024 envs, the two were within 1%). Results go to ``train_<machine>[_quick][_<N>dev].json``.

For each ``num_envs`` it builds the real trainer (``harv_jax.ppo.train.make_train``) on the recovery env
(actor and critic [256, 128] tanh, unroll 32, 4 epochs x 8 minibatches, one seed), measures the compile time
(``lower().compile()`` of the period function) and the best of a few timed calls of one period of
``--updates`` PPO updates (``block_until_ready``), and reports env-steps/s = updates * num_envs * unroll /
time.

FLOPs per env-step are counted analytically for the networks only (dense layers, 2 * in * out per sample):
rollout = actor forward + critic forward on obs and on final_obs; learning = epochs x (actor + critic) x 3
forward-equivalents (forward + backward). Environment arithmetic (RK4, table lookup) is not counted, so the
"fraction of ceiling" is a lower bound on how well the machine is used. The fp32 matmul ceiling is measured
in the same run (best of a few square matmuls at the default precision the trainer uses, and at ``HIGHEST``
for reference).

Optionally (``stable_baselines3`` + torch + gymnasium installed), Stable-Baselines3 PPO with the paper's
settings runs for ``--sb3-steps`` steps in the same process and the ratio is reported; otherwise the JSON
says why it was skipped. ``benchmarks/bench_sb3.py`` is the dedicated side-by-side comparison. Results go to
``benchmarks/results/train_<machine>.json``. Needs only jax, flax, optax, numpy and harv_jax (no brax).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.common import set_host_devices  # noqa: E402


def _host_devices_from_argv(argv: list[str]) -> int:
    """--host-devices N (default 1: the trainer's CPU default, one device using every core), read before jax
    starts."""
    for i, a in enumerate(argv):
        if a == "--host-devices" and i + 1 < len(argv):
            return int(argv[i + 1])
        if a.startswith("--host-devices="):
            return int(a.split("=", 1)[1])
    return 1


HOST_DEVICES = _host_devices_from_argv(sys.argv)
if HOST_DEVICES > 1:
    set_host_devices(HOST_DEVICES)

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks.common import cpu_cores, load_average_1min, machine_name, result_header, write_json  # noqa: E402
from harv_jax.env import EnvConfig, default_params, make_env  # noqa: E402
from harv_jax.env.episode_metrics import harv_episode_metrics  # noqa: E402
from harv_jax.ppo import config as ppo_config  # noqa: E402
from harv_jax.ppo.config import PPOConfig  # noqa: E402
from harv_jax.ppo.train import make_train, seed_keys  # noqa: E402

HIDDEN = (256, 128)
OBS, ACT = 11, 3


def dense_flops(sizes: list[int]) -> int:
    """Forward FLOPs of an MLP with these layer widths (multiply-add = 2 FLOPs; biases and tanh ignored)."""
    return sum(2 * a * b for a, b in zip(sizes[:-1], sizes[1:], strict=True))


def flops_per_env_step(epochs: int) -> dict[str, int]:
    """Analytic network FLOPs per env step of this trainer."""
    actor = dense_flops([OBS, *HIDDEN, ACT])
    critic = dense_flops([OBS, *HIDDEN, 1])
    rollout = actor + 2 * critic  # policy, V(obs), V(final_obs)
    learn = epochs * 3 * (actor + critic)  # forward + backward ~ 3 forwards
    return {"actor_forward": actor, "critic_forward": critic, "rollout": rollout, "learn": learn,
            "total": rollout + learn}  # fmt: skip


def matmul_ceiling(n: int, repeats: int = 5) -> dict[str, float]:
    """Best fp32 square-matmul FLOP/s at default and HIGHEST precision."""
    out = {}
    a = jax.random.normal(jax.random.key(0), (n, n), jnp.float32)
    b = jax.random.normal(jax.random.key(1), (n, n), jnp.float32)
    for name, prec in (("default", None), ("highest", jax.lax.Precision.HIGHEST)):
        f = jax.jit(lambda x, y, p=prec: jnp.dot(x, y, precision=p))
        f(a, b).block_until_ready()
        best = min(_timed(lambda f=f: f(a, b)) for _ in range(repeats))
        out[name] = 2.0 * n**3 / best
    out["n"] = n
    return out


def _timed(fn) -> float:
    t0 = time.perf_counter()
    jax.block_until_ready(fn())
    return time.perf_counter() - t0


def bench_trainer(env, env_params, num_envs: int, updates: int, repeats: int, unroll: int, epochs: int,
                  minibatches: int) -> dict[str, float]:  # fmt: skip
    """Compile and time one period of ``updates`` PPO updates at ``num_envs``."""
    cfg = PPOConfig(
        total_steps=updates * num_envs * unroll, num_envs=num_envs, unroll=unroll, epochs=epochs,
        minibatches=minibatches, hidden_sizes=HIDDEN, num_periods=1, num_seeds=1,
    )  # fmt: skip
    assert ppo_config.updates_per_period(cfg) == updates
    devices = jax.devices()[:HOST_DEVICES]
    trainer = make_train(env, cfg, env_params, devices=devices, episode_metrics_fn=harv_episode_metrics)
    t0 = time.perf_counter()
    state = trainer.init(seed_keys(jax.random.key(0), 1), env_params)
    jax.block_until_ready(state)
    init_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    compiled = trainer.period.lower(state, env_params).compile()
    compile_s = time.perf_counter() - t0
    state, _ = compiled(state, env_params)  # warm-up
    jax.block_until_ready(state)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        state, metrics = compiled(state, env_params)
        jax.block_until_ready((state, metrics))
        times.append(time.perf_counter() - t0)
    steps = updates * num_envs * unroll
    return {"num_envs": num_envs, "devices_used": len(devices), "updates_per_call": updates,
            "env_steps_per_call": steps,
            "init_s": init_s, "compile_s": compile_s, "best_call_s": min(times),
            "env_steps_per_s": steps / min(times),
            "finite": bool(np.isfinite(float(metrics["total_loss"][0])))}  # fmt: skip


def bench_sb3(steps: int, episode_steps: int) -> dict[str, object]:
    """Stable-Baselines3 PPO (paper settings) on the gymnasium adapter, if what it needs is installed.

    The measurement is :func:`benchmarks.bench_sb3.measure_sb3` (``benchmarks/bench_sb3.py`` is the
    side-by-side benchmark with our trainer at the same env settings).
    """
    from benchmarks.bench_sb3 import missing_requirements

    missing = missing_requirements()
    if missing:
        return {"skipped": f"{', '.join(missing)} not installed"}
    from benchmarks.bench_sb3 import measure_sb3

    return measure_sb3(steps, {"episode_steps": episode_steps, "domain_randomization": False})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--num-envs", default=None, help="comma list (default CPU 64,256,1024; GPU 4096,16384)")
    ap.add_argument("--updates", type=int, default=None, help="PPO updates per timed call (CPU 2, GPU 20)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--unroll", type=int, default=32)
    ap.add_argument("--epochs", type=int, default=4)
    ap.add_argument("--minibatches", type=int, default=8)
    ap.add_argument("--episode-steps", type=int, default=3000)
    ap.add_argument(
        "--no-dr", action="store_true", help="nominal aircraft (default: domain randomization on)"
    )
    ap.add_argument("--matmul-n", type=int, default=None, help="matmul size (CPU 2048, GPU 8192)")
    ap.add_argument("--sb3-steps", type=int, default=4096)
    ap.add_argument("--quick", action="store_true", help="one small num_envs, one repeat (a smoke check)")
    ap.add_argument(
        "--host-devices", type=int, default=1,
        help="CPU: XLA host devices the envs are sharded over (default 1, the trainer's CPU default)",
    )  # fmt: skip
    ap.add_argument("--machine", default=None)
    ap.add_argument("--note", default="", help="free text stored in the JSON (e.g. 'machine shared')")
    ap.add_argument("--out-dir", type=Path, default=Path(__file__).resolve().parent / "results")
    args = ap.parse_args()

    dev = jax.devices()[0]
    gpu = dev.platform != "cpu"
    if args.num_envs:
        sizes = [int(s) for s in args.num_envs.split(",")]
    else:
        sizes = [4096, 16384] if gpu else [64, 256, 1024]
    updates = args.updates or (20 if gpu else 2)
    repeats = args.repeats
    if args.quick:
        sizes, updates, repeats = sizes[:1], 1, 1
    machine = machine_name(args.machine)
    load_before = load_average_1min()
    print(f"device {dev.platform}:{dev.device_kind} x{jax.device_count()}  jax {jax.__version__}", flush=True)

    matmul_n = args.matmul_n or (8192 if gpu else 2048)
    ceiling = matmul_ceiling(matmul_n)
    print(f"fp32 matmul ceiling: {ceiling['default'] / 1e9:,.1f} GFLOP/s (default precision), "
          f"{ceiling['highest'] / 1e9:,.1f} (HIGHEST)", flush=True)  # fmt: skip
    env_cfg = EnvConfig(episode_steps=args.episode_steps, domain_randomization=not args.no_dr)
    env = make_env(env_cfg)
    env_params = default_params(env_cfg)
    flops = flops_per_env_step(args.epochs)
    rows = []
    for n in sizes:
        r = bench_trainer(env, env_params, n, updates, repeats, args.unroll, args.epochs, args.minibatches)
        # the ceiling is re-measured next to every timing and the highest value is used (a busy, shared
        # machine otherwise inflates the fraction)
        again = matmul_ceiling(matmul_n)
        ceiling = {k: max(ceiling[k], again[k]) for k in ("default", "highest")} | {"n": matmul_n}
        r["matmul_ceiling_here_flops_per_s"] = again["default"]
        r["network_gflops_per_s"] = flops["total"] * r["env_steps_per_s"] / 1e9
        rows.append(r)
        print(f"  measured num_envs {n}: {r['env_steps_per_s']:,.0f} env-steps/s", flush=True)
    for r in rows:
        r["fraction_of_matmul_ceiling"] = flops["total"] * r["env_steps_per_s"] / ceiling["default"]
        print(f"num_envs {r['num_envs']:>6}: {r['env_steps_per_s']:>12,.0f} env-steps/s  "
              f"compile {r['compile_s']:.1f} s  init {r['init_s']:.1f} s  "
              f"{r['network_gflops_per_s']:.1f} GFLOP/s "
              f"= {100 * r['fraction_of_matmul_ceiling']:.0f}% of the best ceiling "
              f"{ceiling['default'] / 1e9:.1f} GFLOP/s", flush=True)  # fmt: skip
    best = max(rows, key=lambda r: r["env_steps_per_s"])
    sb3 = {"skipped": "--quick"} if args.quick else bench_sb3(args.sb3_steps, args.episode_steps)
    if "env_steps_per_s" in sb3:
        sb3["ratio_best_jax_over_sb3"] = best["env_steps_per_s"] / sb3["env_steps_per_s"]
    print(f"SB3: {sb3}", flush=True)
    result = {
        **result_header("train", machine, args.note, load_before, device_count=jax.device_count()),
        "cpu_affinity": cpu_cores(),
        "config": {
            "hidden_sizes": list(HIDDEN),
            "unroll": args.unroll,
            "epochs": args.epochs,
            "minibatches": args.minibatches,
            "episode_steps": args.episode_steps,
            "domain_randomization": not args.no_dr,
            "num_seeds": 1,
            "host_devices": HOST_DEVICES,
            "dtype": "float32",
        },  # fmt: skip
        "flops_per_env_step": flops,
        "matmul_ceiling_flops_per_s": ceiling,
        "results": rows,
        "best": {
            "num_envs": best["num_envs"],
            "env_steps_per_s": best["env_steps_per_s"],
            "fraction_of_matmul_ceiling": best["fraction_of_matmul_ceiling"],
        },  # fmt: skip
        "sb3": sb3,
    }
    suffix = ("_quick" if args.quick else "") + (f"_{HOST_DEVICES}dev" if HOST_DEVICES > 1 else "")
    path = write_json(args.out_dir, f"train_{machine}{suffix}.json", result)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
