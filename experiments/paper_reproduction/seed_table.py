"""Markdown tables from ``seed_eval.py`` JSON files: one row per policy, then mean +- std over seeds.

    python experiments/paper_reproduction/seed_table.py \
        experiments/paper_reproduction/results/seed_eval_cpu_partial.json \
        experiments/paper_reproduction/results/seed_eval_cpu_full*.json

Runs trained one seed per folder (``paper-full-seed1``) are grouped with their preset (``paper-full``); the
group label is the runs folder's name plus the preset, e.g. ``cpu-2core/paper-full``.
"""

from __future__ import annotations

import argparse
import json
import re
from collections import defaultdict
from pathlib import Path

import numpy as np

COLUMNS = (  # (metric key, header, format)
    ("recovery_rate", "recovered", "{:.1%}"),
    ("alpha_err_deg", "α err °", "{:.3f}"),
    ("beta_err_deg", "β err °", "{:.3f}"),
    ("mu_err_deg", "μ err °", "{:.2f}"),
    ("alpha_within_2", "α within 2°", "{:.1%}"),
    ("alpha_settled", "α settled", "{:.1%}"),
    ("t_alpha_p50_s", "t_α p50 s", "{:.1f}"),
    ("control_tv_rad", "TV rad", "{:.2f}"),
    ("tv_elevator_rad", "TV δe", "{:.2f}"),
    ("tv_aileron_rad", "TV δa", "{:.2f}"),
    ("tv_rudder_rad", "TV δr", "{:.2f}"),
    ("chatter_rad2", "chatter 1e-6 rad²", "{:.2f}"),
    ("t_recover_p50_s", "t_rec p50 s", "{:.1f}"),
)
FORMAT = {k: f for k, _, f in COLUMNS}
SCALE = {"chatter_rad2": 1e6}


def cell(key: str, value: float | None) -> str:
    if value is None or not np.isfinite(value):
        return "–"
    return FORMAT[key].format(value * SCALE.get(key, 1.0))


def md_row(cells: list[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def header(first: list[str]) -> list[str]:
    cols = first + [h for _, h, _ in COLUMNS]
    return [md_row(cols), "|" + "---|" * len(first) + "---:|" * len(COLUMNS)]


def group_of(runs_dir: str, preset: str) -> str:
    return Path(runs_dir).name + "/" + re.sub(r"-seed\d+$", "", preset)


def tables(files: list[Path]) -> str:
    """Per-policy table and over-seeds table (markdown) of the seed_eval JSON ``files``."""
    lines = header(["policy", "controller"])
    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    smc_rows: set[tuple[str, ...]] = set()
    for f in files:
        d = json.loads(f.read_text())
        smc = tuple(cell(k, d["smc"][k]) for k in FORMAT)
        if smc not in smc_rows:  # the same initial states give the same SMC row: print it once
            smc_rows.add(smc)
            lines.append(md_row([f"SMC only ({f.name})", "smc", *smc]))
        for name, row in d["policies"].items():
            preset, seed, ctrl = name.split("/")
            label = f"{Path(d['runs_dir']).name}/{preset}/{seed}"
            lines.append(md_row([label, ctrl] + [cell(k, row[k]) for k in FORMAT]))
            groups[(group_of(d["runs_dir"], preset), ctrl)].append(row)
    lines += ["", *header(["runs", "controller", "seeds"])]
    for (group, ctrl), rows in groups.items():
        cells = []
        for k in FORMAT:
            v = np.array([np.nan if r[k] is None else r[k] for r in rows], float)
            ok = v[np.isfinite(v)]
            n = f" (n={ok.size})" if 0 < ok.size < v.size else ""  # a seed that never settles has no time
            cells.append(f"{cell(k, ok.mean())} ± {cell(k, ok.std())}{n}" if ok.size else "–")
        lines.append(md_row([group, ctrl, str(len(rows))] + cells))
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", type=Path, nargs="+", help="seed_eval.py JSON outputs")
    print(tables(ap.parse_args().files))


if __name__ == "__main__":
    main()
