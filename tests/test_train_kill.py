"""Training reliability: resume past a damaged checkpoint, restart of a run killed before its first
checkpoint, SIGKILL of a real ``harv-jax train`` process (slow), the stall watchdog, the new train flags."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import chex
import jax
import numpy as np
import pytest
from cli_util import cli_run
from flax import serialization
from test_train import CFG, TOY_PARAMS, ToyEnv

from harv_jax.errors import UsageError
from harv_jax.ppo import checkpoint
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo.runner import run_training
from harv_jax.ppo.train import make_train
from harv_jax.ppo.watchdog import Watchdog
from harv_jax.training.resume import resume_plan

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def trainer():
    return make_train(ToyEnv(), CFG, TOY_PARAMS)


@pytest.fixture(scope="module")
def full_run(trainer, tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("full")
    res = run_training(jax.random.key(CFG.seed), ToyEnv(), TOY_PARAMS, CFG, run_dir=run_dir, trainer=trainer)
    return res, run_dir


def _host_state(state):
    state = jax.device_get(state)
    return state.replace(key=jax.random.key_data(state.key))


def _run(trainer, run_dir, **kw):
    return run_training(jax.random.key(CFG.seed), ToyEnv(), TOY_PARAMS, CFG, run_dir=run_dir, trainer=trainer,
                        **kw)  # fmt: skip


# ---------------------------------------------------------------------------------------------- checkpoints


def test_torn_newest_checkpoint_falls_back_to_the_previous_one(trainer, full_run, tmp_path):
    full, _ = full_run
    _run(trainer, tmp_path, stop_after_periods=3)
    ckpts = tmp_path / "checkpoints"
    newest = ckpts / "ckpt_000003.msgpack"
    newest.write_bytes(newest.read_bytes()[: newest.stat().st_size // 2])  # torn: half of the file
    (ckpts / ".tmp-999999-ckpt_000004.msgpack").write_bytes(b"partial")  # left by a killed save
    choice = checkpoint.latest_intact(ckpts)
    assert choice.path.name == "ckpt_000002.msgpack"
    assert [p.name for p, _ in choice.skipped] == ["ckpt_000003.msgpack"]
    assert "unreadable" in choice.skipped[0][1]
    resumed = _run(trainer, tmp_path, resume=True)
    chex.assert_trees_all_equal(_host_state(full.state), _host_state(resumed.state))  # bit-exact
    assert len(resumed.history) == ppo_config.num_periods(CFG)
    # the torn file is kept aside, the stale temporary file is gone, the newest two are the new ones
    names = sorted(p.name for p in ckpts.iterdir())
    assert names == ["ckpt_000003.msgpack", "ckpt_000003.msgpack.corrupt", "ckpt_000004.msgpack"]
    assert checkpoint.read(ckpts / "ckpt_000004.msgpack")["period"] == 4


def test_checksum_catches_damage_that_still_parses(full_run, tmp_path):
    _, run_dir = full_run
    src = checkpoint.checkpoint_paths(run_dir / "checkpoints")[-1]
    payload = serialization.msgpack_restore(src.read_bytes())
    leaf = np.array(payload["leaves"]["0"])
    leaf.flat[0] += 1.0  # one changed parameter; the stored checksum is the old one
    payload["leaves"]["0"] = leaf
    bad = tmp_path / src.name
    bad.write_bytes(serialization.msgpack_serialize(payload))
    with pytest.raises(UsageError, match=r"is corrupt \(its checksum"):
        checkpoint.read(bad)
    # every checkpoint damaged: one line saying so, nothing loaded
    (tmp_path / "ckpt_000001.msgpack").write_bytes(b"")
    with pytest.raises(UsageError, match=r"none of the 2 checkpoint\(s\) .* is intact"):
        checkpoint.latest_intact(tmp_path)
    assert checkpoint.latest_intact(tmp_path / "absent") is None


def test_resume_plan_messages(full_run, tmp_path):
    _, run_dir = full_run
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    files = checkpoint.checkpoint_paths(run_dir / "checkpoints")
    for f in files:
        (run / "checkpoints" / f.name).write_bytes(f.read_bytes())
    (run / "checkpoints" / files[-1].name).write_bytes(b"\x00" * 10)
    plan = resume_plan(run)
    assert plan.from_checkpoint and plan.period == 3 and plan.spec.ppo == CFG
    assert plan.messages[0].startswith(f"skipping checkpoint {files[-1].name}: ")
    steps = 3 * ppo_config.steps_per_period(CFG)
    assert f"resuming from period 3 (env steps {steps:,})" in plan.messages[-1]
    # killed before the first checkpoint: restart from period 0 with config.json
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    (fresh / "config.json").write_text(json.dumps({"preset": "x", "ppo": ppo_config.to_dict(CFG), "env": {}}))
    plan = resume_plan(fresh)
    assert not plan.from_checkpoint and plan.period == 0 and plan.spec.ppo == CFG
    assert "restarting it from period 0" in plan.messages[0]
    (fresh / "config.json").write_text("{not json")
    with pytest.raises(UsageError, match="config.json' is unreadable .*--force"):
        resume_plan(fresh)
    with pytest.raises(UsageError, match="no checkpoint found .* not a harv-jax train run folder"):
        resume_plan(tmp_path)


# ---------------------------------------------------------------------------------------------- watchdog


def _watch(**kw) -> tuple[Watchdog, threading.Event, list[str]]:
    fired, reasons = threading.Event(), []
    dog = Watchdog(lambda r: (reasons.append(r), fired.set()), poll_s=0.1, backstop_s=None, **kw)
    return dog, fired, reasons


def _spin(seconds: float) -> None:
    t = time.monotonic()
    while time.monotonic() - t < seconds:
        sum(i * i for i in range(1000))


def test_watchdog_wall_limit_and_beats():
    # limit 12x the beat interval: on a shared 2-core VM under the full suite, a 0.6 s limit with beats every
    # 0.2 s fired once (two beats more than 0.6 s apart)
    dog, fired, reasons = _watch(limit_s=1.2, idle_s=0)
    with dog:
        for _ in range(16):  # progress every 0.1 s keeps it quiet
            _spin(0.1)
            dog.beat()
        assert not fired.is_set()
        assert fired.wait(5.0)  # no more beats: stall after 1.2 s
    assert "no progress for" in reasons[0] and "limit 1 s" in reasons[0]


def test_watchdog_no_cpu_use_is_a_stall_busy_is_not():
    dog, fired, reasons = _watch(limit_s=0, idle_s=1.0)
    with dog:
        _spin(3.0)  # busy: not a stall however long
        assert not fired.is_set()
        assert fired.wait(10.0)  # this thread now waits without using CPU: a stall after 1 s
    assert "no CPU use" in reasons[0]


def test_watchdog_ignores_busy_helper_threads():
    """A busy Python helper thread (like the progress display's refresh) does not hide an idle main thread."""
    stop = threading.Event()

    def busy() -> None:
        while not stop.is_set():
            _spin(0.05)

    helper = threading.Thread(target=busy, daemon=True)
    helper.start()
    try:
        dog, fired, reasons = _watch(limit_s=0, idle_s=1.0)
        with dog:
            assert fired.wait(10.0)
        assert "no CPU use" in reasons[0]
    finally:
        stop.set()
        helper.join()


def test_watchdog_backstop_ends_the_process():
    """If the watchdog thread cannot act (here: its handler does nothing), faulthandler ends the process."""
    code = ("import time; from harv_jax.ppo.watchdog import Watchdog; "
            "Watchdog(lambda r: None, limit_s=0.5, idle_s=0, poll_s=0.1, backstop_s=0.5).start(); "
            "time.sleep(30)")  # fmt: skip
    t0 = time.monotonic()
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert r.returncode == 1 and "Timeout (0:00:01)!" in r.stderr, r.stderr
    assert time.monotonic() - t0 < 25


def test_watchdog_automatic_limit():
    dog, _, _ = _watch(first_limit_s=100.0, min_limit_s=7.0)
    dog._t_start = time.monotonic() - 2.0
    assert dog.current_limit_s() == 100.0  # before the first period (compilation included)
    dog.beat()  # first period took ~2 s
    assert math.isclose(dog.current_limit_s(), 40.0, rel_tol=0.01)  # 20 x the first period
    dog2, _, _ = _watch(first_limit_s=100.0, min_limit_s=7.0)
    dog2._t_start = time.monotonic() - 0.1
    dog2.beat()
    assert dog2.current_limit_s() == 7.0
    with pytest.raises(ValueError, match="limit_s -1 must be"):
        Watchdog(print, limit_s=-1)


# ---------------------------------------------------------------------------------------------- CLI flags


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--periods", "0", "--out", "{tmp}/o"], "--periods 0 must be a positive integer"),
        (["--checkpoint-every", "-2", "--out", "{tmp}/o"], "--checkpoint-every -2 must be a positive"),
        (["--watchdog-s", "-1", "--out", "{tmp}/o"], "--watchdog-s -1.0 must be a finite number"),
        (["--watchdog-s", "nan", "--out", "{tmp}/o"], "--watchdog-s nan must be a finite number"),
        (
            ["--steps", "4096", "--num-envs", "16", "--periods", "99", "--out", "{tmp}/o"],
            "--periods 99 exceeds the 8 PPO updates",
        ),  # fmt: skip
        (["--resume", "{tmp}", "--steps", "100"], "drop --steps"),  # not the absent --total-steps
        (["--resume", "{tmp}", "--periods", "3"], "drop --periods"),
        (["--resume", "{tmp}", "--seeds", "3"], "drop --seeds"),
        (["--resume", "{tmp}"], "no checkpoint found"),
    ],
)
def test_train_flags_one_line_errors(monkeypatch, capsys, tmp_path, args, message):
    code, _, err = cli_run(monkeypatch, capsys, "train", *[a.replace("{tmp}", str(tmp_path)) for a in args])
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("harv-jax: error:"), err
    assert message in lines[0]
    assert not (tmp_path / "o").exists()


