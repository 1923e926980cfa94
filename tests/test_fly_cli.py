"""`harv-jax fly`: outputs of short flights, one-line usage errors (exit code 2) for bad flags."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_util import cli_run

from harv_jax.task.criteria import OUTCOME_NAMES

DURATION = "10.5"  # s: just past the criterion's hold; the 60 s results are in experiments/


def _run(monkeypatch, capsys, *args):
    return cli_run(monkeypatch, capsys, "fly", *args)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--controller", "rl", "--policy", "nowhere.npz"], "policy 'nowhere.npz' does not exist"),
        (["--controller", "hybrid", "--zeta", "bang"], "--zeta 'bang' is unknown"),
        (["--controller", "hybrid", "--policy", "shipped:best"], "shipped policy 'best' is unknown"),
        (["--controller", "pid"], "--controller 'pid' is unknown"),
        (["--target-alpha", "2.0"], "--target-alpha 2.0 rad is outside"),
        (["--target-alpha", "nan"], "--target-alpha nan"),
        (["--duration", "-1"], "--duration -1.0 s: allowed"),
        (["--duration", "0.001"], "criterion's 10 s hold"),
        (["--switching", "tanh"], "--switching 'tanh' is unknown"),
        (["--scenario", "nowhere.json"], "is neither spin nor random nor an existing file"),
        (["--spin-s", "-3"], "--spin-s -3.0 must be in"),
    ],
)
def test_bad_flags_are_one_line_usage_errors(monkeypatch, capsys, tmp_path, args, needle):
    code, out, err = _run(monkeypatch, capsys, *args, "--out", str(tmp_path / "o"))
    assert code == 2
    assert needle in err
    assert err.startswith("harv-jax: error:") and err.count("\n") == 1
    assert not (tmp_path / "o").exists()  # nothing written


@pytest.mark.parametrize(
    "name, text, needle",
    [
        ("s.json", '{"V": 500, "alpha": 0.1}', "lacks beta, p, q, r, mu, gamma"),
        ("s.json", "{not json", "is not valid JSON"),
        ("s.json", '{"V": -5, "alpha": 0, "beta": 0, "p": 0, "q": 0, "r": 0, "mu": 0, "gamma": 0}', "V=-5.0"),
        ("s.csv", "V,alpha\n500,0.1", "lacks beta"),
        ("s.csv", "V,alpha\n500", "2 header names but 1 values"),
        ("s.txt", "V=500", "must end in .json or .csv"),
    ],
)
def test_bad_state_files(monkeypatch, capsys, tmp_path, name, text, needle):
    f = tmp_path / name
    f.write_text(text)
    code, _, err = _run(monkeypatch, capsys, "--scenario", str(f), "--out", str(tmp_path / "o"))
    assert code == 2 and needle in err and err.count("\n") == 1


def test_out_dir_is_not_overwritten_without_force(monkeypatch, capsys, tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    code, _, err = _run(monkeypatch, capsys, "--scenario", "random", "--out", str(out))
    assert code == 2 and "--force" in err
    assert (out / "keep.txt").exists()


def _check_outputs(out, n_rows_min, controller="smc"):
    names = {p.name for p in out.iterdir()}
    assert {"trajectory.csv", "trajectory.png", "sliding.png", "metrics.json"} <= names
    header = (out / "trajectory.csv").read_text().splitlines()[0].split(",")
    assert header[:4] == ["t", "V", "alpha", "beta"] and "s_mu" in header and "de_cmd" in header
    data = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)
    assert data.shape[0] >= n_rows_min and data.shape[1] == len(header)
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["metrics"]["outcome_name"] in OUTCOME_NAMES
    assert doc["controller"] == controller
    for key in (
        "t_recover_s",
        "altitude_loss_ft",
        "control_tv_rad",
        "chatter_index_rad2",
        "sat_position_fraction",
    ):
        assert key in doc["metrics"]
    return data, header, doc


def test_fly_random_and_state_file(monkeypatch, capsys, tmp_path):
    code, out, err = _run(
        monkeypatch,
        capsys,
        "--scenario",
        "random",
        "--seed",
        "3",
        "--duration",
        DURATION,
        "--out",
        str(tmp_path / "r"),
    )
    assert code == 0, err
    assert "outcome" in out
    data, header, doc = _check_outputs(tmp_path / "r", 50)
    assert np.all(np.isfinite(data[:, header.index("s_alpha")]))  # controller engaged from t = 0
    # the same state written as a JSON file flies the same trajectory
    state = doc["initial_state"]
    f = tmp_path / "state.json"
    f.write_text(json.dumps(state))
    code, _, err = _run(
        monkeypatch, capsys, "--scenario", str(f), "--duration", DURATION, "--out", str(tmp_path / "f")
    )
    assert code == 0, err
    data_f, _, _ = _check_outputs(tmp_path / "f", 50)
    assert data_f.shape == data.shape  # the first 0.5 s: later, the state file's float32 rounding grows
    np.testing.assert_allclose(data_f[:50], data[:50], rtol=1e-5, atol=1e-5)


@pytest.mark.slow
def test_fly_spin(monkeypatch, capsys, tmp_path):
    code, _, err = _run(
        monkeypatch,
        capsys,
        "--scenario",
        "spin",
        "--spin-s",
        "0.5",
        "--duration",
        DURATION,
        "--out",
        str(tmp_path / "s"),
    )
    assert code == 0, err
    data, header, doc = _check_outputs(tmp_path / "s", 100)
    assert doc["t_engage_s"] == pytest.approx(0.5)
    s_alpha = data[:, header.index("s_alpha")]
    assert np.all(np.isnan(s_alpha[:50])) and np.all(np.isfinite(s_alpha[50:]))  # controller off, then on
    np.testing.assert_allclose(data[:50, header.index("de_cmd")], -0.436)  # pro-spin command held


@pytest.mark.slow
def test_fly_hybrid_with_shipped_partial_policy(monkeypatch, capsys, tmp_path, figure_texts):
    code, out, err = _run(
        monkeypatch, capsys, "--controller", "hybrid", "--policy", "shipped:partial", "--scenario", "random",
        "--duration", DURATION, "--out", str(tmp_path / "h"),
    )  # fmt: skip
    assert code == 0, err
    data, header, doc = _check_outputs(tmp_path / "h", 50, "hybrid")
    assert (tmp_path / "h" / "hybrid.png").stat().st_size > 0
    assert set(figure_texts) == {"trajectory.png", "sliding.png", "hybrid.png"}
    assert not any(figure_texts.values()), figure_texts
    z = data[:, header.index("zeta")]
    assert np.all((z >= 0) & (z <= 1))
    assert doc["policy"] == "shipped:partial" and doc["zeta_schedule"] == "simplex"
    assert set(doc["certificate"]) == {"all_steps", "unsaturated_steps"}
    assert set(doc["certificate"]["all_steps"]) == {"alpha", "beta", "mu"}
