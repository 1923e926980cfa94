"""Nothing a user made is lost: ``--force`` never deletes what the command reads nor what harv-jax did not
write; every output is written atomically and listed in the folder's manifest; an interrupted command says
so, exits 130 / 143 and leaves a folder marked incomplete (real processes, synchronized on their output)."""

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

from harv_jax import atomic, manifest, outdir, runlock
from harv_jax.manifest import MANIFEST, MARKER

REPO = Path(__file__).resolve().parents[1]
SIM = ("simulate", "--duration", "0.05")


def _tree(root: Path) -> dict[str, bytes | None]:
    return {str(p.relative_to(root)): (None if p.is_dir() else p.read_bytes()) for p in root.rglob("*")}


@pytest.fixture
def train_run(tmp_path_factory) -> Path:
    """A folder shaped like a training run (policy, checkpoints, TensorBoard events), written through the
    same API a training run uses, with a user's notes beside it."""
    from harv_jax import policy

    d = tmp_path_factory.mktemp("run") / "D"
    run = outdir.prepare_out_dir(d)
    (run / "policy").mkdir()
    atomic.write_bytes(run / "policy" / "policy.npz", policy.shipped_path().read_bytes())
    (run / "checkpoints").mkdir()
    (run / "checkpoints" / "ckpt_000001.msgpack").write_bytes(b"ckpt")
    (run / "tb").mkdir()
    (run / "tb" / "events.out.tfevents.1.host").write_bytes(b"events")
    outdir.finish_all()
    runlock.release(run)
    manifest.forget(run)
    return run


# ------------------------------------------------------------------------------ read before you delete


@pytest.mark.parametrize(
    "args",
    [
        ["mc", "--controller", "rl", "--runs", "8", "--policy", "{D}", "--out", "{D}"],
        ["mc", "--controller", "rl,smc", "--runs", "8", "--policy", "{D}/policy/policy.npz", "--out", "{D}"],
        ["mc", "--controller", "hybrid", "--runs", "8", "--policy", "{D}", "--out", "{D}/policy"],
        ["fly", "--controller", "rl", "--policy", "{D}", "--out", "{D}"],
        ["compare", "--controller", "rl", "--policy", "{D}", "--out", "{D}"],
        ["quickstart", "--runs", "8", "--policy", "{D}", "--out", "{D}"],
        ["envelope", "--controller", "rl", "--n", "2", "--policy", "{D}", "--out", "{D}"],
        ["robustness", "--controller", "rl", "--policy", "{D}", "--out", "{D}"],
        ["train", "--preset", "smoke", "--init-policy", "{D}", "--out", "{D}"],
        ["train", "--preset", "smoke", "--init-policy", "{D}/policy/policy.npz", "--out", "{D}/policy"],
    ],
    ids=lambda a: " ".join(a[:2]) + " " + a[-1],
)
def test_force_refuses_what_the_command_reads(monkeypatch, capsys, train_run, args):
    before = _tree(train_run.parent)
    argv = [a.replace("{D}", str(train_run)) for a in args] + ["--force"]
    code, _, err = cli_run(monkeypatch, capsys, *argv)
    assert code == 2, err
    line = err.strip()
    assert "\n" not in line and "which this command reads" in line and "choose another --out" in line, line
    assert _tree(train_run.parent) == before  # nothing deleted, nothing added


def test_force_refuses_a_state_file_inside_out(monkeypatch, capsys, tmp_path):
    monkeypatch.chdir(tmp_path)
    assert cli_run(monkeypatch, capsys, *SIM, "--out", "run")[0] == 0
    state = tmp_path / "run" / "state.json"
    state.write_text(json.dumps({"V": 600.0, "alpha": 0.3, "beta": 0.0, "p": 0, "q": 0, "r": 0, "mu": 0,
                                 "gamma": 0.0}))  # fmt: skip
    before = _tree(tmp_path)
    code, _, err = cli_run(monkeypatch, capsys, "fly", "--scenario", str(state), "--out", "run", "--force")
    assert code == 2 and "contains" in err and "which this command reads" in err, err
    assert _tree(tmp_path) == before


# ------------------------------------------------------------------- --force deletes only what we wrote


def _sim(monkeypatch, capsys, *extra: str) -> tuple[int, str]:
    code, _, err = cli_run(monkeypatch, capsys, *SIM, "--out", "run", *extra)
    return code, err


