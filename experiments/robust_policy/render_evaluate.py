"""Redraw ``evaluate.md`` and ``evaluate.png`` of ``harv-jax evaluate`` folders from their ``evaluate.json``.

The study commits each evaluation's ``evaluate.json`` (every number of the report); the table and the figure
are drawn from it by the same functions ``harv-jax evaluate`` uses::

    python experiments/robust_policy/render_evaluate.py experiments/robust_policy/results/*_eval
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from harv_jax import atomic
from harv_jax.evaluation.seeds.report import figure, markdown


def render(folder: Path) -> None:
    """Write ``folder/evaluate.md`` and ``folder/evaluate.png`` from ``folder/evaluate.json``."""
    doc = json.loads((folder / "evaluate.json").read_text())
    atomic.write_text(folder / "evaluate.md", markdown(doc))
    figure(doc, folder / "evaluate.png")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path, help="folders holding an evaluate.json")
    for folder in ap.parse_args().folders:
        if not (folder / "evaluate.json").is_file():
            raise SystemExit(f"{folder}: no evaluate.json (a harv-jax evaluate folder holds one)")
        render(folder)
        print(f"wrote {folder}/evaluate.md, evaluate.png")


if __name__ == "__main__":
    main()
