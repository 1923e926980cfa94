"""``--disturbances`` on the commands: recorded in each output, and zero levels equal none."""

from __future__ import annotations

import csv
import json

import pytest

from tests.cli_util import cli_run


def test_mc_records_disturbances_and_zero_levels_equal_none(monkeypatch, capsys, tmp_path):
    base = ["--controller", "smc", "--runs", "3", "--duration", "2", "--seed", "5"]
    code, _, err = cli_run(monkeypatch, capsys, "mc", *base, "--out", tmp_path / "none")
    assert code == 0, err
    code, _, err = cli_run(
        monkeypatch, capsys, "mc", *base, "--disturbances", "noise,delay", "--noise-scale", "0",
        "--delay-ms", "0", "--out", tmp_path / "zero",
    )  # fmt: skip
    assert code == 0, err
    code, _, err = cli_run(
        monkeypatch, capsys, "mc", *base, "--disturbances", "default", "--out", tmp_path / "default"
    )
    assert code == 0, err
    none = (tmp_path / "none" / "runs.csv").read_text()
    assert (tmp_path / "zero" / "runs.csv").read_text() == none  # levels 0: no disturbance columns either
    summary = json.loads((tmp_path / "default" / "summary.json").read_text())
    assert summary["disturbances"]["active"] == ["noise", "delay", "gust", "model", "lag"]
    rows = list(csv.DictReader((tmp_path / "default" / "runs.csv").open()))
    assert rows[0]["delay_ms"] == "20" and rows[0]["noise_scale"] == "1"
    assert json.loads((tmp_path / "none" / "summary.json").read_text())["disturbances"]["active"] == []


@pytest.mark.slow  # two compiles of 30-60 s on the 2-core CI machine
def test_fly_and_envelope_take_disturbances(monkeypatch, capsys, tmp_path):
    code, _, err = cli_run(
        monkeypatch, capsys, "fly", "--scenario", "random", "--duration", "2", "--disturbances", "gust,model",
        "--out", tmp_path / "fly",
    )  # fmt: skip
    assert code == 0, err
    metrics = json.loads((tmp_path / "fly" / "metrics.json").read_text())
    assert metrics["disturbances"]["active"] == ["gust", "model"]
    code, _, err = cli_run(
        monkeypatch, capsys, "envelope", "--n", "2", "--duration", "2", "--disturbances", "delay",
        "--delay-ms", "50", "--out", tmp_path / "env",
    )  # fmt: skip
    assert code == 0, err
    env = json.loads((tmp_path / "env" / "envelope.json").read_text())
    assert env["disturbances"]["delay_steps"] == 5


def test_a_command_reads_the_policy_file_once(monkeypatch, capsys, tmp_path):
    """``mc`` with the policy flown alone and in the hybrid (plus the loop check) reads the file once."""
    from harv_jax import policy

    reads = []
    real = policy._load_npz
    monkeypatch.setattr(policy, "_load_npz", lambda p: reads.append(str(p)) or real(p))
    policy._load_file.cache_clear()
    args = ["--controller", "rl,hybrid", "--runs", "2", "--duration", "1", "--out", tmp_path / "mc"]
    code, _, err = cli_run(monkeypatch, capsys, "mc", *args)
    assert code == 0, err
    assert len(reads) == 1, reads
