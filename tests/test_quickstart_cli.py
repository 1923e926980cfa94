"""``harv-jax quickstart`` end to end on a few runs: the spin comparison, the Monte Carlo and the report."""

from __future__ import annotations

import json

import pytest
from cli_util import cli_run


@pytest.mark.slow  # five controllers compiled for the comparison and the Monte Carlo, ~2 min
def test_quickstart_writes_the_comparison_the_monte_carlo_and_the_report(tmp_path, monkeypatch, capsys):
    out = tmp_path / "qs"
    code, stdout, err = cli_run(monkeypatch, capsys, "quickstart", "--runs", 4, "--seed", 3, "--out", out)
    assert code == 0, err
    for f in ("compare/compare.json", "mc/runs.csv", "mc/summary.json", "report.md", "report.html"):
        assert (out / f).is_file(), f
    summary = json.loads((out / "mc" / "summary.json").read_text())
    assert summary["runs"] == 4 and summary["seed"] == 3
    assert set(summary["controllers"]) == {"smc", "smc-brake", "smc-brake-zoom", "rl", "hybrid"}
    assert "[quickstart] hybrid: recovery rate" in stdout
