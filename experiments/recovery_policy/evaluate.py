"""Evaluation of recovery policies against the SMC on the same runs, RL-only.

    python experiments/recovery_policy/evaluate.py POLICY.npz [POLICY.npz ...] --out results/eval.json

For each policy and for the SMC (default gains), on common random numbers:
- the 1000-run Monte Carlo of ``harv-jax mc`` (reset bounds, mu0 = gamma0 = 0, alpha_d 0.349 rad, 60 s,
  ``--mc-seed``), nominal aircraft and ``--randomize`` (mass, inertia, aero multipliers per run): recovery
  rate, median / p95 recovery time, control TV, and the per-run paired ratio of recovery times;
- the 30 s developed spin of ``harv-jax fly --scenario spin`` (nominal aircraft, pro-spin deflections at
  engagement): recovered, recovery time after engagement, TV;
- the policy alone (no SMC for this one) over ``--env-episodes`` episodes of the training env with the FULL
  domain randomization on (mass/inertia/aero, gust, sensor noise, actuator delay): fraction of 60 s episodes
  that end inside the criterion (|e_alpha| < 2 deg, |e_beta| < 1 deg, |e_mu| < 2 deg, ||omega|| < 0.17
  rad/s at the last step, not terminated), from reset-bound states with alpha_d = 0.349 rad.
Seeds used here (MC seed 0 by default, env seed 1) are not the training seeds and were not tuned on.
"""

from __future__ import annotations

import argparse
import json
import platform
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.rl import make_rl_controller
from harv_jax.control.smc import make_smc
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.evaluation.policy_eval import make_eval_batch
from harv_jax.evaluation.summary import summarize_controller
from harv_jax.policy import resolve_policy
from harv_jax.task.spec import ALPHA_TARGET_RAD as DEFAULT_ALPHA_TARGET_RAD

N_STEPS = 6000  # 60 s at dt 0.01 s
REF = jnp.asarray([DEFAULT_ALPHA_TARGET_RAD, 0.0, 0.0])


def mc(ctrl, inputs) -> tuple[dict, np.ndarray, np.ndarray]:
    """Summary, per-run recovery times [N] (NaN: not recovered) and TV [N] of one controller."""
    out, wall = run_mc(ctrl, inputs, REF, N_STEPS, 0.01, 10, 250)
    s = summarize_controller(out, wall, N_STEPS)
    row = {
        "recovery_rate": s["recovery_rate"],
        "t_recover_p50_s": s["recovery_time_s"]["p50"],
        "t_recover_p95_s": s["recovery_time_s"]["p95"],
        "t_alpha_p50_s": s["alpha_recovery_time_s"]["p50"],
        "control_tv_mean_rad": s["control_tv"]["mean"],
        "control_tv_by_channel_rad": s["control_tv"]["by_channel"],
        "altitude_loss_p50_ft": float(np.median(np.asarray(out.metrics.altitude_loss_ft))),
        "outcomes": s["outcomes"],
        "wall_s": wall,
    }
    return row, np.asarray(out.metrics.t_recover_s, np.float64), np.asarray(out.metrics.control_tv_rad)


def spin(ctrl) -> dict:
    b = make_eval_batch(0, 1, harv())
    res = jax.jit(lambda: closed_loop(ctrl, harv(), b.x0_wind[0], REF, jax.random.key(0), N_STEPS, 0.01,
                                      b.delta0_rad[0]))()  # fmt: skip
    m, _ = score(res, REF, harv(), 0.01)
    rec = bool(m.recovered)
    return {"recovered": rec, "t_recover_s": float(m.t_recover_s) if rec else None,
            "control_tv_rad": float(jnp.sum(m.control_tv_rad)),
            "altitude_loss_ft": float(m.altitude_loss_ft)}  # fmt: skip


