"""Run-folder locks: a folder another live harv-jax process writes is refused (``--force``, ``--resume``,
``report``), nothing is deleted, and a dead process's lock is reported and taken over."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from cli_util import cli_run

from harv_jax import runlock
from harv_jax.atomic import write_text
from harv_jax.errors import UsageError
from harv_jax.manifest import MANIFEST
from harv_jax.outdir import MARKER, prepare_out_dir

REPO = Path(__file__).resolve().parents[1]

#: A harv-jax writer that holds its run folder until its stdin closes.
HOLDER = textwrap.dedent(
    """
    import sys
    from harv_jax.atomic import write_text
    from harv_jax.outdir import prepare_out_dir
    out = prepare_out_dir(sys.argv[1], force=len(sys.argv) > 2)
    write_text(out / "notes.md", "mine")
    print("ready", flush=True)
    sys.stdin.read()
    """
)


def _start_holder(folder: Path, *extra: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(folder), *extra], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, cwd=REPO)  # fmt: skip
    assert proc.stdout.readline().strip() == "ready"
    return proc


def test_force_refuses_a_folder_another_live_process_writes(tmp_path, monkeypatch, capsys):
    run = tmp_path / "run"
    proc = _start_holder(run)
    try:
        holder = runlock.read_holder(run)
        assert holder["pid"] == proc.pid
        code, _, err = cli_run(monkeypatch, capsys, "simulate", "--out", run, "--force", "--duration", "1")
        assert code == 2
        line = err.strip()
        assert "\n" not in line and "Traceback" not in err
        assert f"is in use by harv-jax PID {proc.pid}" in line
        assert (run / "notes.md").read_text() == "mine"  # nothing deleted
        with pytest.raises(UsageError, match=f"PID {proc.pid}"):
            prepare_out_dir(run, force=True)
        assert (run / "notes.md").read_text() == "mine"
    finally:
        proc.stdin.close()
        proc.wait(timeout=60)
    assert proc.returncode == 0
    assert runlock.read_holder(run) is None  # released at exit
    out = prepare_out_dir(run, force=True)  # free now: replaced
    assert not (out / "notes.md").exists() and (out / MARKER).is_file()
    runlock.release(out)


def test_resume_and_report_refuse_a_held_folder(tmp_path, monkeypatch, capsys):
    run = tmp_path / "run"
    proc = _start_holder(run)
    try:
        code, _, err = cli_run(monkeypatch, capsys, "train", "--resume", run)
        assert code == 2 and err.count("\n") == 1
        assert f"--resume {str(run)!r} is in use by harv-jax PID {proc.pid}" in err
        code, _, err = cli_run(monkeypatch, capsys, "report", run)
        assert code == 2 and err.count("\n") == 1 and f"PID {proc.pid}" in err
        assert not (run / "report.md").exists()
    finally:
        proc.stdin.close()
        proc.wait(timeout=60)


def test_a_killed_holders_stale_lock_is_named_and_taken_over(tmp_path, capsys):
    run = tmp_path / "run"
    proc = _start_holder(run)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    assert runlock.read_holder(run)["pid"] == proc.pid  # left behind by the killed process
    assert runlock.is_held_by_other(run) is None  # the kernel released the lock itself
    out = prepare_out_dir(run, force=True)
    err = capsys.readouterr().err
    assert f"had a stale lock of PID {proc.pid}" in err and "no longer running; taken over" in err
    assert runlock.read_holder(out)["pid"] == os.getpid()
    assert not (out / "notes.md").exists()
    runlock.release(out)
    assert runlock.read_holder(out) is None


def test_lock_files_are_kept_when_force_empties_a_folder(tmp_path):
    run = prepare_out_dir(tmp_path / "run")
    write_text(run / "old.csv", "x")
    runlock.release(run)
    run = prepare_out_dir(run, force=True)
    assert sorted(p.name for p in run.iterdir()) == sorted([MARKER, MANIFEST, *runlock.LOCK_FILES])
    assert json.loads((run / runlock.HOLDER_NAME).read_text())["pid"] == os.getpid()
    runlock.release(run)


TINY_PRESET = """
[ppo]
total_steps = 400000
num_envs = 16
unroll = 16
epochs = 1
minibatches = 2
hidden_sizes = [16]
num_seeds = 1
num_periods = 40
checkpoint_every = 1
[env]
episode_steps = 100
domain_randomization = false
"""


@pytest.mark.slow
def test_live_train_and_a_second_command_with_force(tmp_path):
    """A real ``harv-jax train``; ``simulate --force`` on its folder exits 2 naming it; the training ends
    with all its files."""
    preset = tmp_path / "tiny.toml"
    preset.write_text(TINY_PRESET)
    run = tmp_path / "run"
    cmd = [sys.executable, "-m", "harv_jax.cli", "train", "--preset", str(preset), "--out", str(run)]
    train = subprocess.Popen(cmd, cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 600
    while runlock.read_holder(run) is None:
        assert train.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)
    second = subprocess.run([sys.executable, "-m", "harv_jax.cli", "simulate", "--out", str(run), "--force"],
                            cwd=REPO, text=True, capture_output=True, timeout=300)  # fmt: skip
    assert second.returncode == 2
    assert second.stderr.count("\n") == 1 and f"PID {train.pid}" in second.stderr
    _, err = train.communicate(timeout=900)
    assert train.returncode == 0, err[-3000:]
    for name in ("config.json", "metrics.csv", "summary.json", "tb", "checkpoints", MARKER):
        assert (run / name).exists(), name
