"""PPO trainer mechanics on a tiny toy env of the same interface: one trace, learning, resume == continuous,
checkpoint validation, sharded == unsharded (2 host devices, subprocess), policy export, CLI errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct

from harv_jax.errors import UsageError
from harv_jax.ppo import checkpoint
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo.acting import make_evaluate
from harv_jax.ppo.config import PPOConfig
from harv_jax.ppo.runner import run_training, warm_start
from harv_jax.ppo.train import make_train, seed_keys
from harv_jax.training import presets

REPO = Path(__file__).resolve().parents[1]

if __name__ == "__main__" and sys.argv[1:2] == ["multiprocess"]:  # child of the 2-process test: before any
    # array is created (TOY_PARAMS below), join the 2-process cluster
    jax.distributed.initialize(f"localhost:{sys.argv[2]}", num_processes=2, process_id=int(sys.argv[3]))


# ---------------------------------------------------------------------------------------------- toy env


@struct.dataclass
class ToyState:
    x: jax.Array  # [3] position
    step: jax.Array  # [] int32 step in episode (the field `stagger_episodes` sets)


@struct.dataclass
class ToyParams:
    gain: jax.Array  # [] position change per unit action per step


class ToyEnv:
    """x' = x + gain * a, reward -|x'|^2 (and -5 on leaving |x| <= 2, a termination); time limit 12 steps.

    Same interface as the HARV env (gymnax style, auto-reset, info truncation/final_obs). The optimal
    policy drives x to 0 (a = -x / gain, clipped), so a learner that works raises the return quickly.
    """

    observation_size = 4
    action_size = 3
    episode_steps = 12

    def _obs(self, s: ToyState) -> jax.Array:
        return jnp.concatenate([s.x, (s.step / self.episode_steps)[None].astype(jnp.float32)])

    def reset(self, key: jax.Array, params: ToyParams) -> tuple[jax.Array, ToyState]:
        s = ToyState(jax.random.uniform(key, (3,), minval=-1.0, maxval=1.0), jnp.zeros((), jnp.int32))
        return self._obs(s), s

    def step(self, key: jax.Array, state: ToyState, action: jax.Array, params: ToyParams):
        x = state.x + params.gain * jnp.clip(action, -1.0, 1.0)
        s = ToyState(x, state.step + 1)
        term = jnp.any(jnp.abs(x) > 2.0)
        trunc = (s.step >= self.episode_steps) & ~term
        reward = -jnp.sum(x**2) - 5.0 * term
        done = term | trunc
        final_obs = self._obs(s)
        obs_r, s_r = self.reset(key, params)
        s = jax.tree.map(lambda a, b: jnp.where(done, a, b), s_r, s)
        info = {"truncation": trunc, "final_obs": final_obs, "settled": jnp.all(jnp.abs(x) < 0.2)}
        return jnp.where(done, obs_r, final_obs), s, reward, done, info


TOY_PARAMS = ToyParams(jnp.asarray(0.25, jnp.float32))
CFG = PPOConfig(
    total_steps=32 * 16 * 24, num_envs=32, unroll=16, epochs=2, minibatches=4, lr=3e-3, hidden_sizes=(16,),
    reward_scale=0.1, num_seeds=2, num_periods=4, seed=0,
)  # fmt: skip


@pytest.fixture(scope="module")
def trainer():
    return make_train(ToyEnv(), CFG, TOY_PARAMS)


@pytest.fixture(scope="module")
def full_run(trainer, tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("full")
    res = run_training(jax.random.key(CFG.seed), ToyEnv(), TOY_PARAMS, CFG, run_dir=run_dir, trainer=trainer)
    return res, run_dir


# ---------------------------------------------------------------------------------------------- tests


def test_derived_sizes():
    assert ppo_config.batch_size(CFG) == 512
    assert ppo_config.updates_per_period(CFG) == 6
    assert ppo_config.num_periods(CFG) == 4
    assert ppo_config.steps_per_period(CFG) == 3072


def test_one_trace_finite_metrics(trainer):
    state = trainer.init(seed_keys(jax.random.key(5), CFG.num_seeds), TOY_PARAMS)
    before = trainer.num_traces()
    for _ in range(3):
        state, metrics = trainer.period(state, TOY_PARAMS)
    # at most one trace of the period function, ever (the module fixture may have traced it already)
    assert trainer.num_traces() == 1 and before <= 1
    chex.assert_shape(state.obs, (CFG.num_seeds, CFG.num_envs, ToyEnv.observation_size))
    chex.assert_tree_all_finite(state.params)
    np.testing.assert_array_equal(state.update_step, 3 * ppo_config.updates_per_period(CFG))
    for k in ("policy_loss", "value_loss", "entropy", "approx_kl", "grad_norm", "episode_return", "episodes"):
        chex.assert_shape(metrics[k], (CFG.num_seeds,))
        assert np.all(np.isfinite(metrics[k])), k
    assert "episode/settled" in metrics
    # the two seeds are independent learners: different parameters
    w = state.params.policy["params"]["mlp"]["out"]["kernel"]
    assert not np.allclose(w[0], w[1])


def test_learns_on_toy_env(trainer, full_run):
    res, _ = full_run
    first, last = res.history[0], res.history[-1]
    # every seed improves its mean episode return by a wide margin (initial ~ -6, optimum ~ -0.5)
    gain = last["episode_return"] - first["episode_return"]
    assert np.all(gain > 1.0), (first["episode_return"], last["episode_return"])
    # deterministic evaluation on common initial states: trained beats the initial parameters
    evaluate = jax.jit(make_evaluate(ToyEnv(), trainer.networks, 64, ToyEnv.episode_steps))
    init_state = trainer.init(seed_keys(jax.random.key(CFG.seed), CFG.num_seeds), TOY_PARAMS)
    for s in range(CFG.num_seeds):
        pick = lambda tree: jax.tree.map(lambda x: x[s], tree)  # noqa: E731, B023
        r0 = evaluate(jax.random.key(9), pick(init_state.params), pick(init_state.normalizer), TOY_PARAMS)
        r1 = evaluate(jax.random.key(9), pick(res.state.params), pick(res.state.normalizer), TOY_PARAMS)
        assert float(r1["return"].mean()) > float(r0["return"].mean()) + 1.0
        assert float(r1["ended"].mean()) == 1.0  # every episode ran to its time limit or terminated


def test_resume_equals_continuous(trainer, full_run, tmp_path):
    full, _ = full_run
    key = jax.random.key(CFG.seed)
    half = run_training(
        key, ToyEnv(), TOY_PARAMS, CFG, run_dir=tmp_path, trainer=trainer, stop_after_periods=2
    )
    assert len(half.history) == 2
    resumed = run_training(key, ToyEnv(), TOY_PARAMS, CFG, run_dir=tmp_path, trainer=trainer, resume=True)
    assert len(resumed.history) == ppo_config.num_periods(CFG)
    # bit-identical on CPU: params, optimizer state, normaliser, env state, keys, counters
    a, b = jax.device_get(full.state), jax.device_get(resumed.state)
    a = a.replace(key=jax.random.key_data(a.key))
    b = b.replace(key=jax.random.key_data(b.key))
    chex.assert_trees_all_equal(a, b)
    np.testing.assert_array_equal(resumed.history[-1]["episode_return"], full.history[-1]["episode_return"])
    assert trainer.num_traces() == 1  # resuming reused the compiled period


def test_resume_restores_the_evaluation_history(trainer, tmp_path):
    """Every history row, the period hook's (evaluation) entries included, equals the uninterrupted run's."""

    def hook(p, state):  # a stand-in evaluation: a number computed from the parameters
        leaves = jax.tree.leaves(jax.device_get(state.params))
        return {
            "eval/param_sum": np.asarray([float(np.sum(x[s])) for s in range(2) for x in leaves[:1]])
        }, False

    key = jax.random.key(CFG.seed)
    full = run_training(key, ToyEnv(), TOY_PARAMS, CFG, run_dir=tmp_path / "full", trainer=trainer,
                        period_hook=hook)  # fmt: skip
    run_training(key, ToyEnv(), TOY_PARAMS, CFG, run_dir=tmp_path / "half", trainer=trainer,
                 stop_after_periods=2, period_hook=hook)  # fmt: skip
    resumed = run_training(key, ToyEnv(), TOY_PARAMS, CFG, run_dir=tmp_path / "half", trainer=trainer,
                           resume=True, period_hook=hook)  # fmt: skip
    assert len(resumed.history) == len(full.history)
    for a, b in zip(full.history, resumed.history, strict=True):
        assert a.keys() == b.keys()
        for k in a:
            if k not in ("wall_s", "period_s"):
                np.testing.assert_array_equal(np.asarray(a[k]), np.asarray(b[k]), err_msg=k)


def test_warm_start_from_a_trained_policy(trainer, full_run):
    """--init-policy: every seed starts from one policy (fine-tuning); a shape mismatch is named."""
    res, _ = full_run
    pick = lambda tree: jax.tree.map(lambda x: np.asarray(x[1]), tree)  # noqa: E731
    params, normalizer = pick(res.state.params), pick(res.state.normalizer)
    fresh = trainer.init(seed_keys(jax.random.key(5), CFG.num_seeds), TOY_PARAMS)
    warm = warm_start(fresh, params, normalizer)
    for s in range(CFG.num_seeds):
        seed_s = lambda tree, s=s: jax.tree.map(lambda x: np.asarray(x[s]), tree)  # noqa: E731
        chex.assert_trees_all_equal(seed_s(warm.params), params)
        chex.assert_trees_all_equal(seed_s(warm.normalizer), normalizer)
    chex.assert_trees_all_equal(warm.env_state, fresh.env_state)  # only the learner is replaced
    assert warm.params.policy["params"]["mlp"]["out"]["kernel"].sharding == fresh.params.policy["params"][
        "mlp"]["out"]["kernel"].sharding  # fmt: skip
    # a run started from the trained policy begins where that policy is, not at the random init's return
    key = jax.random.key(5)
    cold = run_training(key, ToyEnv(), TOY_PARAMS, CFG, trainer=trainer, stop_after_periods=1)
    hot = run_training(key, ToyEnv(), TOY_PARAMS, CFG, trainer=trainer, stop_after_periods=1,
                       init_policy=(params, normalizer))  # fmt: skip
    assert np.all(hot.history[0]["episode_return"] > cold.history[0]["episode_return"] + 1.0)
    bad = jax.tree.map(lambda x: x[..., :3] if x.ndim == 2 else x, params)  # narrower kernels
    with pytest.raises(ValueError, match=r"initial policy parameter .*kernel.* has shape \(4, 3\)"):
        warm_start(fresh, bad, normalizer)


def test_checkpoints_atomic_pruned_and_validated(full_run, tmp_path):
    _, run_dir = full_run
    files = checkpoint.checkpoint_paths(run_dir / "checkpoints")
    assert [f.name for f in files] == ["ckpt_000003.msgpack", "ckpt_000004.msgpack"]  # KEEP = 2
    assert not [p for p in (run_dir / "checkpoints").iterdir() if p.name.startswith(".tmp")]
    payload = checkpoint.read(files[-1])
    assert payload["period"] == 4 and payload["env_steps"] == 4 * ppo_config.steps_per_period(CFG)
    # a different config is refused, naming the field
    with pytest.raises(UsageError, match="lr"):
        template = jax.eval_shape(make_train(ToyEnv(), CFG.replace(lr=1e-4), TOY_PARAMS).init,
                                  seed_keys(jax.random.key(0), 2), TOY_PARAMS)  # fmt: skip
        checkpoint.restore_latest(run_dir / "checkpoints", template, CFG.replace(lr=1e-4))
    # a torn/corrupt file is refused with one line
    bad = tmp_path / "ckpt_000001.msgpack"
    bad.write_bytes(files[-1].read_bytes()[:100])
    with pytest.raises(UsageError, match="unreadable|not a harv_jax"):
        checkpoint.read(bad)
    with pytest.raises(UsageError, match="no checkpoint"):
        checkpoint.restore_latest(tmp_path / "nothing", None, CFG)


def test_checkpoint_without_a_newer_setting_restores(trainer, full_run, tmp_path):
    """A checkpoint written before a PPO setting existed restores with that setting's default."""
    from flax import serialization

    _, run_dir = full_run
    payload = checkpoint.read(checkpoint.checkpoint_paths(run_dir / "checkpoints")[-1])
    old_config = json.loads(payload["config"])
    del old_config["stagger_episodes"]
    payload["config"] = json.dumps(old_config)
    del payload["sha256"]  # such old files also predate the checksum
    (tmp_path / "ckpt_000004.msgpack").write_bytes(serialization.msgpack_serialize(payload))
    template = jax.eval_shape(trainer.init, seed_keys(jax.random.key(0), 2), TOY_PARAMS)
    assert checkpoint.restore_latest(tmp_path, template, CFG).period == 4
    with pytest.raises(UsageError, match="stagger_episodes=False vs True"):
        checkpoint.restore_latest(tmp_path, template, CFG.replace(stagger_episodes=True))