def test_train_help_shows_preset_defaults(monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "200")
    code, out, _ = cli_run(monkeypatch, capsys, "train", "--help")
    assert code == 0
    text = " ".join(out.replace("│", " ").split())  # the help's box borders out of wrapped lines
    assert "Default from --preset: robust 4,000,000, fast 8,000,000, paper-full 120,000,000" in text
    assert "paper-partial 10,000,000, recovery 8,000,000, smoke 600,000, teacher 4,000,000" in text
    assert "(robust, fast, paper-full, paper-partial, recovery, smoke, teacher)" in text  # the default first
    assert "--periods" in text and "--checkpoint-every" in text and "--watchdog-s" in text
    assert "[@seed]" in text


def test_cli_train_uses_one_host_device_per_core(monkeypatch):
    """train gets the host devices every command gets (the Monte Carlo and envelope maps shard over them)."""
    from harv_jax import cli

    monkeypatch.setenv("XLA_FLAGS", "")
    cli.use_all_cpu_cores()
    assert "--xla_force_host_platform_device_count=" in __import__("os").environ["XLA_FLAGS"]
    assert not hasattr(cli, "ONE_HOST_DEVICE_COMMANDS")


# --------------------------------------------------------------------------------------------- real processes

TINY_PRESET = """
[ppo]
total_steps = 204_800        # 8 periods of 200 updates of 8 envs x 16 steps: ~1 s each on a CPU core
num_envs = 8
unroll = 16
epochs = 1
minibatches = 2
lr = 1e-3
hidden_sizes = [16]
num_seeds = 1
num_periods = 8
checkpoint_every = 1
[env]
episode_steps = 100
domain_randomization = false
"""


