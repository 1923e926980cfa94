"""Demonstrations as a behaviour-cloning source (``harv-jax train --demos``): the BC term on demo pairs
against hand-worked numbers, the minibatch draw, a toy training run (reproducible, clones the demos), the
CLI run on the real env, and every bad input (one line, exit code 2, no run folder)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cli_util import cli_run
from test_train import CFG, TOY_PARAMS, ToyEnv

from harv_jax import policy as policy_api
from harv_jax.errors import UsageError
from harv_jax.optimal.demos import FORMAT_NAME, FORMAT_VERSION, make_demos, save_demos
from harv_jax.ppo.loss_terms import (
    BehaviourCloning,
    DemoBatch,
    behaviour_cloning,
    sample_minibatches,
    terms_from_config,
)
from harv_jax.ppo.losses import LossWeights, PPOBatch, PPOLossSettings, ppo_loss
from harv_jax.ppo.networks import gaussian_log_prob, make_ppo_networks
from harv_jax.ppo.runner import run_training
from harv_jax.ppo.train import make_train
from harv_jax.training.demos import load_run_demos
from harv_jax.training.outputs import export_seed_policies
from harv_jax.training.spec import TrainSpec
from harv_jax.training.start import write_run_record

SMOKE = (Path(__file__).resolve().parents[1] / "harv_jax/training/presets/smoke.toml").read_text()


def write_demos(path: Path, n: int = 2, t: int = 5, recovered: tuple[bool, ...] = (True, False)) -> Path:
    """A tiny demos file written with ``optimal.demos``'s writer (states near level flight)."""
    rng = np.random.default_rng(0)
    x = np.zeros((n, t + 1, 10), np.float32)
    x[..., 0] = 600.0
    x[..., 1:9] = rng.normal(0.0, 0.1, (n, t + 1, 8))
    x[..., 9] = 20000.0
    cmd = rng.uniform(-0.2, 0.2, (n, t, 3)).astype(np.float32)
    lim = np.full(3, 0.4, np.float32)
    rec = np.asarray(recovered, bool)
    d = make_demos(x, cmd, np.zeros(3), -lim, lim, np.where(rec, 3.0, np.nan), rec, np.zeros(n, bool), 0.01)
    return save_demos(path, d)


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def smoke_preset(tmp_path: Path, extra: str = "bc_coef = 1.0\n") -> Path:
    """The smoke preset with behaviour cloning on (``extra`` goes into its [ppo] table)."""
    p = tmp_path / "smoke_bc.toml"
    p.write_text(SMOKE.replace("[ppo]\n", f"[ppo]\n{extra}", 1))
    return p


# ------------------------------------------------------------------------------------------- the loss


def test_bc_formula_equals_a_hand_worked_number():
    mean = jnp.asarray([[0.5, 1.5, -2.0], [0.0, 0.0, 0.0]], jnp.float32)
    target = jnp.asarray([[0.0, 1.0, -1.0], [0.2, -0.4, 1.0]], jnp.float32)
    # row 1: clipped error (0.5, 0, 0) -> 0.25; unclipped (0.5, 0.5, -1) -> 1.5 * 0.01; 0.265
    # row 2: (-0.2, 0.4, -1) both -> 1.2 + 0.012 = 1.212; mean 0.7385
    assert float(behaviour_cloning(mean, target)) == pytest.approx(0.7385, rel=1e-6)


def _batch(nets, params, teacher, n=4):
    obs = jnp.asarray(np.random.default_rng(0).normal(size=(n, nets.observation_size)), jnp.float32)
    mean, log_std = nets.policy(params, obs)
    zeros = jnp.zeros((n,), jnp.float32)
    return PPOBatch(
        obs,
        mean,
        gaussian_log_prob(mean, log_std, mean),
        zeros,
        jnp.arange(n, dtype=jnp.float32),
        zeros,
        (teacher,),
    )


NO_VALUE = PPOLossSettings(vf_coef=0.0)


def _bc(params, batch, nets, label_key, demo):
    """PPO loss (no value term) plus behaviour cloning with weight 2 toward the batch's labels and/or a
    minibatch sample ``demo``."""
    term = BehaviourCloning(
        2.0, 2.0, label_key=label_key, demos=None if demo is None else (demo.obs, demo.action)
    )
    batch = batch._replace(term_samples=(demo,))
    return ppo_loss(params, batch, nets, NO_VALUE, (term,), LossWeights(None, (jnp.asarray(2.0),)))


