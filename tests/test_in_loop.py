"""Controller-in-the-loop training (``harv-jax train --in-loop hybrid[:schedule]``): the wrapped env, one
trace of the trainer, the loop recorded in the policy file, the warning when a policy flies in another
loop."""

from __future__ import annotations

import functools
import json
import subprocess
import sys
from pathlib import Path

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from compile_options import FAST_COMPILE

from harv_jax.env import EnvConfig, make_env
from harv_jax.env.episode_metrics import harv_episode_metrics
from harv_jax.errors import UsageError
from harv_jax.ppo.config import PPOConfig
from harv_jax.ppo.train import make_train, seed_keys
from harv_jax.training.in_loop import LOOPS, make_in_loop_env, parse_loop

REPO = Path(__file__).resolve().parents[1]
ENV = make_env(EnvConfig(episode_steps=200))
PARAMS = ENV.default_params()


ACTIONS = jnp.asarray([[0.5, -0.5, 0.3], [-0.9, 0.9, -0.2], [0.0, 0.0, 0.0]], jnp.float32)
N_STEPS = 50


@functools.partial(jax.jit, static_argnums=(0, 2), compiler_options=FAST_COMPILE)
def _first_steps(loop_env, actions: jnp.ndarray, auto_reset: bool):
    """``N_STEPS`` steps from the same reset (the same episode in every row) flying the constant ``actions``
    [B, 3] with ``step`` (the trainer's, auto-reset) or ``step_no_reset``: (the reset's observations [B, O],
    wind states [N_STEPS, B, 10], the first step's observations [B, O], rewards [B] and info)."""
    b = actions.shape[0]
    keys = jnp.broadcast_to(jax.random.key(3), (b,))
    obs0, st = jax.vmap(loop_env.reset, in_axes=(0, None))(keys, PARAMS)
    step = jax.vmap(loop_env.step if auto_reset else loop_env.step_no_reset, in_axes=(0, 0, 0, None))

    def body(st, k):
        out = step(jnp.broadcast_to(k, (b,)), st, actions, PARAMS)
        st = out[1]
        return st, (st.env.wind, (out[0], out[2], out[-1]))

    _, (wind, firsts) = jax.lax.scan(body, st, jax.random.split(jax.random.key(4), N_STEPS))
    return obs0, wind, jax.tree.map(lambda a: a[0], firsts)


@functools.cache
def _flight(loop: str):
    """The in-loop env of the schedule ``loop`` and its ``_first_steps`` with ACTIONS, flown once per module
    (``gated`` with the trainer's step: its compile serves two tests)."""
    loop_env = make_in_loop_env(ENV, loop)
    return loop_env, _first_steps(loop_env, ACTIONS, loop == "gated")