def _train_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "harv_jax.cli", "train", *args]


def _final_leaves(run: Path) -> dict[str, np.ndarray]:
    payload = checkpoint.read(checkpoint.checkpoint_paths(run / "checkpoints")[-1])
    assert payload["period"] == 8
    return {k: np.asarray(v) for k, v in payload["leaves"].items()}


def _assert_same_final_state(a: Path, b: Path) -> None:
    la, lb = _final_leaves(a), _final_leaves(b)
    assert la.keys() == lb.keys()
    for k in la:
        np.testing.assert_array_equal(la[k], lb[k], err_msg=f"leaf {k}")


def _wait_for(cond, proc: subprocess.Popen, timeout_s: float = 600) -> None:
    deadline = time.monotonic() + timeout_s
    while not cond():
        assert proc.poll() is None, proc.communicate()[1][-3000:]
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


def _resume(run: Path) -> str:
    cmd = _train_cmd("--resume", str(run))
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return r.stderr


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> tuple[Path, Path]:
    """(preset file, an uninterrupted run of it)."""
    d = tmp_path_factory.mktemp("tiny")
    preset = d / "tiny.toml"
    preset.write_text(TINY_PRESET)
    run = d / "uninterrupted"
    r = subprocess.run(_train_cmd("--preset", str(preset), "--out", str(run)), capture_output=True, text=True,
                       cwd=REPO, timeout=900)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    return preset, run


