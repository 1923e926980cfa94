"""Training throughput of our PPO against the paper's Stable-Baselines3 PPO, side by side on one machine.

Usage (needs torch and stable-baselines3, which the project does not depend on; a separate venv is best)::

    python3 -m venv /work/venv_sb3 && . /work/venv_sb3/bin/activate
    pip install torch==2.13.0 stable-baselines3 && pip install -e ".[gym]"
    python benchmarks/bench_sb3.py [--sb3-steps 40960] [--preset smoke] [--num-envs 128,1024] [--machine NAME]

Without torch, stable-baselines3 or gymnasium it prints why and exits with status 0 (nothing is written).

In one process, on the same environment settings (the preset's ``[env]`` table: smoke = 10 s episodes,
nominal aircraft):

1. **ours**: ``harv_jax.ppo.train.make_train`` with the preset's PPO settings and one seed (and, with
   ``--num-envs``, the same settings at other env counts). The period function is compiled first
   (``lower().compile()``, timed separately), then the best of ``--repeats`` timed calls of one period of
   ``--updates`` PPO updates (``block_until_ready``): env-steps/s = updates * num_envs * unroll / time.
2. **SB3**: ``stable_baselines3.PPO("MlpPolicy")`` with the paper's settings (actor and critic [256, 128]
   tanh, lr 5e-5, gamma 0.99, n_steps 2048, batch 64, 10 epochs, GAE 0.95, clip 0.2, max-grad-norm 0.5,
   value coef 0.5, one env) on the gymnasium adapter ``harv_jax.env.gym_env.HarvRecoveryEnv``:
   ``model.learn(--sb3-steps)`` timed after the adapter's jitted step has been compiled (one reset and step
   before timing). env-steps/s = steps / time, rollouts and gradient steps included. The adapter alone
   (random actions, no learning) is timed too, to show how much of SB3's time is the environment.
3. **ours** again (the same compiled function): a disturbance of the shared machine shows up as a spread
   between the two measurements of ours. The ratio uses the mean of the two.

Results: ``benchmarks/results/sb3_<machine>.json`` (both rates, the ratio, versions, load averages, the
command). Not a test.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import importlib
import os
import platform
import shlex
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

#: The paper's network (actor and critic), and its SB3 settings (SB3 defaults where the paper gives none).
HIDDEN = (256, 128)
SB3_SETTINGS: dict[str, Any] = {
    "learning_rate": 5e-5,
    "gamma": 0.99,
    "n_steps": 2048,
    "batch_size": 64,
    "n_epochs": 10,
    "gae_lambda": 0.95,
    "clip_range": 0.2,
    "ent_coef": 0.0,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
}
INSTALL_HINT = "pip install torch==2.13.0 stable-baselines3 gymnasium (a separate venv is best)"


def missing_requirements() -> list[str]:
    """Names of the modules SB3 training needs that cannot be imported (empty if all are there)."""
    missing = []
    for mod in ("torch", "stable_baselines3", "gymnasium"):
        try:
            importlib.import_module(mod)
        except ImportError:
            missing.append(mod)
    return missing


def _load() -> tuple[float, float, float]:
    return os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3


def measure_sb3(steps: int, env_table: dict[str, Any], seed: int = 0) -> dict[str, Any]:
    """SB3 PPO with the paper's settings for ``steps`` env steps; env-steps/s of training and of the adapter.

    Args:
        steps: env steps of ``model.learn`` (a multiple of n_steps = 2048 gives whole rollouts).
        env_table: EnvConfig fields (a preset's ``[env]`` table).
        seed: SB3 / torch seed.

    Returns:
        Dict with ``env_steps_per_s`` (training), ``adapter_env_steps_per_s`` (stepping only), timings and
        the settings used.
    """
    import numpy as np
    import torch
    from stable_baselines3 import PPO

    from harv_jax.env import EnvConfig
    from harv_jax.env.gym_env import HarvRecoveryEnv

    env = HarvRecoveryEnv(EnvConfig(**env_table))
    # compile the adapter's jitted reset/step outside the timed region, then time the adapter alone
    env.reset(seed=seed)
    env.step(np.zeros(3, np.float32))
    rng = np.random.default_rng(seed)
    n_adapter = min(steps, 4000)
    env.reset(seed=seed)
    t0 = time.perf_counter()
    for _ in range(n_adapter):
        _, _, term, trunc, _ = env.step(rng.uniform(-1.0, 1.0, 3).astype(np.float32))
        if term or trunc:
            env.reset()
    adapter_s = time.perf_counter() - t0

    model = PPO(
        "MlpPolicy", env, **SB3_SETTINGS, seed=seed, device="cpu", verbose=0,
        policy_kwargs={"net_arch": {"pi": list(HIDDEN), "vf": list(HIDDEN)}, "activation_fn": torch.nn.Tanh},
    )  # fmt: skip
    t0 = time.perf_counter()
    model.learn(total_timesteps=steps)
    dt = time.perf_counter() - t0
    done = int(model.num_timesteps)
    return {
        "env_steps": done,
        "seconds": dt,
        "env_steps_per_s": done / dt,
        "gradient_steps": int(model._n_updates) * (SB3_SETTINGS["n_steps"] // SB3_SETTINGS["batch_size"]),
        "adapter_env_steps": n_adapter,
        "adapter_env_steps_per_s": n_adapter / adapter_s,
        "torch_threads": torch.get_num_threads(),
        "settings": {
            **SB3_SETTINGS,
            "policy": "MlpPolicy",
            "net_arch": list(HIDDEN),
            "activation": "tanh",
            "n_envs": 1,
        },  # fmt: skip
    }


def build_ours(cfg: Any, env_table: dict[str, Any], num_envs: int, updates: int) -> dict[str, Any]:
    """Build and compile our trainer for one seed at ``num_envs``; the pieces for :func:`time_ours`."""
    import jax

    from harv_jax.env.episode_metrics import harv_episode_metrics
    from harv_jax.ppo import config as ppo_config
    from harv_jax.ppo.train import make_train, seed_keys
    from harv_jax.training.environment import make_harv_env

    cfg = cfg.replace(num_envs=num_envs, num_seeds=1, num_periods=1,
                      total_steps=updates * num_envs * cfg.unroll)  # fmt: skip
    assert ppo_config.updates_per_period(cfg) == updates
    env, env_params = make_harv_env(env_table)
    trainer = make_train(env, cfg, env_params, devices=jax.devices()[:1],
                         episode_metrics_fn=harv_episode_metrics)  # fmt: skip
    state = trainer.init(seed_keys(jax.random.key(cfg.seed), 1), env_params)
    jax.block_until_ready(state)
    t0 = time.perf_counter()
    compiled = trainer.period.lower(state, env_params).compile()
    compile_s = time.perf_counter() - t0
    state, _ = compiled(state, env_params)  # warm-up
    jax.block_until_ready(state)
    return {"cfg": cfg, "compiled": compiled, "state": state, "env_params": env_params,
            "compile_s": compile_s}  # fmt: skip


def time_ours(built: dict[str, Any], repeats: int) -> dict[str, Any]:
    """Best of ``repeats`` timed periods of the compiled trainer (state carried over, as in training)."""
    import jax

    cfg, compiled, env_params = built["cfg"], built["compiled"], built["env_params"]
    times = []
    state = built["state"]
    for _ in range(repeats):
        t0 = time.perf_counter()
        state, metrics = compiled(state, env_params)
        jax.block_until_ready((state, metrics))
        times.append(time.perf_counter() - t0)
    built["state"] = state
    steps = cfg.total_steps  # = updates * num_envs * unroll: one period
    return {"env_steps_per_call": steps, "call_s": times, "best_call_s": min(times),
            "env_steps_per_s": steps / min(times)}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="smoke", help="PPO and env settings of ours (and env of SB3)")
    ap.add_argument("--num-envs", default=None, help="comma list of num_envs of ours (default: the preset's)")
    ap.add_argument("--updates", type=int, default=6, help="PPO updates per timed call of ours")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sb3-steps", type=int, default=40960, help="env steps of SB3 training (x 2048)")
    ap.add_argument("--machine", default=None)
    ap.add_argument("--note", default="", help="free text stored in the JSON")
    ap.add_argument("--out-dir", type=Path, default=Path(__file__).resolve().parent / "results")
    args = ap.parse_args()

    missing = missing_requirements()
    if missing:
        print(f"bench_sb3: skipped, {', '.join(missing)} not installed ({INSTALL_HINT})")
        return
    import gymnasium
    import jax
    import numpy as np
    import stable_baselines3
    import torch

    from benchmarks.common import cpu_cores, machine_name, write_json
    from harv_jax.ppo import config as ppo_config
    from harv_jax.training.presets import load_preset

    base, env_table = load_preset(args.preset)
    sizes = [int(s) for s in args.num_envs.split(",")] if args.num_envs else [base.num_envs]
    machine = machine_name(args.machine)
    load_start = _load()
    print(f"jax {jax.__version__} ({jax.devices()[0].platform}), torch {torch.__version__} "
          f"({torch.get_num_threads()} threads), stable-baselines3 {stable_baselines3.__version__}; "
          f"load {load_start[0]:.2f}", flush=True)  # fmt: skip

    built = {}
    ours: dict[int, dict[str, Any]] = {}
    for n in sizes:
        built[n] = build_ours(base, env_table, n, args.updates)
        before = time_ours(built[n], args.repeats)
        ours[n] = {"num_envs": n, "compile_s": built[n]["compile_s"], "before": before}
        print(f"ours  num_envs {n:>5}: {ours[n]['before']['env_steps_per_s']:>9,.0f} env-steps/s "
              f"(compile {built[n]['compile_s']:.1f} s)", flush=True)  # fmt: skip
    load_mid = _load()
    sb3 = measure_sb3(args.sb3_steps, env_table)
    print(f"SB3:                  {sb3['env_steps_per_s']:>9,.0f} env-steps/s ({sb3['env_steps']:,} steps in "
          f"{sb3['seconds']:.1f} s; the adapter alone {sb3['adapter_env_steps_per_s']:,.0f} steps/s)",
          flush=True)  # fmt: skip
    load_after_sb3 = _load()
    for n in sizes:
        ours[n]["after"] = time_ours(built[n], args.repeats)
        rates = [ours[n][k]["env_steps_per_s"] for k in ("before", "after")]
        ours[n]["env_steps_per_s"] = float(np.mean(rates))
        ours[n]["spread"] = float(max(rates) / min(rates) - 1.0)
        ours[n]["ratio_over_sb3"] = ours[n]["env_steps_per_s"] / sb3["env_steps_per_s"]
        ours[n]["config"] = {k: v for k, v in ppo_config.to_dict(built[n]["cfg"]).items()
                             if k not in ("total_steps", "num_periods", "checkpoint_every")}  # fmt: skip
        print(f"ours  num_envs {n:>5}: {ours[n]['after']['env_steps_per_s']:>9,.0f} env-steps/s after SB3; "
              f"mean {ours[n]['env_steps_per_s']:,.0f} = {ours[n]['ratio_over_sb3']:.0f}x SB3 "
              f"(spread {100 * ours[n]['spread']:.0f}%)", flush=True)  # fmt: skip
    main_n = sizes[0]
    result = {
        "benchmark": "sb3",
        "machine": machine,
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "command": "python " + " ".join(shlex.quote(a) for a in sys.argv),
        "note": args.note,
        "versions": {
            "python": platform.python_version(),
            "jax": jax.__version__,
            "torch": torch.__version__,
            "stable_baselines3": stable_baselines3.__version__,
            "gymnasium": gymnasium.__version__,
            "numpy": np.__version__,
        },
        "platform": platform.platform(),
        "cpu_affinity": cpu_cores(),
        "load_average_1_5_15min": {
            "start": load_start,
            "before_sb3": load_mid,
            "after_sb3": load_after_sb3,
            "end": _load(),
        },  # fmt: skip
        "preset": args.preset,
        "env": env_table,
        "sb3": sb3,
        "ours": [ours[n] for n in sizes],
        "ratio": {
            "num_envs": main_n,
            "ours_env_steps_per_s": ours[main_n]["env_steps_per_s"],
            "sb3_env_steps_per_s": sb3["env_steps_per_s"],
            "ours_over_sb3": ours[main_n]["ratio_over_sb3"],
            "best_ours_over_sb3": max(o["ratio_over_sb3"] for o in ours.values()),
        },
    }
    path = write_json(args.out_dir, f"sb3_{machine}.json", result)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