def env_episodes(policy, n: int, seed: int, randomize: bool = True) -> dict:
    """Deterministic policy over n 60 s episodes of the env with the full randomization on (or off)."""
    from harv_jax.env import EnvConfig, default_params, make_env
    from harv_jax.env.episode_metrics import harv_episode_metrics

    env = make_env(EnvConfig(episode_steps=N_STEPS, domain_randomization=randomize))
    params = default_params(env.config)
    a = jnp.asarray(DEFAULT_ALPHA_TARGET_RAD, params.reset.alpha_d_low_rad.dtype)
    params = params.replace(reset=params.reset.replace(alpha_d_low_rad=a, alpha_d_high_rad=a))
    act = policy.deterministic

    @jax.jit
    def run(key):
        k0, k1 = jax.random.split(key)
        obs, state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(k0, n), params)

        def step(carry, k):
            obs, state, alive, last = carry
            obs2, state2, _, terminated, truncated, info = jax.vmap(
                env.step_no_reset, in_axes=(0, 0, 0, None)
            )(jax.random.split(k, n), state, act(obs), params)
            info["final_state_wind"], info["final_obs"] = state2.wind, obs2
            m = jax.vmap(harv_episode_metrics)(info)
            last = {k: jnp.where(alive, v, last[k]) for k, v in m.items()}
            alive = alive & ~terminated & ~truncated
            return (obs2, state2, alive, last), None

        names = (
            "recovered",
            "alpha_ok",
            "final_omega_radps",
            "terminated",
            "final_omega_alive_radps",
            "final_abs_e_alpha_rad",
        )  # harv_episode_metrics' keys
        last0 = {k: jnp.zeros((n,), jnp.float32) for k in names}
        (_, _, _, last), _ = jax.lax.scan(
            step, (obs, state, jnp.ones((n,), bool), last0), jax.random.split(k1, N_STEPS)
        )
        return last

    last = jax.device_get(run(jax.random.key(seed)))
    keep = ("recovered", "alpha_ok", "terminated")
    return {k: float(np.mean(last[k])) for k in keep} | {"episodes": n}


def paired(t_a: np.ndarray, t_b: np.ndarray) -> dict:
    """Per-run ratio of recovery times on the runs both recover."""
    both = np.isfinite(t_a) & np.isfinite(t_b) & (t_b > 0)
    r = t_a[both] / t_b[both]
    return {"runs_both_recovered": int(both.sum()), "ratio_p50": float(np.median(r)) if r.size else None,
            "fraction_faster": float(np.mean(t_a[both] < t_b[both])) if r.size else None}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("policies", nargs="+")
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--mc-seed", type=int, default=0)
    ap.add_argument("--env-episodes", type=int, default=1000)
    ap.add_argument("--env-seed", type=int, default=1)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    result: dict = {"runs": args.runs, "mc_seed": args.mc_seed, "machine": platform.processor() or "cpu",
                    "jax": jax.__version__, "smc": {}, "policies": {}}  # fmt: skip
    times = {}
    for label, rand in (("nominal", False), ("randomized", True)):
        inputs = sample_mc_inputs(jax.random.key(args.mc_seed), args.runs, harv(), randomize=rand)
        row, t, _ = mc(make_smc(), inputs)
        result["smc"][label] = row
        times[("smc", label)] = t
    result["smc"]["spin"] = spin(make_smc())
    for spec in args.policies:
        pol = resolve_policy(spec)
        ctrl = make_rl_controller(pol.deterministic)
        r: dict = {}
        for label, rand in (("nominal", False), ("randomized", True)):
            inputs = sample_mc_inputs(jax.random.key(args.mc_seed), args.runs, harv(), randomize=rand)
            row, t, _ = mc(ctrl, inputs)
            row["paired_vs_smc"] = paired(t, times[("smc", label)])
            row["t_recover_p50_ratio_to_smc"] = (
                row["t_recover_p50_s"] / result["smc"][label]["t_recover_p50_s"]
                if row["t_recover_p50_s"]
                else None
            )
            r[label] = row
        r["spin"] = spin(ctrl)
        if args.env_episodes:
            r["env_full_randomization"] = env_episodes(pol, args.env_episodes, args.env_seed)
        result["policies"][spec] = r
        print(spec, json.dumps({k: (v if not isinstance(v, dict) else {kk: v[kk] for kk in list(v)[:4]})
                                for k, v in r.items()}), flush=True)  # fmt: skip
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(result, indent=2))
    args.out.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