@pytest.mark.slow
def test_sigkill_mid_period_then_resume_is_bit_exact(tiny, tmp_path):
    preset, reference = tiny
    run = tmp_path / "run"
    proc = subprocess.Popen(_train_cmd("--preset", str(preset), "--out", str(run)), cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    _wait_for(lambda: checkpoint.checkpoint_paths(run / "checkpoints"), proc)
    time.sleep(0.4)  # inside period 2 or 3 (each ~1 s)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done = checkpoint.checkpoint_paths(run / "checkpoints")
    assert done and checkpoint.read(done[-1])["period"] < 8  # killed before the end
    period = checkpoint.read(done[-1])["period"]
    err = _resume(run)
    assert f"resuming from period {period} (env steps" in err
    _assert_same_final_state(reference, run)


@pytest.mark.slow
def test_sigkill_before_first_checkpoint_then_resume_restarts(tiny, tmp_path):
    preset, reference = tiny
    run = tmp_path / "run"
    proc = subprocess.Popen(_train_cmd("--preset", str(preset), "--out", str(run)), cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    _wait_for(lambda: (run / "config.json").is_file(), proc)  # the folder exists, compilation is under way
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert not checkpoint.checkpoint_paths(run / "checkpoints")
    err = _resume(run)
    assert "restarting it from period 0" in err
    _assert_same_final_state(reference, run)


@pytest.mark.slow
def test_torn_newest_checkpoint_then_resume_falls_back(tiny, tmp_path):
    preset, reference = tiny
    run = tmp_path / "run"
    r = subprocess.run(_train_cmd("--preset", str(preset), "--out", str(run), "--checkpoint-every", "3"),
                       capture_output=True, text=True, cwd=REPO, timeout=900)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    names = [p.name for p in checkpoint.checkpoint_paths(run / "checkpoints")]
    assert names == ["ckpt_000006.msgpack", "ckpt_000008.msgpack"]  # --checkpoint-every 3, and the last
    newest = run / "checkpoints" / names[-1]
    newest.write_bytes(newest.read_bytes()[:1000])  # truncated
    err = _resume(run)
    assert "skipping checkpoint ckpt_000008.msgpack: is unreadable" in err
    assert "resuming from period 6 (env steps" in err
    assert (run / "checkpoints" / "ckpt_000008.msgpack.corrupt").is_file()
    _assert_same_final_state(reference, run)


@pytest.mark.slow
def test_watchdog_stops_a_stalled_cli_run(tiny, tmp_path):
    """A watchdog limit shorter than compilation: the run stops with exit 3 and one line."""
    preset, _ = tiny
    run = tmp_path / "run"
    r = subprocess.run(_train_cmd("--preset", str(preset), "--out", str(run), "--watchdog-s", "0.5"),
                       capture_output=True, text=True, cwd=REPO, timeout=900)  # fmt: skip
    assert r.returncode == 3, r.stderr[-3000:]
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("harv-jax: error: training stalled: no progress for")
    assert "no checkpoint written yet: continue with harv-jax train --resume" in last
    assert (run / "stall_traceback.txt").read_text().count("File ") > 0