def test_stagger_episodes_spreads_first_episodes():
    cfg = CFG.replace(num_seeds=1, num_envs=64)
    keys = seed_keys(jax.random.key(3), 1)
    plain = make_train(ToyEnv(), cfg, TOY_PARAMS).init(keys, TOY_PARAMS)
    staggered = make_train(ToyEnv(), cfg.replace(stagger_episodes=True), TOY_PARAMS).init(keys, TOY_PARAMS)
    steps = np.asarray(staggered.env_state.step[0])
    assert np.all(np.asarray(plain.env_state.step) == 0)
    assert steps.min() >= 0 and steps.max() < ToyEnv.episode_steps and len(np.unique(steps)) >= 6
    # only the step counters differ: the stagger draws from a stream of its own
    np.testing.assert_array_equal(staggered.env_state.x, plain.env_state.x)
    np.testing.assert_array_equal(staggered.obs, plain.obs)
    chex.assert_trees_all_equal(staggered.params, plain.params)

    class NoTimeLimit(ToyEnv):
        episode_steps = None

    with pytest.raises(ValueError, match="stagger_episodes needs"):
        make_train(NoTimeLimit(), cfg.replace(stagger_episodes=True), TOY_PARAMS)


def _check_obs_count_in_meta(path, policy_api):
    """A file without meta["obs_count"] (older files) loads with ASSUMED_OBS_COUNT; a bad one is refused."""
    import json

    with np.load(path, allow_pickle=False) as z:
        arrays = dict(z)
    meta = json.loads(str(arrays["meta"]))
    for count, ok in ((None, True), (-1.0, False), ("many", False)):
        m = {k: v for k, v in meta.items() if k != "obs_count"} | (
            {} if count is None else {"obs_count": count}
        )
        np.savez(path.with_name("c.npz"), **(arrays | {"meta": np.asarray(json.dumps(m))}))
        if ok:
            got = policy_api.load(path.with_name("c.npz")).normalizer.count
            assert float(got) == policy_api.ASSUMED_OBS_COUNT
        else:
            with pytest.raises(UsageError, match="obs_count"):
                policy_api.load(path.with_name("c.npz"))