@pytest.mark.parametrize(
    "make, named",
    [
        (lambda r: (r / "notes.md").write_text("mine"), "notes.md"),
        (lambda r: (r / "plots").mkdir() or (r / "plots" / "mine.png").write_bytes(b"x"), "plots/mine.png"),
        (lambda r: (r / "empty").mkdir(), "empty/ (an empty folder)"),
        (lambda r: (r / "trajectory.csv").write_text("edited"), "trajectory.csv (changed since"),
        (lambda r: (r / "link").symlink_to(r.parent), "link (a symbolic link)"),
        (
            lambda r: (r / "checkpoints").mkdir() or (r / "checkpoints" / "best.txt").write_text("x"),
            "best.txt",
        ),
    ],
    ids=["file", "file_in_folder", "empty_folder", "changed_output", "symlink", "unknown_name_in_own_folder"],
)
def test_force_refuses_files_harv_jax_did_not_write(monkeypatch, capsys, tmp_path, make, named):
    monkeypatch.chdir(tmp_path)
    assert _sim(monkeypatch, capsys)[0] == 0
    make(tmp_path / "run")
    before = _tree(tmp_path)
    code, err = _sim(monkeypatch, capsys, "--force")
    assert code == 2 and err.count("\n") == 1, err
    assert "holds files harv-jax did not write" in err and named in err, err
    assert _tree(tmp_path) == before


def test_force_replaces_what_harv_jax_wrote_including_crash_leftovers(monkeypatch, capsys, tmp_path):
    monkeypatch.chdir(tmp_path)
    assert _sim(monkeypatch, capsys)[0] == 0
    run = tmp_path / "run"
    doc = manifest.read(run)
    assert doc["status"] == manifest.COMPLETE and set(doc["files"]) == {
        "trajectory.csv",
        "trajectory.png",
    }
    # what a killed command leaves: temporary files of atomic writes and checkpoints, event files
    (run / atomic.tmp_path(run / "summary.json").name).write_text("{")
    (run / "checkpoints").mkdir()
    (run / "checkpoints" / ".tmp-123-ckpt_000002.msgpack").write_bytes(b"x")
    (run / "checkpoints" / "ckpt_000001.msgpack").write_bytes(b"x")
    (run / "tb").mkdir()
    (run / "tb" / "events.out.tfevents.123.host").write_bytes(b"x")
    assert manifest.foreign_entries(run) == []
    code, err = _sim(monkeypatch, capsys, "--force")
    assert code == 0, err
    assert sorted(p.name for p in run.iterdir()) == sorted([*runlock.LOCK_FILES[:1], MARKER, MANIFEST,
                                                            "trajectory.csv", "trajectory.png"])  # fmt: skip


def test_a_folder_of_an_older_harv_jax_is_refused_with_the_command_that_removes_it(
    monkeypatch, capsys, tmp_path
):
    monkeypatch.chdir(tmp_path)
    assert _sim(monkeypatch, capsys)[0] == 0
    (tmp_path / "run" / MANIFEST).unlink()
    before = _tree(tmp_path)
    code, err = _sim(monkeypatch, capsys, "--force")
    assert code == 2 and "older harv-jax" in err and "rm -r run" in err, err
    assert _tree(tmp_path) == before


def test_nested_run_folders_are_checked_against_their_own_manifests(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    top = outdir.prepare_out_dir(tmp_path / "q")
    sub = outdir.prepare_out_dir(top / "mc")
    atomic.write_text(sub / "summary.json", "{}")
    atomic.write_text(top / "report.md", "# r")
    outdir.finish_all()
    assert manifest.foreign_entries(top) == []
    (sub / "extra.txt").write_text("mine")
    assert manifest.foreign_entries(top) == ["mc/extra.txt"]
    with pytest.raises(ValueError, match="mc/extra.txt"):
        outdir.prepare_out_dir(top, force=True)
    assert (sub / "extra.txt").exists() and (sub / "summary.json").exists()


def test_atomic_write_leaves_the_old_file_when_it_fails(tmp_path):
    path = tmp_path / "a.txt"
    atomic.write_text(path, "old")
    with pytest.raises(RuntimeError), atomic.open_atomic(path) as f:
        f.write("half of the new")
        raise RuntimeError("killed")
    assert path.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    fig_path = tmp_path / "f.png"
    import matplotlib.pyplot as plt

    fig = plt.figure()
    atomic.save_figure(fig, fig_path, dpi=20)
    plt.close(fig)
    assert fig_path.read_bytes()[:4] == b"\x89PNG"
    atomic.savez(tmp_path / "x.npz", a=[1, 2])  # exactly this name (numpy would not add a second .npz)
    assert (tmp_path / "x.npz").is_file() and not (tmp_path / "x.npz.npz").exists()


def test_an_unfinished_folder_says_what_to_do(monkeypatch, capsys, tmp_path):
    """A folder whose command never finished (killed: status 'running', lock free) is named as such by a
    re-run without --force and by report; a training run names --resume."""
    monkeypatch.chdir(tmp_path)
    assert _sim(monkeypatch, capsys)[0] == 0
    doc = manifest.read(tmp_path / "run")
    doc["status"] = manifest.RUNNING
    (tmp_path / "run" / MANIFEST).write_text(json.dumps(doc))
    code, err = _sim(monkeypatch, capsys)
    assert code == 2 and "unfinished run of `harv-jax simulate" in err and "--force to replace it" in err, err
    code, _, err = cli_run(monkeypatch, capsys, "report", "run")
    assert code == 0 and "incomplete" in err, err
    doc["command"] = "harv-jax train --out run"
    doc["status"] = manifest.INTERRUPTED
    (tmp_path / "run" / MANIFEST).write_text(json.dumps(doc))
    code, err = _sim(monkeypatch, capsys)
    assert code == 2 and "interrupted run" in err and "harv-jax train --resume run" in err, err


# --------------------------------------------------------------------------- interrupted means interrupted


def _popen(args: list[str], cwd: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "harv_jax.cli", *args],
        cwd=cwd,
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )


