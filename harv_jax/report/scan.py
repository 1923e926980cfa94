"""The report's scan of a run directory: which files each directory holds, what kind of run it is and the
commands and seeds recorded in its JSON files."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from harv_jax.report.sections import reconstruct_fly_command

REPORT_FILES = ("report.md", "report.html")
#: How deep sub-directories of RUN_DIR are searched.
MAX_DEPTH = 2
#: Figures shown first (then the rest alphabetically).
_FIGURE_ORDER = ("trajectory", "sliding", "bands_", "terminal_errors", "envelope_recovery", "envelope_time")


@dataclass
class Section:
    """One directory of the run: its recognized files."""

    path: Path
    jsons: dict[str, dict] = field(default_factory=dict)
    pngs: list[Path] = field(default_factory=list)
    mds: list[Path] = field(default_factory=list)
    data: list[Path] = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return not (self.jsons or self.pngs or self.mds)


def _figure_key(p: Path) -> tuple[int, str]:
    for i, prefix in enumerate(_FIGURE_ORDER):
        if p.name.startswith(prefix):
            return i, p.name
    return len(_FIGURE_ORDER), p.name


def _read_json(path: Path) -> dict | None:
    try:
        d = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return d if isinstance(d, dict) else None


def scan(run_dir: Path, skip: Sequence[Path] = ()) -> list[Section]:
    """Sections of ``run_dir`` and its sub-directories (depth ``MAX_DEPTH``), in a stable order."""
    skip_resolved = {p.resolve() for p in skip}
    sections = []

    def visit(d: Path, depth: int) -> None:
        if d.resolve() in skip_resolved:
            return
        sec = Section(d)
        subdirs = []
        for f in sorted(d.iterdir()):
            if f.name.startswith("."):
                continue
            if f.is_dir():
                subdirs.append(f)
            elif f.name in REPORT_FILES:
                continue
            elif f.suffix == ".json":
                j = _read_json(f)
                if j is not None:
                    sec.jsons[f.name] = j
            elif f.suffix == ".png":
                sec.pngs.append(f)
            elif f.suffix == ".md":
                sec.mds.append(f)
            elif f.suffix in (".csv", ".npz", ".parquet"):
                sec.data.append(f)
        sec.pngs.sort(key=_figure_key)
        if not sec.empty:
            sections.append(sec)
        if depth < MAX_DEPTH:
            for s in subdirs:
                visit(s, depth + 1)

    visit(run_dir, 0)
    return sections


def provenance(sec: Section) -> tuple[list[str], list[Any], bool]:
    """(commands, seeds, reconstructed?) recorded in the section's JSON files."""
    commands, seeds, reconstructed = [], [], False
    for j in sec.jsons.values():
        if isinstance(j.get("command"), str):
            commands.append(j["command"])
        if "seed" in j and j["seed"] is not None:
            seeds.append(j["seed"])
    if not commands and "metrics.json" in sec.jsons:
        cmd = reconstruct_fly_command(sec.jsons["metrics.json"])
        if cmd:
            commands.append(cmd)
            reconstructed = True
    return list(dict.fromkeys(commands)), list(dict.fromkeys(seeds)), reconstructed


def run_kind(sec: Section) -> str:
    """What produced the section (e.g. ``Monte Carlo (harv-jax mc)``), or ``files``."""
    if "summary.json" in sec.jsons and "controllers" in sec.jsons["summary.json"]:
        return "Monte Carlo (harv-jax mc)"
    if "envelope.json" in sec.jsons:
        return "recovery envelope map (harv-jax envelope)"
    if "robustness.json" in sec.jsons:
        return "robustness margins (harv-jax robustness)"
    if any(p.name.startswith("compare_metrics") for p in sec.mds + sec.data):
        return "controller comparison (harv-jax compare)"
    if "metrics.json" in sec.jsons and "metrics" in sec.jsons["metrics.json"]:
        return "closed-loop flight (harv-jax fly)"
    return "files"
