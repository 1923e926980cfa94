"""Probe: a policy that acts every k plant steps (action repeat), trained and flown RL-only.

The discount of the policy gradient then spans k times as long in time (gamma 0.99 per decision at 25 Hz:
about 4 s instead of 1 s) for the zoom-and-capture that pays off 10-20 s after its choice.

Training (``train``): the teacher env of the preset is wrapped so that one step of the trainer is k plant
steps with the same action (the teacher still runs at every plant step along the flown trajectory; its label
is the one at the decision's state); the reward is the sum over the k steps, and an episode that ends inside
the k steps ends there. This script replaces ``make_teacher_env`` of ``harv_jax.training.environment`` for
its own process, then runs ``harv-jax train`` with the arguments given. Evaluation (``evaluate``): each
seed's policy flies the Monte Carlo's runs holding its command for k plant steps, beside the SMC.

    python experiments/teacher_recipe/repeat_probe.py train 4 --preset P --seed 7 --out RUN
    python experiments/teacher_recipe/repeat_probe.py evaluate 4 RUN --mc-seed 11 --out OUT.json

The package's ``rl`` controller acts at every step; a policy trained here flies as intended only through this
script's evaluation.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.base import Controller
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.env.recovery import with_auto_reset
from harv_jax.evaluation.montecarlo.paired import paired_vs_reference
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.evaluation.seed_stats import iqm_ci
from harv_jax.task.spec import ALPHA_TARGET_RAD
from harv_jax.training import environment

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
RUN_LENGTH_S, N_STEPS = 60.0, 6000


def repeat_env(env: Any, k: int) -> Any:
    """``env`` (a teacher env) whose step is k of its steps with the same action (module docstring)."""

    def step_no_reset(key: jax.Array, state: Any, action: jnp.ndarray, params: Any):
        keys = jax.random.split(key, k)
        obs, state, reward, term, trunc, info = env.step_no_reset(keys[0], state, action, params)
        label = info["teacher_action"]

        def inner(carry, key_j):
            obs, state, reward, term, trunc, info = carry
            o, s, r, te, tr, i = env.step_no_reset(key_j, state, action, params)
            live = ~(term | trunc)
            pick = lambda new, old: jnp.where(live, new, old)  # noqa: E731
            carry = (pick(o, obs), jax.tree.map(pick, s, state), reward + jnp.where(live, r, 0.0))
            carry += (term | (live & te), trunc | (live & tr), jax.tree.map(pick, i, info))
            return carry, None

        carry = (obs, state, reward, term, trunc, info)
        (obs, state, reward, term, trunc, info), _ = jax.lax.scan(inner, carry, keys[1:])
        info["teacher_action"] = label
        return obs, state, reward, term, trunc & ~term, info

    step = with_auto_reset(step_no_reset, env.reset)

    def batch_step(keys: jax.Array, states: Any, actions: jnp.ndarray, params: Any):
        return jax.vmap(step, in_axes=(0, 0, 0, None))(keys, states, actions, params)

    return env._replace(step=step, step_no_reset=step_no_reset, batch_step=batch_step)


def hold(ctrl: Controller, k: int) -> Controller:
    """``ctrl`` evaluated every k steps, its command held in between."""

    def init(params):
        return (ctrl.init(params), jnp.zeros((), jnp.int32), jnp.zeros((3,), jnp.result_type(float)))

    def apply(state, x_wind, reference_rad, key):
        inner, n, held = state
        cmd, inner_next, info = ctrl.apply(inner, x_wind, reference_rad, key)
        new = n % k == 0
        out = jnp.where(new, cmd, held.astype(cmd.dtype))
        inner = jax.tree.map(lambda a, b: jnp.where(new, a, b), inner_next, inner)
        return out, (inner, n + 1, out), info

    return Controller(init=init, apply=apply)


def train(k: int, args: list[str]) -> None:
    make_teacher_env = environment.make_teacher_env
    environment.make_teacher_env = lambda *a, **kw: repeat_env(make_teacher_env(*a, **kw), k)
    from harv_jax.cli import main as cli_main

    sys.argv = ["harv-jax", "train", *args]
    cli_main()


def evaluate(k: int, run: Path, mc_seed: int, n_runs: int, out: Path) -> None:
    inputs = sample_mc_inputs(jax.random.key(mc_seed), n_runs, harv())

    def fly(ctrl):
        m = run_mc(ctrl, inputs, REF, N_STEPS)[0].metrics
        tv_rad = float(np.asarray(m.control_tv_rad, np.float64).sum(-1).mean())
        return np.asarray(m.t_recover_s), np.asarray(m.recovered), tv_rad

    t_smc, ok_smc, tv_smc = fly(build_controller("smc"))
    rows = []
    for path in sorted((run / "policy").glob("policy_seed*.npz")):
        t, ok, tv = fly(hold(build_controller("rl", ControllerOptions(policy=str(path))), k))
        vs = paired_vs_reference(t, ok, t_smc, ok_smc, RUN_LENGTH_S)
        row = {"policy": path.name, "recovered": float(ok.mean()), "mean_over_smc": vs["mean_ratio"]}
        row |= {"slower_than_smc_by_1s": vs["slower_fraction"], "tv_mean_rad": tv}
        print(row, flush=True)
        rows.append(row)
    summary = {key: iqm_ci([r[key] for r in rows]) for key in ("mean_over_smc", "slower_than_smc_by_1s")}
    result = {"command": " ".join(["python", *sys.argv]), "action_repeat": k, "mc_seed": mc_seed}
    result |= {"runs": n_runs, "smc_tv_mean_rad": tv_smc, "seeds": rows, "iqm": summary}
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(summary))


def main() -> None:
    what, k = sys.argv[1], int(sys.argv[2])
    if what == "train":
        train(k, sys.argv[3:])
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("run", type=Path)
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(sys.argv[3:])
    evaluate(k, a.run, a.mc_seed, a.runs, a.out)


if __name__ == "__main__":
    main()