def test_bc_on_demos_in_the_ppo_loss_equals_the_formula_and_adds_to_the_teachers():
    nets = make_ppo_networks(5, 3, (8,), -0.5)
    params = nets.init(jax.random.key(1))
    demo_obs = jnp.asarray(np.random.default_rng(1).normal(size=(3, 5)), jnp.float32)
    demo = DemoBatch(
        demo_obs, jnp.asarray([[0.5, -0.5, 0.0], [1.0, 1.0, -1.0], [0.0, 0.2, 0.9]], jnp.float32)
    )
    mu = np.asarray(nets.policy(params, demo_obs)[0], np.float64)
    y = np.asarray(demo.action, np.float64)
    want = np.mean(np.sum((np.clip(mu, -1, 1) - y) ** 2 + 0.01 * (mu - y) ** 2, axis=-1))
    plain = _batch(nets, params, None)
    total_0, _ = ppo_loss(params, plain._replace(term_data=()), nets, NO_VALUE)
    total, m = _bc(params, plain, nets, None, demo)
    np.testing.assert_allclose(float(m["bc_demo_loss"]), want, rtol=1e-5)
    np.testing.assert_allclose(float(total - total_0), 2.0 * want, rtol=1e-4, atol=1e-6)
    assert "bc_loss" not in m  # no teacher labels: the demo term alone
    teacher = jnp.full((4, 3), 0.3, jnp.float32)
    both, mb = _bc(params, _batch(nets, params, teacher), nets, "teacher_action", demo)
    only_t, mt = _bc(params, _batch(nets, params, teacher), nets, "teacher_action", None)
    assert float(mb["bc_loss"]) == float(mt["bc_loss"])
    np.testing.assert_allclose(float(both - only_t), 2.0 * want, rtol=1e-4, atol=1e-6)


def test_demo_minibatches_are_pairs_through_the_normalizer_and_reproducible():
    obs = np.arange(20, dtype=np.float32).reshape(10, 2)
    demo = DemoBatch(jnp.asarray(obs), jnp.asarray(obs[:, :1] * 10.0))
    key = jax.random.key(3)
    got = sample_minibatches(key, demo, (2, 3, 4), lambda o: o - 1.0)
    assert got.obs.shape == (2, 3, 4, 2) and got.action.shape == (2, 3, 4, 1)
    np.testing.assert_array_equal(np.asarray(got.obs[..., :1] + 1.0) * 10.0, np.asarray(got.action))
    again = sample_minibatches(key, demo, (2, 3, 4), lambda o: o - 1.0)
    np.testing.assert_array_equal(np.asarray(got.obs), np.asarray(again.obs))


# ------------------------------------------------------------------------------------------ toy training