def test_policy_export_roundtrip(trainer, full_run, tmp_path):
    from harv_jax import policy as policy_api
    from harv_jax import policy_stablehlo

    res, run_dir = full_run
    params = jax.tree.map(lambda x: x[1], res.state.params)
    normalizer = jax.tree.map(lambda x: x[1], res.state.normalizer)
    pol = policy_api.make_policy(params, normalizer, trainer.networks, True, {"seed": 1})
    obs = jnp.asarray(np.random.default_rng(0).normal(size=(7, 4)), jnp.float32)
    want = pol.deterministic(obs)
    chex.assert_shape(want, (7, 3))
    assert float(jnp.max(jnp.abs(want))) <= 1.0
    from_npz = policy_api.load(policy_api.export_npz(tmp_path / "p.npz", pol))
    np.testing.assert_allclose(from_npz.deterministic(obs), want, rtol=1e-5, atol=1e-6)
    # the statistics come back with their count (a fine-tune updates them instead of replacing them)
    for name in ("count", "mean", "m2"):
        np.testing.assert_allclose(getattr(from_npz.normalizer, name), getattr(normalizer, name), rtol=1e-5)
    _check_obs_count_in_meta(tmp_path / "p.npz", policy_api)
    if policy_stablehlo.export_available():  # jax.export serialization needs flatbuffers
        saved = policy_stablehlo.export_stablehlo(tmp_path / "p.stablehlo", pol)
        exported = policy_stablehlo.load_exported(saved)
        np.testing.assert_allclose(exported(obs), want, rtol=1e-5, atol=1e-6)
    ckpt = checkpoint.checkpoint_paths(run_dir / "checkpoints")[-1]
    from_ckpt = policy_api.load(ckpt, seed=1)
    np.testing.assert_allclose(from_ckpt.deterministic(obs), want, rtol=1e-6)
    # the plain npz is usable without jax: numpy forward pass
    with np.load(tmp_path / "p.npz", allow_pickle=False) as z:
        x = np.clip((np.asarray(obs) - z["obs_mean"]) / z["obs_std"], -10, 10)
        h = np.tanh(x @ z["policy/hidden_0/kernel"] + z["policy/hidden_0/bias"])
        mean = h @ z["policy/out/kernel"] + z["policy/out/bias"]
    np.testing.assert_allclose(np.clip(mean, -1, 1), want, rtol=1e-4, atol=1e-5)
    a = pol.stochastic(jax.random.key(0), obs)
    assert not np.allclose(a, want)
    with pytest.raises(UsageError, match="does not exist"):
        policy_api.load(tmp_path / "missing.npz")


