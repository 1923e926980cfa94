"""``--disturbances`` on the commands: recorded in each output, and zero levels equal none."""

from __future__ import annotations

import json

import pytest

from tests.cli_util import cli_run


def test_mc_records_disturbances_and_zero_levels_equal_none(monkeypatch, capsys, tmp_path, damper):
    """A cheap feedback controller (the SMC's compile adds nothing to the command's handling of the flags):
    it reads the measured state, so sensor noise would reach its flights."""
    base = ["--controller", damper, "--runs", "3", "--duration", "10.5", "--seed", "5"]
    code, _, err = cli_run(monkeypatch, capsys, "mc", *base, "--out", tmp_path / "none")
    assert code == 0, err
    code, _, err = cli_run(
        monkeypatch, capsys, "mc", *base, "--disturbances", "noise,delay", "--noise-scale", "0",
        "--delay-ms", "0", "--out", tmp_path / "zero",
    )  # fmt: skip
    assert code == 0, err
    none = (tmp_path / "none" / "runs.csv").read_text()
    assert (tmp_path / "zero" / "runs.csv").read_text() == none  # levels 0: no disturbance columns either
    assert json.loads((tmp_path / "none" / "summary.json").read_text())["disturbances"]["active"] == []


@pytest.mark.slow  # two compiles of 30-60 s on the 2-core CI machine
def test_fly_and_envelope_take_disturbances(monkeypatch, capsys, tmp_path):
    code, _, err = cli_run(
        monkeypatch, capsys, "fly", "--scenario", "random", "--duration", "11",
        "--disturbances", "gust,model", "--out", tmp_path / "fly",
    )  # fmt: skip
    assert code == 0, err
    metrics = json.loads((tmp_path / "fly" / "metrics.json").read_text())
    assert metrics["disturbances"]["active"] == ["gust", "model"]
    code, _, err = cli_run(
        monkeypatch, capsys, "envelope", "--n", "2", "--duration", "10.5", "--disturbances", "delay",
        "--delay-ms", "50", "--out", tmp_path / "env",
    )  # fmt: skip
    assert code == 0, err
    env = json.loads((tmp_path / "env" / "envelope.json").read_text())
    assert env["disturbances"]["delay_steps"] == 5


def test_a_command_reads_the_policy_file_once(monkeypatch):
    """What ``mc --controller rl,hybrid`` does with the policy before and while it flies (build both for
    the argument check, the loop check, build both again in the study) reads the file once."""
    from harv_jax import policy
    from harv_jax.control.registry import ControllerOptions, build_controller, loop_mismatches

    reads = []
    real = policy._load_npz
    monkeypatch.setattr(policy, "_load_npz", lambda p: reads.append(str(p)) or real(p))
    policy._load_file.cache_clear()
    options = ControllerOptions()
    for _ in range(2):
        build_controller("rl", options)
        build_controller("hybrid", options)
        loop_mismatches(["rl", "hybrid"], options)
    assert len(reads) == 1, reads
    policy._load_file.cache_clear()
    build_controller("rl", options)
    assert len(reads) == 2  # the count sees reads: a cleared cache reads again


def test_turbulence_on_mc_and_fly_is_recorded_and_its_wind_written(monkeypatch, capsys, tmp_path, damper):
    """``--turbulence``: the level in runs.csv and summary.json (sigma 0 is still air: ``none``); fly writes
    the air mass's body-axis velocity next to the states."""
    import csv

    from harv_jax.evaluation.montecarlo.disturbances import parse_turbulence

    assert parse_turbulence("0") == parse_turbulence(None) == "none" and parse_turbulence("6.50") == "6.5"
    base = ["--controller", damper, "--runs", "3", "--duration", "10.5", "--seed", "5"]
    code, _, err = cli_run(
        monkeypatch, capsys, "mc", *base, "--turbulence", "moderate", "--out", tmp_path / "t"
    )
    assert code == 0, err
    rows = list(csv.DictReader((tmp_path / "t" / "runs.csv").open()))
    assert [r["turbulence"] for r in rows] == ["moderate"] * 3
    summary = json.loads((tmp_path / "t" / "summary.json").read_text())
    doc = summary["disturbances"]
    assert doc["turbulence"] == "moderate" and doc["active"] == ["turbulence"]
    assert summary["recovery_criterion"]["kind"].startswith("turbulence")
    assert summary["recovery_criterion"]["angle_filter_tau_s"] == 1.0
    code, _, err = cli_run(
        monkeypatch, capsys, "fly", "--controller", damper, "--scenario", "random", "--duration", "10.5",
        "--turbulence", "severe", "--out", tmp_path / "fly",
    )  # fmt: skip
    assert code == 0, err
    rows = list(csv.DictReader((tmp_path / "fly" / "trajectory.csv").open()))
    wind = [[float(r[f"wind_{c}_fps"]) for c in "uvw"] for r in rows]
    assert all(w == w for w in wind[-1]) and max(abs(w[1]) for w in wind) > 1.0  # severe: ~20 ft/s std


@pytest.mark.slow
def test_robustness_sweeps_turbulence_and_names_its_margin(monkeypatch, capsys, tmp_path, damper):
    """``robustness --disturbances turbulence``: a row per sigma (0: still air), each scored by its own
    criterion, and the margin in ft/s; ``--turbulence`` is recorded."""
    code, out, err = cli_run(
        monkeypatch, capsys, "robustness", "--controller", damper, "--disturbances", "turbulence",
        "--turbulence-levels", "0,20", "--runs", "3", "--duration", "10.5", "--out", tmp_path / "r",
    )  # fmt: skip
    assert code == 0, err
    doc = json.loads((tmp_path / "r" / "robustness.json").read_text())
    t = doc["disturbances"]["turbulence"]
    assert t["unit"] == "ft/s" and t["levels"] == [0.0, 20.0] and doc["turbulence"] == "none"
    rows = t["controllers"][damper]["rows"]
    assert [r["level"] for r in rows] == [0.0, 20.0]
    assert "turbulence margin (ft/s)" in (tmp_path / "r" / "margins.md").read_text()
