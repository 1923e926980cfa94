"""The report's section of a robustness sweep (``robustness.json`` of ``harv-jax robustness``)."""

from __future__ import annotations

from typing import Any

from harv_jax.report.document import Doc


def _cell(v: Any, spec: str) -> str:
    return "–" if v is None else format(v, spec)


def robustness_section(doc: Doc, rob: dict[str, Any]) -> None:
    """Margins per controller and disturbance, then per disturbance a table of every level; the opening
    sentence names the aircraft when robustness.json records it."""
    ctrls = rob["controllers"]
    aircraft = f"Aircraft {rob['aircraft']}; " if rob.get("aircraft") is not None else ""
    doc.p(
        f"{aircraft}{rob['runs']} runs per level, seed {rob['seed']}, {rob['duration_s']:g} s; the margin is "
        "the largest level of the sweep up to which every level recovers at least "
        f"{rob['margin_recovery']:.0%} of the runs."
    )
    dists = rob["disturbances"]
    header = ["controller", *[f"{n} margin [{d['unit']}]" for n, d in dists.items()]]
    rows = []
    for c in ctrls:
        cells = []
        for d in dists.values():
            m = d["controllers"][c]["margin"]
            cells.append("< lowest level" if m is None else f"{m:g}")
        rows.append([c, *cells])
    doc.table(header, rows)
    for name, d in dists.items():
        doc.h(3, f"{name} [{d['unit']}]")
        header = ["level", *[f"{c}: recovered, mean [s], TV [rad]" for c in ctrls]]
        rows = []
        for i, level in enumerate(d["levels"]):
            cells = []
            for c in ctrls:
                r = d["controllers"][c]["rows"][i]
                cells.append(
                    f"{_cell(r['recovery_rate'], '.1%')}, {_cell(r['t_recover_mean_nr_at_run_s'], '.2f')}, "
                    f"{_cell(r['control_tv_mean_rad'], '.1f')}"
                )
            rows.append([f"{level:g}", *cells])
        doc.table(header, rows)