def _toy_demos(n: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """The toy env's expert: a = clip(-x / gain, -1, 1) at random positions."""
    x = np.random.default_rng(5).uniform(-1.0, 1.0, (n, 3)).astype(np.float32)
    obs = np.concatenate([x, np.zeros((n, 1), np.float32)], axis=1)
    return obs, np.clip(-x / float(TOY_PARAMS.gain), -1.0, 1.0)


@pytest.mark.slow
def test_training_from_demos_alone_clones_them_is_reproducible_and_recorded(tmp_path):
    cfg = dataclasses.replace(
        CFG,
        total_steps=16 * 8 * 6,
        num_envs=16,
        unroll=8,
        minibatches=2,
        num_periods=2,
        bc_coef=1.0,
        bc_coef_end=1.0,
    )
    demos = _toy_demos()
    trainer = make_train(ToyEnv(), cfg, TOY_PARAMS, terms=terms_from_config(cfg, demos=demos))
    runs = [
        run_training(jax.random.key(cfg.seed), ToyEnv(), TOY_PARAMS, cfg, trainer=trainer) for _ in range(2)
    ]
    a, b = (jax.device_get(r.state.params) for r in runs)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(x, y)  # same seed: the same policy bit for bit
    first, last = (np.asarray(r["bc_demo_loss"]) for r in (runs[0].history[0], runs[0].history[-1]))
    assert first.shape == (cfg.num_seeds,) and np.all(last < first)
    with pytest.raises(ValueError, match="the env has 4 and 3"):
        make_train(ToyEnv(), cfg, TOY_PARAMS, terms=terms_from_config(cfg, demos=(demos[0][:, :3], demos[1])))
    record = {"path": "/d.npz", "sha256": "ab" * 32, "runs": 2, "runs_in_file": 3, "pairs": 256}
    (pol,) = export_seed_policies(tmp_path, runs[0].state, trainer, cfg.replace(num_seeds=1), 1, demos=record)
    assert policy_api.load(tmp_path / "policy_seed0.npz").meta["demos"] == record == pol.meta["demos"]
    spec = TrainSpec.from_settings("smoke", cfg.replace(demos="/d.npz"), {})
    write_run_record(tmp_path, spec, None, demos=_Recorded(record))
    config = json.loads((tmp_path / "config.json").read_text())
    assert config["demos"] == record and config["ppo"]["demos"] == "/d.npz"


class _Recorded:
    """Stands in for a RunDemos: only its record is written."""

    def __init__(self, record: dict) -> None:
        self._record = record

    def record(self) -> dict:
        return self._record


# ------------------------------------------------------------------------------------------ loading


def test_loader_keeps_the_recovered_runs_and_records_the_file(tmp_path):
    path = write_demos(tmp_path / "d.npz", n=3, t=4, recovered=(True, False, True))
    d = load_run_demos(str(path), 11, 3)
    assert d.observations.shape == (8, 11) and d.actions.shape == (8, 3) and d.runs == 2
    rec = d.record()
    assert rec["path"] == str(path) and rec["runs_in_file"] == 3 and rec["pairs"] == 8
    assert len(rec["sha256"]) == 64
    with pytest.raises(UsageError, match="changed since the run started"):
        load_run_demos(str(path), 11, 3, expect_sha256="0" * 64)


def test_a_relative_preset_path_is_the_preset_folders(tmp_path, monkeypatch):
    from harv_jax.training.presets import load_preset

    monkeypatch.chdir(Path(__file__).parent)
    cfg, _ = load_preset(str(smoke_preset(tmp_path, 'bc_coef = 1.0\ndemos = "sub/d.npz"\n')))
    assert cfg.demos == str(tmp_path / "sub" / "d.npz")


# ---------------------------------------------------------------------------------------------- CLI


def _train(monkeypatch, capsys, tmp_path, *args):
    flags = [
        "--steps",
        "1024",
        "--num-envs",
        "16",
        "--minibatches",
        "4",
        "--periods",
        "1",
        "--watchdog-s",
        "0",
    ]
    return cli_run(monkeypatch, capsys, "train", "--preset", smoke_preset(tmp_path), *flags, *args)


@pytest.mark.slow
def test_cli_trains_from_demos_and_records_them(tmp_path, monkeypatch, capsys):
    demos = write_demos(tmp_path / "d.npz")
    code, out, err = _train(monkeypatch, capsys, tmp_path, "--demos", demos, "--out", tmp_path / "run")
    assert code == 0, err[-2000:]
    record = {"path": str(demos), "runs": 1, "runs_in_file": 2, "pairs": 5}
    config = json.loads((tmp_path / "run" / "config.json").read_text())
    assert config["ppo"]["demos"] == str(demos) and record.items() <= config["demos"].items()
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["demos"] == config["demos"]
    assert policy_api.load(tmp_path / "run").meta["demos"] == config["demos"]
    assert "bc_demo_loss" in (tmp_path / "run" / "metrics.csv").read_text().splitlines()[0]


@pytest.mark.slow
def test_cli_same_seed_twice_gives_the_same_policy(tmp_path, monkeypatch, capsys):
    demos = write_demos(tmp_path / "d.npz")
    for run in ("a", "b"):
        code, _, err = _train(monkeypatch, capsys, tmp_path, "--demos", demos, "--out", tmp_path / run)
        assert code == 0, err[-2000:]
    a, b = (_arrays(tmp_path / run / "policy" / "policy.npz") for run in ("a", "b"))
    assert a.keys() == b.keys()
    for k in a:
        np.testing.assert_array_equal(a[k], b[k], err_msg=k)


def _bad(tmp_path: Path, name: str, drop: tuple[str, ...] = (), **changes) -> Path:
    arrays = {**_arrays(write_demos(tmp_path / "good.npz")), **changes}
    np.savez(tmp_path / name, **{k: v for k, v in arrays.items() if k not in drop})
    return tmp_path / name


def _bad_inputs(tmp_path: Path) -> dict[str, tuple[list, str]]:
    good = _arrays(write_demos(tmp_path / "good.npz"))
    n, t = good["actions"].shape[:2]
    (tmp_path / "text.npz").write_text("not a zip\n")
    np.save(tmp_path / "pickled.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    obs12 = np.zeros((n, t, 12), np.float32)
    nan_obs = good["observations"].copy()
    nan_obs[0, 0, 0] = np.nan
    return {
        "missing": (["--demos", tmp_path / "nope.npz"], "does not exist; give a file written by harv-jax"),
        "not npz": (["--demos", tmp_path / "text.npz"], "is not a pickle-free npz file"),
        "pickle": (["--demos", tmp_path / "pickled.npy"], "is not a pickle-free npz file"),
        "malformed": (["--demos", _bad(tmp_path, "m.npz", format=None)], "is not a pickle-free npz file"),
        "lacks": (["--demos", _bad(tmp_path, "l.npz", drop=("dt_s",))], "lacks dt_s"),
        "format": (["--demos", _bad(tmp_path, "f.npz", format=np.array("x"))], "format 'x', expected"),
        "version": (
            ["--demos", _bad(tmp_path, "v.npz", format_version=np.array(FORMAT_VERSION + 1))],
            f"this reader reads {FORMAT_VERSION}",
        ),
        "obs size": (
            ["--demos", _bad(tmp_path, "o.npz", observations=obs12)],
            f"observations has shape [{n}, {t}, 12], expected [{n}, {t}, 11]",
        ),
        "action size": (
            ["--demos", _bad(tmp_path, "a.npz", actions=np.zeros((n, t, 2), np.float32))],
            f"actions has shape [{n}, {t}, 2], expected [{n}, {t}, 3]",
        ),
        "non-finite": (["--demos", _bad(tmp_path, "n.npz", observations=nan_obs)], "non-finite"),
        "range": (
            ["--demos", _bad(tmp_path, "r.npz", actions=good["actions"] * 0 + 1.5)],
            "actions lie outside [-1, 1]",
        ),
        "no recovered": (
            ["--demos", _bad(tmp_path, "u.npz", recovered=np.zeros(n, bool))],
            "hold no recovered run",
        ),
        "empty": (["--demos", ""], "must be the path of a demonstrations .npz file"),
        "resume": (
            ["--demos", tmp_path / "good.npz", "--resume", tmp_path / "run"],
            "--resume continues the stored configuration; drop --demos",
        ),
    }


def test_every_bad_demos_input_is_one_line_exit_2_and_no_run_folder(tmp_path, monkeypatch, capsys):
    assert FORMAT_NAME == "harv_jax.optimal.demos"
    for case, (args, message) in _bad_inputs(tmp_path).items():
        if "--resume" in args:
            code, _, err = cli_run(monkeypatch, capsys, "train", *args)
        else:
            code, _, err = _train(monkeypatch, capsys, tmp_path, *args, "--out", tmp_path / "run")
        assert code == 2 and err.count("\n") == 1 and message in err, (case, err)
        assert not (tmp_path / "run").exists(), case


def test_demos_without_behaviour_cloning_is_refused(tmp_path, monkeypatch, capsys):
    demos = write_demos(tmp_path / "d.npz")
    args = ["--preset", "smoke", "--demos", demos, "--out", tmp_path / "run"]
    code, _, err = cli_run(monkeypatch, capsys, "train", *args)
    assert code == 2 and err.count("\n") == 1 and "bc_coef and bc_coef_end are 0" in err, err
    assert not (tmp_path / "run").exists()


def test_resume_refuses_demos_that_changed_since_the_run_started(tmp_path, monkeypatch, capsys):
    from harv_jax.ppo import config as ppo_config
    from harv_jax.training.presets import load_preset

    demos = write_demos(tmp_path / "d.npz")
    cfg, env = load_preset(str(smoke_preset(tmp_path)))
    record = {
        "preset": "smoke",
        "ppo": ppo_config.to_dict(cfg.replace(demos=str(demos))),
        "env": env,
        "demos": {"path": str(demos), "sha256": "0" * 64, "runs": 1, "runs_in_file": 2, "pairs": 5},
    }
    run = tmp_path / "run"
    run.mkdir()
    (run / "config.json").write_text(json.dumps(record))
    code, _, err = cli_run(monkeypatch, capsys, "train", "--resume", run)
    assert code == 2 and err.count("\n") == 1 and "changed since the run started" in err, err