def _read_until(stream, needle: str, proc: subprocess.Popen) -> str:
    """Lines of ``stream`` up to the first holding ``needle`` (fails if the process ends first)."""
    seen = ""
    for line in stream:
        seen += line
        if needle in line:
            return seen
    raise AssertionError(f"ended before {needle!r} (exit {proc.wait()}): {seen[-2000:]}{proc.stderr.read()}")


def test_sigint_to_the_process_group_during_a_monte_carlo(tmp_path):
    proc = _popen(["mc", "--controller", "smc,hybrid", "--runs", "512", "--out", "mc"], tmp_path)
    _read_until(proc.stdout, "[mc] smc: recovery", proc)  # the SMC is done; the hybrid's is under way
    t0 = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)  # as Ctrl-C in a shell does
    code = proc.wait(timeout=30)
    err = proc.stderr.read()
    assert code == 130, (code, err)  # not 0, not a segmentation fault (-11)
    assert time.monotonic() - t0 < 10
    lines = err.strip().splitlines()
    assert lines[-1].startswith("harv-jax: interrupted (SIGINT); mc kept, incomplete"), err
    assert "Traceback" not in err
    assert manifest.read(tmp_path / "mc")["status"] == manifest.INTERRUPTED
    assert not (tmp_path / "mc" / "summary.json").exists()
    rerun = subprocess.run([sys.executable, "-m", "harv_jax.cli", "mc", "--out", "mc"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=120)  # fmt: skip
    assert rerun.returncode == 2 and "interrupted run of" in rerun.stderr, rerun.stderr


def test_sigterm_during_training_then_resume(tmp_path):
    preset = tmp_path / "tiny.toml"
    preset.write_text(
        textwrap.dedent("""
        [ppo]
        total_steps = 40_960
        num_envs = 8
        unroll = 16
        epochs = 1
        minibatches = 2
        hidden_sizes = [16]
        num_seeds = 1
        num_periods = 4
        checkpoint_every = 1
        [env]
        episode_steps = 100
        domain_randomization = false
    """)
    )
    proc = _popen(["train", "--preset", str(preset), "--out", "run"], tmp_path)
    _read_until(proc.stderr, "period 2/4", proc)
    proc.send_signal(signal.SIGTERM)
    code = proc.wait(timeout=30)
    err = proc.stderr.read()
    assert code == 143, (code, err)
    assert err.strip().splitlines()[-1] == (
        "harv-jax: interrupted (SIGTERM); run kept with its last checkpoint; it can be resumed: "
        "harv-jax train --resume run"
    ), err
    assert manifest.read(tmp_path / "run")["status"] == manifest.INTERRUPTED
    assert manifest.foreign_entries(tmp_path / "run") == []
    r = subprocess.run([sys.executable, "-m", "harv_jax.cli", "train", "--resume", "run"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    assert manifest.read(tmp_path / "run")["status"] == manifest.COMPLETE


SLOW_STOP = """
import sys, time
from harv_jax import interrupt

def message(name):
    time.sleep(60)  # marking the folders hangs
    return "never printed"

with interrupt.handled(message):
    print("ready", flush=True)
    time.sleep(60)
"""


@pytest.mark.parametrize("first, second", [(signal.SIGINT, signal.SIGINT), (signal.SIGTERM, signal.SIGINT)])
def test_a_second_signal_exits_at_once(tmp_path, first, second):
    proc = subprocess.Popen([sys.executable, "-c", SLOW_STOP], text=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, cwd=REPO)  # fmt: skip
    _read_until(proc.stdout, "ready", proc)
    proc.send_signal(first)
    time.sleep(0.2)
    assert proc.poll() is None  # the first signal is being handled (the message hangs)
    t0 = time.monotonic()
    proc.send_signal(second)
    code = proc.wait(timeout=10)
    assert time.monotonic() - t0 < 5
    assert code == {signal.SIGINT: 130, signal.SIGTERM: 143}[second]
    assert "interrupted again" in proc.stderr.read()
