"""Recovery times compared run by run (``harv_jax.evaluation.montecarlo.paired``) against hand-worked
numbers, and where they show: the Monte Carlo summary block, the report's table and compare's rows."""

from __future__ import annotations

import numpy as np
import pytest

from harv_jax.evaluation.comparison import add_vs_smc
from harv_jax.evaluation.montecarlo.paired import (
    mean_nr_at_run_s,
    paired_vs_reference,
    paired_vs_smc,
    times_nr_at_run_s,
)
from harv_jax.evaluation.montecarlo.study import paired_line
from harv_jax.report.document import Doc, to_markdown
from harv_jax.report.sections import mc_section

RUN_S = 60.0
# 4 runs. The controller: 10, 20, not recovered (-> 60), 30 s. The SMC: 12, 19.5, 40, not recovered (-> 60).
T = np.array([10.0, 20.0, np.nan, 30.0])
REC = np.array([True, True, False, True])
T_SMC = np.array([12.0, 19.5, 40.0, np.nan])
REC_SMC = np.array([True, True, True, False])


def test_not_recovered_runs_count_at_the_run_length():
    np.testing.assert_array_equal(times_nr_at_run_s(T, REC, RUN_S), [10.0, 20.0, 60.0, 30.0])
    assert mean_nr_at_run_s(T, REC, RUN_S) == pytest.approx(30.0)  # (10 + 20 + 60 + 30) / 4
    assert mean_nr_at_run_s(T_SMC, REC_SMC, RUN_S) == pytest.approx(32.875)  # (12 + 19.5 + 40 + 60) / 4
    # a finite time with the flag down counts as not recovered; no runs: None
    assert mean_nr_at_run_s([5.0], [False], RUN_S) == pytest.approx(RUN_S)
    assert mean_nr_at_run_s([], [], RUN_S) is None


def test_paired_against_the_reference_hand_worked():
    # differences controller - smc: -2 (faster by > 1), +0.5 (within 1 s), +20 (slower), -30 (faster)
    vs = paired_vs_reference(T, REC, T_SMC, REC_SMC, RUN_S)
    assert vs["faster_fraction"] == pytest.approx(0.5)
    assert vs["slower_fraction"] == pytest.approx(0.25)
    assert vs["mean_ratio"] == pytest.approx(30.0 / 32.875)
    assert (vs["runs"], vs["margin_s"], vs["run_length_s"]) == (4, 1.0, RUN_S)
    # both not recovered: a tie; a margin of 3 s leaves only the 30 s gap on either side
    tie = paired_vs_reference([np.nan], [False], [np.nan], [False], RUN_S)
    assert (tie["faster_fraction"], tie["slower_fraction"], tie["mean_ratio"]) == (0.0, 0.0, 1.0)
    wide = paired_vs_reference(T, REC, T_SMC, REC_SMC, RUN_S, margin_s=3.0)
    assert (wide["faster_fraction"], wide["slower_fraction"]) == (0.25, 0.25)
    with pytest.raises(ValueError, match="differ in number"):
        paired_vs_reference(T, REC, T_SMC[:3], REC_SMC[:3], RUN_S)


def test_paired_vs_smc_only_when_smc_is_in_the_run():
    times = {"smc": (T_SMC, REC_SMC), "smc-brake": (T, REC), "rl": (T_SMC, REC_SMC)}
    vs = paired_vs_smc(times, RUN_S)
    assert list(vs) == ["smc-brake", "rl"]
    assert vs["smc-brake"] == paired_vs_reference(T, REC, T_SMC, REC_SMC, RUN_S)
    assert vs["rl"]["mean_ratio"] == pytest.approx(1.0) and vs["rl"]["faster_fraction"] == 0.0
    assert paired_vs_smc({"rl": (T, REC)}, RUN_S) == {}
    line = paired_line(vs["smc-brake"])
    assert line.startswith("50.0% of runs faster by > 1 s, 25.0% slower, mean recovery time 0.913x")


def test_report_shows_the_nr_mean_and_the_paired_table():
    block = {"recovery_rate": 0.75, "recovery_time_s": {"mean": 20.0, "p50": 20.0, "p95": 29.0}}
    summary = {
        "runs": 4, "duration_s": RUN_S, "seed": 0,
        "controllers": {
            "smc": {**block, "t_recover_mean_nr_at_run_s": 32.875},
            "smc-brake": {
                **block, "t_recover_mean_nr_at_run_s": 30.0,
                "vs_smc": paired_vs_reference(T, REC, T_SMC, REC_SMC, RUN_S),
            },
        },
    }  # fmt: skip
    doc = Doc()
    mc_section(doc, summary)
    md = to_markdown(doc, ".")
    assert "| recovery time mean, not recovered at run length [s] | 32.88 | 30.00 |" in md
    assert "### Against the SMC, run by run" in md and "(60 s)" in md
    assert "| runs faster than smc by > 1 s | – | 50.0% |" in md
    assert "| runs slower than smc by > 1 s | – | 25.0% |" in md
    assert "| mean recovery time / smc's | – | 0.913 |" in md
    # an older summary without the new keys: no paired table
    doc = Doc()
    mc_section(doc, {"runs": 4, "seed": 0, "controllers": {"smc": block}})
    md = to_markdown(doc, ".")
    assert "Against the SMC" not in md and "not recovered at run length" not in md


def test_compare_rows_against_smc():
    rows = [
        {"scenario": "spin", "controller": "smc", "recovery_time_nr_at_run_s": 20.0},
        {"scenario": "spin", "controller": "smc-brake", "recovery_time_nr_at_run_s": 10.0},
        {"scenario": "fixed", "controller": "smc", "recovery_time_nr_at_run_s": 15.0},
        {"scenario": "fixed", "controller": "smc-brake", "recovery_time_nr_at_run_s": 60.0},
    ]
    vs = add_vs_smc(rows, RUN_S)
    assert [r["recovery_time_vs_smc"] for r in rows] == [1.0, 0.5, 1.0, 4.0]
    assert vs == {
        "smc-brake": paired_vs_reference([10.0, 60.0], [True, True], [20.0, 15.0], [True, True], RUN_S)
    }
    assert vs["smc-brake"]["faster_fraction"] == 0.5 and vs["smc-brake"]["mean_ratio"] == pytest.approx(2.0)
    assert (
        add_vs_smc([{"scenario": "spin", "controller": "rl", "recovery_time_nr_at_run_s": 9.0}], RUN_S) == {}
    )