def test_presets_load_and_bad_values():
    for name in ("smoke", "paper-partial", "paper-full"):
        cfg, env = presets.load_preset(name)
        assert cfg.hidden_sizes == (256, 128) and cfg.gamma == 0.99
        assert "episode_steps" in env
    _, env_full = presets.load_preset("paper-full")
    assert env_full["domain_randomization"] is True
    assert presets.load_preset("paper-full")[0].total_steps == 120_000_000
    assert presets.load_preset("paper-partial")[0].total_steps == 10_000_000
    with pytest.raises(UsageError, match="unknown preset 'nope'"):
        presets.load_preset("nope")
    with pytest.raises(UsageError, match="--steps -5"):
        CFG.replace(total_steps=-5)
    with pytest.raises(UsageError, match="--minibatches 7 must divide"):
        CFG.replace(minibatches=7)
    with pytest.raises(UsageError, match="--lr"):
        CFG.replace(lr=0.0)
    with pytest.raises(UsageError, match="unknown PPO setting 'lrr'"):
        ppo_config.from_dict({"lrr": 1.0})
    with pytest.raises(UsageError, match="not divisible by the 2 available devices"):
        ppo_config.check_devices(CFG.replace(num_envs=3, minibatches=1), 2)


def test_presets_load_from_package_data():
    """The presets live once, as package data (what a non-editable install loads too)."""
    assert presets.available_presets() == [
        "fast",
        "paper-full",
        "paper-partial",
        "recovery",
        "robust",
        "smoke",
        "teacher",
    ]
    assert str(presets.preset_path("smoke")) == str(presets.PRESET_DIR / "smoke.toml")
    assert not (REPO / "experiments" / "presets").exists()
    with pytest.raises(
        UsageError,
        match="unknown preset .nope.; available: fast, paper-full, paper-partial, recovery, robust, smoke, "
        "teacher",
    ):
        presets.load_preset("nope")


