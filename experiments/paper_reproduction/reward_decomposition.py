"""Where a policy's training return comes from: every reward term of one episode, summed per env.

    python experiments/paper_reproduction/reward_decomposition.py \
        --out experiments/paper_reproduction/results/reward_decomposition.json

Each policy flies ``--runs`` episodes of the training env (paper reset bounds, ``--steps`` steps, the
deterministic action) with domain randomization on and off. Per term (reward.RewardTerms): the mean
episode sum, and its share of the mean return; plus episode length, termination rate and the final
|e_alpha| of the episodes that were not terminated, and what terminated the others. Nothing is trained;
the env and policies are the real ones.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.env.config import EnvConfig
from harv_jax.env.recovery import make_env
from harv_jax.env.termination import TerminationFlags
from harv_jax.policy import resolve_policy
from harv_jax.task.criteria import tracking_errors

TERMS = ("raw", "bonus_alpha", "bonus_beta", "bonus_mu", "action", "shaping", "terminal")
REASONS = TerminationFlags._fields


def decompose(spec: str, dr: bool, runs: int, steps: int, seed: int) -> dict:
    """Episode sums of every reward term of ``spec`` flown ``runs`` times in the training env."""
    policy = resolve_policy(spec)
    env = make_env(EnvConfig(episode_steps=steps, domain_randomization=dr))
    params = env.default_params()

    def episode(key: jax.Array) -> dict:
        k_reset, k_steps = jax.random.split(key)
        obs, state = env.reset(k_reset, params)

        def step(carry, k):
            obs, state, alive, sums, length, why = carry
            action = policy.deterministic(obs)
            obs2, state2, _, terminated, _, info = env.step_no_reset(k, state, action, params)
            terms = info["reward_terms"]
            sums = {t: sums[t] + jnp.where(alive, terms[t], 0.0) for t in TERMS}
            why = {r: why[r] | (alive & info["termination"][r]) for r in REASONS}
            return (obs2, state2, alive & ~terminated, sums, length + alive, why), None

        sums0 = {t: jnp.zeros(()) for t in TERMS}
        why0 = {r: jnp.asarray(False) for r in REASONS}
        carry0 = (obs, state, jnp.asarray(True), sums0, jnp.zeros((), jnp.int32), why0)
        (_, state, alive, sums, length, why), _ = jax.lax.scan(step, carry0, jax.random.split(k_steps, steps))
        e_alpha = jnp.abs(tracking_errors(state.wind, state.target_rad)[0])
        return {"sums": sums, "alive": alive, "length": length, "final_abs_e_alpha_rad": e_alpha, "why": why}

    out = jax.device_get(jax.jit(jax.vmap(episode))(jax.random.split(jax.random.key(seed), runs)))
    total = sum(out["sums"][t] for t in TERMS)
    alive = np.asarray(out["alive"])
    e_alpha_deg = np.degrees(np.asarray(out["final_abs_e_alpha_rad"])[alive])
    return {
        "policy": spec,
        "domain_randomization": dr,
        "return_mean": float(np.mean(total)),
        "term_sum_mean": {t: float(np.mean(out["sums"][t])) for t in TERMS},
        "term_share_of_return": {t: float(np.mean(out["sums"][t]) / np.mean(total)) for t in TERMS},
        "episode_length_mean": float(np.mean(out["length"])),
        "terminated_rate": float(1.0 - alive.mean()),
        "terminated_by": {r: float(np.mean(out["why"][r])) for r in REASONS},
        "final_abs_e_alpha_deg_p50": float(np.median(e_alpha_deg)) if e_alpha_deg.size else None,
        "final_alpha_within_1deg": float(np.mean(e_alpha_deg < 1.0)) if e_alpha_deg.size else None,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policies", default="shipped:full,shipped:partial", help="comma-separated policy specs")
    ap.add_argument("--runs", type=int, default=128)
    ap.add_argument("--steps", type=int, default=20_000, help="episode length, steps of 0.01 s")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    if args.out.exists():
        raise SystemExit(f"{args.out} exists; remove it first")
    rows = []
    for spec in args.policies.split(","):
        for dr in (True, False):
            row = decompose(spec, dr, args.runs, args.steps, args.seed)
            print(json.dumps(row), flush=True)
            rows.append(row)
    meta = {"runs": args.runs, "steps": args.steps, "seed": args.seed, "backend": jax.default_backend()}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({**meta, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
