"""The order of ``harv-jax evaluate``'s work: each condition's reference controllers, then each seed's
policy as RL-only and hybrid, each cell stored as it finishes and reused on ``--resume``; then the report."""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from harv_jax import atomic
from harv_jax.aircraft.registry import resolve_aircraft
from harv_jax.evaluation.seeds.conditions import (
    CONDITIONS,
    POLICY_CONTROLLERS,
    EvalSettings,
    Evaluator,
    cell_path,
    read_cell,
    write_cell,
)
from harv_jax.evaluation.seeds.report import build_document, figure, markdown
from harv_jax.machine import cpu_model


def load_policies(files: list[Path]) -> list[Any]:
    """The seeds' policies (validated on load); ValueError if their networks differ in size."""
    from harv_jax.policy import load
    from harv_jax.task.spaces import check_policy_sizes

    policies = [load(p) for p in files]
    shapes = {tuple(int(x.size) for x in _leaves(p.params)) for p in policies}
    if len(shapes) > 1:
        raise ValueError(
            f"the policies of {files[0].parent} differ in network size; one training run has one size"
        )
    check_policy_sizes(policies[0].networks.observation_size, policies[0].networks.action_size)
    return policies


def _leaves(tree: Any) -> list[Any]:
    import jax

    return jax.tree.leaves(tree)


def run_evaluation(
    out: Path,
    settings: EvalSettings,
    record: dict[str, Any],
    files: list[Path],
    command: str,
    echo: Callable[[str], None] = print,
) -> dict[str, Any]:
    """Fly every cell not yet stored in ``out``, then write ``evaluate.json``, ``evaluate.md`` and
    ``evaluate.png``. Returns the document."""
    t0 = time.perf_counter()
    policies = load_policies(files)
    _, nominal = resolve_aircraft(record.get("aircraft"))  # the aircraft the run trained on
    ev = Evaluator(settings, policies, nominal)
    cells: dict[str, dict[str, Any]] = {}
    reused = flown = 0
    for cname in settings.conditions:
        cond = CONDITIONS[cname]
        runs = 1 if cond.disturbances is None else settings.runs
        todo: list[tuple[str, Callable[[], Any], dict[str, Any]]] = [
            (b, lambda b=b, c=cond: ev.baseline(c, b), settings.record()) for b in cond.baselines
        ]
        for seed, pol in enumerate(record["policies"]):
            for kind in POLICY_CONTROLLERS:
                stamp = {**settings.record(), "policy_sha256": pol["sha256"]}
                todo.append(
                    (f"{kind}_seed{seed}", lambda k=kind, s=seed, c=cond: ev.policy_cell(c, k, s), stamp)
                )
        cells[cname] = {}
        for name, fly, stamp in todo:
            path = cell_path(out, cname, name)
            cell = read_cell(path, stamp, runs)
            if cell is None:
                t1 = time.perf_counter()
                cell = fly()
                write_cell(path, cell, stamp)
                flown += 1
                wall = time.perf_counter() - t1
                echo(f"{cname} {name}: recovered {cell['recovered'].mean():.1%} ({wall:.0f} s)")
            else:
                reused += 1
            cells[cname][name] = cell
    doc = build_document(
        {
            **record,
            "command": command,
            "cpu_model": cpu_model(),
            "cells_flown": flown,
            "cells_reused": reused,
        },
        [{k: p[k] for k in ("seed", "policy", "sha256")} for p in record["policies"]],
        cells,
        settings.duration_s,
    )
    doc["wall_s"] = round(time.perf_counter() - t0, 1)
    atomic.write_text(out / "evaluate.json", json.dumps(doc, indent=1, default=_json) + "\n")
    atomic.write_text(out / "evaluate.md", markdown(doc))
    figure(doc, out / "evaluate.png")
    verdict = "every seed passes" if doc["all_seeds_pass"] else "not every seed passes"
    echo(f"{verdict} the required criteria; wrote {out}/evaluate.json, evaluate.md, evaluate.png")
    return doc


def _json(v: Any) -> Any:
    """numpy scalars as Python numbers."""
    return v.item() if hasattr(v, "item") else str(v)
