"""Print the observer table of the robustness README from the committed Monte Carlo summaries.

    python experiments/robustness/observer_table.py

Reads the entries ``mc_observer_{clean,nogust,noise3}/summary.json`` of ``results/summaries.json``
(``experiments/results_bundle.py``), the same conditions of the 0.15 Hz observer, ``mc_observer015_*``, of
``smc-brake-zoom``, ``mc_observer_zoom_*``, and of the extended-state observer, ``mc_eso_*`` (``harv-jax
mc`` with the commands in the README, under the folder each wrote) and prints, per
controller and condition, recovered share, mean recovery time (not recovered at the run length), control TV
and chatter index, and TV and chatter against the same controller's clean run.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import results_bundle  # noqa: E402

RESULTS = Path(__file__).parent / "results"
CONDITIONS = (("clean", "clean"), ("noise, delay, model, lag", "nogust"), ("noise 3x", "noise3"))
#: Result folders: each holds the three conditions as ``<prefix>_<condition>``.
PREFIXES = ("mc_observer", "mc_observer015", "mc_observer_zoom", "mc_eso")


def main() -> None:
    print("| controller | condition | recovered | mean (s) | TV (rad) | TV / clean | chatter / clean |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for prefix in PREFIXES:
        rows(prefix)


def rows(prefix: str) -> None:
    """Print the table rows of one set of result folders."""
    files = results_bundle.load(RESULTS / "summaries.json")
    runs = {label: files[f"{prefix}_{d}/summary.json"] for label, d in CONDITIONS}
    clean = runs["clean"]["controllers"]
    for name, c0 in clean.items():
        for label, _ in CONDITIONS:
            c = runs[label]["controllers"][name]
            tv, ch = c["control_tv"]["mean"], c["chatter_index"]["mean"]
            rec, mean_s = 100 * c["recovery_rate"], c["t_recover_mean_nr_at_run_s"]
            tv_ratio, ch_ratio = tv / c0["control_tv"]["mean"], ch / c0["chatter_index"]["mean"]
            cells = (f"{rec:.1f}%", f"{mean_s:.2f}", f"{tv:.1f}", f"{tv_ratio:.2f}", f"{ch_ratio:.2f}")
            row = (name, label, *cells)
            print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
