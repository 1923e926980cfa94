"""`harv-jax compare`: files, one table row per scenario and controller, one-line errors."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from cli_util import cli_run

from harv_jax.evaluation.comparison import omega_settling_time_s
from harv_jax.evaluation.summary import COMPARE_COLUMNS as COLUMNS


def _run(monkeypatch, capsys, *args):
    return cli_run(monkeypatch, capsys, "compare", *args)


def test_omega_settling_time():
    t = np.arange(5) * 0.1
    x = np.zeros((5, 10))
    x[:, 3] = [1.0, 0.5, 0.1, 0.3, 0.1]
    assert omega_settling_time_s(t, x) == pytest.approx(0.4)
    x[-1, 3] = 1.0
    assert omega_settling_time_s(t, x) is None


def test_compare_writes_tables_and_figures(monkeypatch, capsys, tmp_path, figure_texts):
    out = tmp_path / "c"
    code, _, err = _run(
        monkeypatch, capsys, "--controller", "smc,hybrid", "--policy", "shipped:partial", "--duration", "11",
        "--spin-s", "0.5", "--out", str(out),
    )  # fmt: skip
    assert code == 0, err
    assert len(figure_texts) >= 3 and not any(figure_texts.values()), figure_texts
    for f in ("spin_trajectories.png", "fixed_trajectories.png", "spin_hybrid.png", "compare_metrics.md"):
        assert (out / f).stat().st_size > 0
    rows = list(csv.DictReader((out / "compare_metrics.csv").open()))
    assert [(r["scenario"], r["controller"]) for r in rows] == [
        ("spin", "smc"), ("spin", "hybrid"), ("fixed", "smc"), ("fixed", "hybrid"),
    ]  # fmt: skip
    assert list(rows[0]) == list(COLUMNS)
    assert rows[0]["zeta_active_fraction"] == "" and 0 <= float(rows[1]["zeta_active_fraction"]) <= 1
    md = (out / "compare_metrics.md").read_text().split("\n\n")
    table = next(block for block in md if block.startswith("| scenario |")).splitlines()
    assert len([ln for ln in table if ln.startswith("| ")]) == 1 + len(rows)
    doc = json.loads((out / "compare.json").read_text())
    assert doc["policy"] == "shipped:partial" and len(doc["rows"]) == 4
    # against smc: each row's time over smc's on its scenario, and hybrid over both scenarios
    assert [float(r["recovery_time_vs_smc"]) for r in rows[::2]] == [1.0, 1.0]
    for r in rows:
        assert float(r["recovery_time_nr_at_run_s"]) == pytest.approx(
            float(r["recovery_time_s"]) if r["recovery_time_s"] else 11.0
        )
    assert list(doc["vs_smc"]) == ["hybrid"] and doc["vs_smc"]["hybrid"]["runs"] == 2
    assert any(block.startswith("| controller | faster_fraction") for block in md)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--controller", "smc,pid"], "unknown controller 'pid'"),
        (["--state", "nowhere.json"], "--state 'nowhere.json' does not exist"),
        (["--duration", "0"], "--duration 0.0 s: allowed"),
        (["--zeta", "x"], "--zeta 'x' is unknown"),
    ],
)
def test_compare_bad_flags(monkeypatch, capsys, tmp_path, args, needle):
    code, _, err = _run(monkeypatch, capsys, *args, "--out", str(tmp_path / "o"))
    assert code == 2 and needle in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()
