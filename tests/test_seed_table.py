"""experiments/paper_reproduction/seed_table.py: one-seed folders go with their preset, means by hand."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location(
    "seed_table", REPO / "experiments" / "paper_reproduction" / "seed_table.py"
)
seed_table = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(seed_table)


def _row(recovery: float, t_alpha: float | None) -> dict:
    row = {k: 0.0 for k, _, _ in seed_table.COLUMNS}
    return {**row, "recovery_rate": recovery, "t_alpha_p50_s": t_alpha}


def test_groups_seed_folders_and_averages(tmp_path):
    for s, (rec, t) in enumerate([(1.0, 10.0), (0.5, None)]):
        d = {
            "runs_dir": "x/cpu-2core",
            "smc": _row(1.0, 16.7),
            "policies": {f"paper-full-seed{s}/seed0/rl": _row(rec, t)},
        }
        (tmp_path / f"e{s}.json").write_text(json.dumps(d))
    out = seed_table.tables(sorted(tmp_path.glob("*.json"))).splitlines()
    assert sum("SMC only" in line for line in out) == 1  # identical SMC rows printed once
    (group,) = [line for line in out if line.startswith("| cpu-2core/paper-full | rl | 2 |")]
    cells = [c.strip() for c in group.strip("|").split("|")]
    assert cells[3] == "75.0% ± 25.0%"  # recovery mean/std of 1.0 and 0.5
    assert cells[9] == "10.0 ± 0.0 (n=1)"  # the seed with no settling time is left out and counted