@pytest.mark.slow
def test_zeta_one_flies_the_smc_whatever_the_policy():
    """With ``always`` (zeta = 1) u = u_SMC: the action does not change the flight (up to float round-off)."""
    _, (_, x, _) = _flight("always")
    np.testing.assert_allclose(x[:, 0], x[:, 1], rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(x[:, 0], x[:, 2], rtol=1e-5, atol=1e-5)


@pytest.mark.slow
def test_the_policy_acts_through_the_gate():
    """With ``gated`` the action changes the flight: the policy is in the loop."""
    _, (_, x, _) = _flight("gated")
    assert float(jnp.max(jnp.abs(x[:, 0] - x[:, 1]))) > 1e-3


def test_interface_and_info():
    """The reset's and the (auto-reset) step's outputs of one env (the first row of the gated flight)."""
    loop_env, (obs0, _, (obs, r, info)) = _flight("gated")
    chex.assert_shape(obs0[0], (loop_env.observation_size,))
    info = jax.tree.map(lambda a: a[0], info)
    assert set(info["loop"]) == {"zeta", "policy_unmodified", "fallback"}
    m = harv_episode_metrics(info)  # the trainer's HARV metrics read the wrapped env's info
    assert set(m) >= {"recovered", "terminated"}
    chex.assert_tree_all_finite((obs[0], r[0]))


@pytest.mark.slow
def test_trainer_traces_once_and_its_policies_record_the_loop(tmp_path):
    cfg = PPOConfig(total_steps=16 * 8 * 4, num_envs=16, unroll=8, epochs=1, minibatches=2,
                    hidden_sizes=(16,), num_periods=2, seed=0, stagger_episodes=True)  # fmt: skip
    loop_env = make_in_loop_env(ENV, "gated")
    trainer = make_train(loop_env, cfg, PARAMS, episode_metrics_fn=harv_episode_metrics)
    state = trainer.init(seed_keys(jax.random.key(0), cfg.num_seeds), PARAMS)
    for _ in range(2):
        state, metrics = trainer.period(state, PARAMS)
    assert trainer.num_traces() == 1
    assert np.all(np.isfinite(metrics["policy_loss"]))

    # the exported policy records its loop; flying it in another loop is flagged, in its own loop not
    from harv_jax.control.registry import ControllerOptions, loop_mismatches
    from harv_jax.training.outputs import export_seed_policies

    export_seed_policies(tmp_path, state, trainer, cfg, 1, loop=loop_env.loop)
    path = str(tmp_path / "policy_seed0.npz")
    meta = json.loads(str(np.load(path, allow_pickle=False)["meta"]))
    assert meta["loop"] == "hybrid:gated"
    [line] = loop_mismatches(["smc", "rl", "hybrid"], ControllerOptions(policy=path, zeta="gated"))
    assert "trained in the loop 'hybrid:gated'" in line and "flies here as 'rl'" in line
    assert len(loop_mismatches(["hybrid"], ControllerOptions(policy=path, zeta="continuous"))) == 1


def test_parse_loop():
    assert parse_loop("hybrid") == "hybrid:gated"
    assert parse_loop("hybrid:continuous") == "hybrid:continuous"
    assert parse_loop("none") == "none"
    assert "hybrid:hysteresis" in LOOPS
    with pytest.raises(UsageError, match="allowed: none, hybrid:"):
        parse_loop("hybrid:fast")


@pytest.mark.slow
def test_cli_in_loop_policy_records_its_loop_and_mc_warns(tmp_path):
    out = tmp_path / "run"
    train = [sys.executable, "-m", "harv_jax.cli", "train", "--preset", "smoke", "--steps", "1024",
             "--num-envs", "16", "--minibatches", "4", "--periods", "1", "--in-loop", "hybrid:gated",
             "--out", str(out)]  # fmt: skip
    r = subprocess.run(train, capture_output=True, text=True, cwd=REPO, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    assert json.loads((out / "config.json").read_text())["env"]["loop"] == "hybrid:gated"
    meta = json.loads(str(np.load(out / "policy" / "policy.npz", allow_pickle=False)["meta"]))
    assert meta["loop"] == "hybrid:gated"

    mc = [sys.executable, "-m", "harv_jax.cli", "mc", "--runs", "2", "--duration", "10.5", "--chunk", "2",
          "--policy", str(out / "policy" / "policy.npz")]  # fmt: skip
    r = subprocess.run(mc + ["--controller", "rl", "--out", str(tmp_path / "mc1")], capture_output=True,
                       text=True, cwd=REPO, timeout=900)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert "trained in the loop 'hybrid:gated'" in r.stderr and "flies here as 'rl'" in r.stderr
    r = subprocess.run(mc + ["--controller", "hybrid", "--zeta", "gated", "--out", str(tmp_path / "mc2")],
                       capture_output=True, text=True, cwd=REPO, timeout=900)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert "trained in the loop" not in r.stderr

    r = subprocess.run(train[:-4] + ["--in-loop", "hybrid:fast", "--out", str(tmp_path / "bad")],
                       capture_output=True, text=True, cwd=REPO, timeout=900)  # fmt: skip
    assert r.returncode == 2 and r.stderr.strip().count("\n") == 0 and "hybrid:fast" in r.stderr


def test_policies_trained_alone_fly_anywhere_without_a_warning():
    from harv_jax.control.registry import ControllerOptions, loop_mismatches

    for zeta in ("continuous", "gated"):
        assert loop_mismatches(["smc", "rl", "hybrid"], ControllerOptions(zeta=zeta)) == []