def _cli(monkeypatch, capsys, *args: str) -> tuple[int, str]:
    from harv_jax import cli

    monkeypatch.setattr(sys, "argv", ["harv-jax", "train", *args])
    with pytest.raises(SystemExit) as e:
        cli.main()
    return e.value.code, capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--steps", "-5", "--out", "{tmp}/o"], "--steps -5 must be a positive integer"),
        (["--preset", "nope", "--out", "{tmp}/o"], "unknown preset 'nope'"),
        (["--resume", "{tmp}/absent"], "is not a directory"),
        (["--resume", "{tmp}"], "no checkpoint found"),
        (["--resume", "{tmp}", "--num-envs", "8"], "drop --num-envs"),
        (["--minibatches", "5", "--out", "{tmp}/o"], "--minibatches 5 must divide"),
        (["--lr", "-1", "--out", "{tmp}/o"], "--lr -1.0 must be > 0"),
        (["--out", "{tmp}/full"], "already exists and is not empty"),
        (["--steps", "abc"], "Invalid value for '--steps'"),
        (["--seeds", "0", "--out", "{tmp}/o"], "--seeds 0 must be a positive integer"),
        (["--resume", "{tmp}", "--init-policy", "shipped:partial"], "drop --init-policy"),
        (["--init-policy", "shipped:nope", "--out", "{tmp}/o"], "shipped policy 'nope' is unknown"),
    ],
)
def test_cli_bad_flags_one_line(monkeypatch, capsys, tmp_path, args, message):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    code, err = _cli(monkeypatch, capsys, *[a.replace("{tmp}", str(tmp_path)) for a in args])
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("harv-jax: error:"), err
    assert message in lines[0]


def test_cli_num_envs_not_divisible_by_devices(monkeypatch, capsys, tmp_path):
    from harv_jax.ppo import sharding

    monkeypatch.setattr(sharding, "default_devices", lambda: ["d0", "d1"])
    code, err = _cli(
        monkeypatch, capsys, "--num-envs", "3", "--minibatches", "1", "--out", str(tmp_path / "o")
    )
    assert code == 2 and err.count("\n") == 1
    assert "--num-envs 3 is not divisible by the 2 available devices" in err


def test_sharded_equals_unsharded():
    """2 host devices (XLA flag set before jax starts, hence a subprocess): same total batch, same seed."""
    # cheaper XLA CPU codegen in the child (both runs use it, so the comparison is unaffected)
    flags = "--xla_force_host_platform_device_count=2 --xla_backend_optimization_level=0"
    env = dict(os.environ, XLA_FLAGS=flags + " --xla_llvm_disable_expensive_passes=true", JAX_PLATFORMS="cpu")
    out = subprocess.run([sys.executable, __file__, "sharded"], env=env, capture_output=True, text=True,
                         timeout=600, cwd=REPO)  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["devices"] == 2
    assert result["shard_shapes"] == [[CFG.num_seeds, CFG.num_envs // 2, 4]] * 2
    assert result["max_abs_param_diff"] < 1e-4, result
    assert result["max_rel_return_diff"] < 1e-3, result
    assert result["params_moved"] > 1e-2  # training changed the parameters (the comparison is not vacuous)


@pytest.mark.slow
def test_sigkill_then_resume_matches_continuous(trainer, full_run, tmp_path):
    """A training process killed with SIGKILL resumes from its last complete checkpoint (<= 1 period lost)
    and ends with the same parameters as the uninterrupted run."""
    import signal
    import time

    proc = subprocess.Popen([sys.executable, __file__, "train-slowly", str(tmp_path)], cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    deadline = time.time() + 600
    while time.time() < deadline and len(checkpoint.checkpoint_paths(tmp_path / "checkpoints")) < 1:
        assert proc.poll() is None, proc.stderr.read()[-2000:]
        time.sleep(0.05)
    time.sleep(0.3)  # somewhere inside a later period (each takes >= 0.5 s in the child)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done = checkpoint.checkpoint_paths(tmp_path / "checkpoints")
    assert done and int(done[-1].name[5:11]) < ppo_config.num_periods(CFG)  # killed before the end
    resumed = run_training(jax.random.key(CFG.seed), ToyEnv(), TOY_PARAMS, CFG, run_dir=tmp_path,
                           trainer=trainer, resume=True)  # fmt: skip
    full, _ = full_run
    a, b = jax.device_get(full.state.params), jax.device_get(resumed.state.params)
    chex.assert_trees_all_equal(a, b)


@pytest.mark.slow
def test_cli_smoke_on_harv_env(tmp_path):
    """`harv-jax train` on the real env, tiny budget: outputs, resume of a finished run, policy.load."""
    from harv_jax import policy as policy_api

    out = tmp_path / "run"
    base = [sys.executable, "-m", "harv_jax.cli", "train"]
    flags = ["--preset", "smoke", "--steps", "2048", "--num-envs", "16", "--minibatches", "4"]
    r = subprocess.run(base + flags + ["--seeds", "2", "--out", str(out)], capture_output=True, text=True,
                       cwd=REPO, timeout=900)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    for name in ("config.json", "metrics.csv", "training_curve.png", "summary.json", "policy/policy.npz",
                 "policy/policy_seed1.npz"):  # fmt: skip
        assert (out / name).is_file(), name
    rows = (out / "metrics.csv").read_text().strip().splitlines()
    assert len(rows) == 1 + ppo_config.num_periods(presets.load_preset("smoke")[0].replace(
        total_steps=2048, num_envs=16, minibatches=4))  # fmt: skip
    r = subprocess.run(base + ["--resume", str(out)], capture_output=True, text=True, cwd=REPO, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    pol = policy_api.load(out)
    obs = jnp.asarray([600.0, 0.1, 0.0, 0.2, -0.1, 0.05, 0.3, 0.0, 0.35, 0.0, 0.0], jnp.float32)
    a = pol.deterministic(obs)
    chex.assert_shape(a, (3,))
    assert bool(jnp.all(jnp.abs(a) <= 1.0))


def _train_slowly_child(run_dir: str) -> None:
    """Run in a subprocess: the toy run of ``full_run`` with checkpoints, 0.5 s pause per period."""
    import time

    run_training(jax.random.key(CFG.seed), ToyEnv(), TOY_PARAMS, CFG, run_dir=run_dir,
                 progress_fn=lambda p, row: time.sleep(0.5))  # fmt: skip


def _sharded_child() -> None:
    """Run in the subprocess: train 2 periods on 1 device and on 2 devices; print a JSON summary."""
    devices = jax.devices()
    cfg = CFG.replace(num_periods=8)  # 2 periods of 3 updates
    key = jax.random.key(3)
    results = []
    for devs in (devices[:1], devices[:2]):
        tr = make_train(ToyEnv(), cfg, TOY_PARAMS, devices=devs)
        res = run_training(key, ToyEnv(), TOY_PARAMS, cfg, trainer=tr, stop_after_periods=2)
        results.append(res)
    p1, p2 = (jax.device_get(r.state.params) for r in results)
    diff = max(
        float(np.max(np.abs(a - b))) for a, b in zip(jax.tree.leaves(p1), jax.tree.leaves(p2), strict=True)
    )
    init = jax.device_get(results[0].trainer.init(seed_keys(key, cfg.num_seeds), TOY_PARAMS).params)
    moved = max(
        float(np.max(np.abs(a - b))) for a, b in zip(jax.tree.leaves(p1), jax.tree.leaves(init), strict=True)
    )
    r1 = np.asarray(results[0].history[-1]["episode_return"])
    r2 = np.asarray(results[1].history[-1]["episode_return"])
    obs = results[1].state.obs
    summary = {
        "devices": len(devices),
        "shard_shapes": [list(s.data.shape) for s in obs.addressable_shards],
        "max_abs_param_diff": diff,
        "params_moved": moved,
        "max_rel_return_diff": float(np.max(np.abs(r1 - r2) / (np.abs(r1) + 1e-6))),
    }
    print(json.dumps(summary))


def _multiprocess_child(port: str, process_id: int, run_dir: str, phase: str) -> None:
    """One of 2 processes (1 CPU device each, gloo collectives; joined at import): train half the run, or
    resume to the end."""
    assert jax.process_count() == 2 and jax.process_index() == process_id, port
    cfg = CFG.replace(num_seeds=1)
    tr = make_train(ToyEnv(), cfg, TOY_PARAMS, devices=jax.devices())
    kw = {"stop_after_periods": 2} if phase == "half" else {"resume": True}
    res = run_training(jax.random.key(cfg.seed), ToyEnv(), TOY_PARAMS, cfg, trainer=tr, run_dir=run_dir, **kw)
    params = [np.asarray(x).ravel().tolist() for x in jax.tree.leaves(jax.device_get(res.state.params))]
    print(json.dumps({"devices": jax.device_count(), "periods": len(res.history), "params": params}))


@pytest.mark.slow
def test_two_processes_with_resume_match_one_process(tmp_path):
    """Multi-host emulated on one machine: 2 processes x 1 CPU device (jax.distributed, gloo), checkpoint
    after 2 periods, resume in 2 new processes; equals one process on one device (same total batch, seed)."""
    import socket

    with socket.socket() as sock:
        sock.bind(("localhost", 0))
        port = str(sock.getsockname()[1])
    env = dict(os.environ, JAX_PLATFORMS="cpu", XLA_FLAGS="--xla_backend_optimization_level=0")
    run_dir = str(tmp_path / "run")
    outs = {}
    for phase in ("half", "resume"):
        cmds = [[sys.executable, __file__, "multiprocess", port, str(i), run_dir, phase] for i in range(2)]
        pipe = subprocess.PIPE
        procs = [subprocess.Popen(c, env=env, stdout=pipe, stderr=pipe, text=True, cwd=REPO) for c in cmds]
        outs[phase] = [p.communicate(timeout=600) for p in procs]
        for p, (_, err) in zip(procs, outs[phase], strict=True):
            assert p.returncode == 0, err[-3000:]
    res = [json.loads(out.strip().splitlines()[-1]) for out, _ in outs["resume"]]
    assert [r["devices"] for r in res] == [2, 2] and [r["periods"] for r in res] == [4, 4]
    assert res[0]["params"] == res[1]["params"]  # replicated parameters agree bit for bit
    assert [f.name for f in checkpoint.checkpoint_paths(tmp_path / "run" / "checkpoints")][
        -1
    ] == "ckpt_000004.msgpack"
    cfg = CFG.replace(num_seeds=1)
    one = run_training(jax.random.key(cfg.seed), ToyEnv(), TOY_PARAMS, cfg,
                       trainer=make_train(ToyEnv(), cfg, TOY_PARAMS, devices=jax.devices()[:1]))  # fmt: skip
    want = np.concatenate([np.asarray(x).ravel() for x in jax.tree.leaves(jax.device_get(one.state.params))])
    got = np.concatenate([np.asarray(x) for x in res[0]["params"]])
    # float reduction order differs (2 devices vs 1; children compile at -O0): 1e-4 relative after 24 updates
    np.testing.assert_allclose(got, want, rtol=1e-3, atol=1e-4)


if __name__ == "__main__" and sys.argv[1:] == ["sharded"]:
    _sharded_child()
elif __name__ == "__main__" and sys.argv[1:2] == ["multiprocess"]:
    _multiprocess_child(sys.argv[2], int(sys.argv[3]), sys.argv[4], sys.argv[5])
elif __name__ == "__main__" and sys.argv[1:2] == ["train-slowly"]:
    _train_slowly_child(sys.argv[2])
