"""The report's sections: tables of a ``harv-jax mc`` summary.json, a ``compare`` compare.json, an
``envelope`` envelope.json and a ``fly`` metrics.json, read through the layout of
``harv_jax.evaluation.summary``."""

from __future__ import annotations

import math
import shlex
from collections.abc import Sequence
from typing import Any

from harv_jax.aircraft.registry import DEFAULT_AIRCRAFT
from harv_jax.control.registry import CONTROLLERS, split_filter
from harv_jax.evaluation.summary import (
    FLY_SETTING_KEYS,
    MC_HYBRID_ROWS,
    MC_OUTCOME_ROWS,
    MC_RECOVERY_ROWS,
    MC_VS_SMC_ROWS,
    WALL_ROWS,
    Row,
    envelope_rows,
    terminal_rows,
)
from harv_jax.report.document import Doc, fmt
from harv_jax.task.spec import H0_FT


def _deg(rad: Any) -> float | None:
    return None if rad is None else math.degrees(float(rad))


def _has(d: Any, path: Sequence[str]) -> bool:
    for k in path:
        if not isinstance(d, dict) or k not in d:
            return False
        d = d[k]
    return True


def _get(d: Any, path: Sequence[str]) -> Any:
    for k in path:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def _cell(block: dict, path: tuple[str, ...], spec: str) -> str:
    v = _get(block, path)
    if spec == "p5/p50/p95":
        return " / ".join(fmt(_get(v, (k,)), ".3f") for k in ("p5", "p50", "p95"))
    if spec == "within":
        return " / ".join(fmt(_get(v, (k,)), "pct") for k in ("within_0p5", "within_2"))
    return fmt(v, spec)


def controller_table(controllers: dict[str, dict], rows: Sequence[Row]) -> tuple[list[str], list[list[str]]]:
    """(header, rows) with one column per controller; rows absent from every controller are dropped (a
    value that is present but null, e.g. the recovery time when nothing recovered, is shown as '–')."""
    names = list(controllers)
    header = ["metric", *names]
    out = []
    for label, path, spec in rows:
        cells = [_cell(controllers[n], path, spec) for n in names]
        if any(_has(controllers[n], path) for n in names):
            out.append([label, *cells])
    return header, out


def _disturbances(block: Any) -> str:
    """The summary's disturbances in one cell ("none" for an undisturbed run or an older summary)."""
    if not isinstance(block, dict) or not block.get("active"):
        return "none"
    units = block.get("units", {})
    parts = [f"{n} {block.get(n + '_level', '?'):g} {units.get(n, '')}".strip() for n in block["active"]]
    if "model" in block["active"]:
        knows = block.get("controller_knows_aircraft")
        parts.append("controllers on the " + ("plant's aircraft" if knows else "nominal aircraft"))
    return ", ".join(parts)


def mc_section(doc: Doc, summary: dict) -> None:
    """Tables of a ``harv-jax mc`` summary.json."""
    ctrls = summary.get("controllers") or {}
    settings = [
        ("runs", fmt(summary.get("runs"), "int")),
        ("target alpha [rad]", fmt(summary.get("target_alpha_rad"))),
        ("target alpha [deg]", fmt(_deg(summary.get("target_alpha_rad")), ".1f")),
        ("initial altitude h0 [ft]", fmt(summary.get("h0_ft", H0_FT), "int")),
        ("duration [s]", fmt(summary.get("duration_s"))),
        ("step [s]", fmt(summary.get("dt_s"))),
        ("seed", str(summary["seed"]) if summary.get("seed") is not None else "–"),
        ("aircraft", str(summary.get("aircraft", "–"))),
        ("randomized aircraft", fmt(summary.get("randomize"))),
        ("disturbances", _disturbances(summary.get("disturbances"))),
        ("devices", ", ".join(summary.get("devices") or []) or "–"),
    ]
    for key, label in (("policy", "policy"), ("zeta_schedule", "ζ schedule")):
        if summary.get(key) is not None:
            settings.append((label, fmt(summary[key])))
    doc.table(["setting", "value"], settings, numeric=False)
    if not ctrls:
        doc.p("summary.json lists no controller.")
        return
    doc.h(3, "Recovery and control activity")
    units = {b.get("safety_interventions_unit") for b in ctrls.values()} - {None}
    rows = tuple(
        (f"{label} [{', '.join(sorted(units))}]", path, spec)
        if label == "safety-filter interventions" and units
        else (label, path, spec)
        for label, path, spec in MC_RECOVERY_ROWS + MC_HYBRID_ROWS
    )
    doc.table(*controller_table(ctrls, rows))
    doc.p(
        "Safety-filter interventions: steps of a run at which the hybrid's safety filter changed the "
        "learned command (its authority cap, or the rate and position box while the policy acts). ζ is the "
        "SMC's share of the hybrid's command (0: the policy alone, 1: the SMC alone); a hand-over is a step "
        "at which ζ, averaged over the three channels, crossed ½ (the hybrid starts with ζ = 0). The simplex "
        "schedule hands over to the SMC for good, so ζ can be active for much of a run after one hand-over. "
        "Tube switches count only the hysteresis schedule's tube; supervisor fallbacks the supervisor's "
        "SMC-only mode. '–': the counter does not apply to that controller."
    )
    header, vs_rows = controller_table(ctrls, MC_VS_SMC_ROWS)
    if vs_rows:
        run_s = fmt(summary.get("duration_s"), "g")
        doc.h(3, "Against the SMC, run by run")
        doc.p(
            "Every controller flies the same runs (common random numbers); run i of a controller is compared "
            f"with run i of smc, a run not recovered counting at the run length ({run_s} s)."
        )
        doc.table(header, vs_rows)
    doc.h(3, "Terminal tracking errors [deg] (mean over the last second of each run)")
    doc.table(*controller_table(ctrls, terminal_rows()))
    doc.h(3, "Outcomes [runs]")
    doc.table(*controller_table(ctrls, MC_OUTCOME_ROWS))
    doc.h(3, "Wall time (compile and run separately)")
    doc.table(*controller_table(ctrls, WALL_ROWS))


def compare_section(doc: Doc, cmp: dict) -> None:
    """Settings of a ``harv-jax compare`` compare.json (its metrics table is compare_metrics.md, included
    as it is); a setting the file does not record is left out, the aircraft shown as '–'."""
    spin_s = cmp.get("spin_s")
    settings = [
        ("controllers", ", ".join(cmp["controllers"]) if isinstance(cmp.get("controllers"), list) else None),
        ("target alpha [rad]", fmt(cmp.get("target_alpha_rad")) if "target_alpha_rad" in cmp else None),
        ("duration [s]", fmt(cmp.get("duration_s")) if "duration_s" in cmp else None),
        ("spin before engagement [s]", fmt(spin_s) if spin_s is not None else None),
        ("seed", str(cmp["seed"]) if cmp.get("seed") is not None else None),
        ("aircraft", str(cmp.get("aircraft", "–"))),
        ("disturbances", _disturbances(cmp["disturbances"]) if "disturbances" in cmp else None),
    ]
    doc.table(["setting", "value"], [(k, v) for k, v in settings if v is not None], numeric=False)
    for line in identical_flights(cmp.get("rows") or []):
        doc.p(line)


#: compare.json row fields that name a row rather than measure its flight.
_ROW_NAMES = ("scenario", "controller", "recovery_time_vs_smc")


def identical_flights(rows: list[dict]) -> list[str]:
    """One sentence per scenario on which controllers flew exactly the same flight (every metric equal):
    the later ones' own logic never engaged there, which the table alone does not say."""
    lines = []
    for scenario in dict.fromkeys(r.get("scenario") for r in rows):
        groups: dict[tuple, list[str]] = {}
        for r in rows:
            if r.get("scenario") == scenario:
                key = tuple(sorted((k, str(v)) for k, v in r.items() if k not in _ROW_NAMES))
                groups.setdefault(key, []).append(str(r.get("controller")))
        for names in groups.values():
            if len(names) > 1:
                lines.append(
                    f"On {scenario}, {', '.join(names[1:])} flew exactly as {names[0]} (every metric equal): "
                    "what they add to it (see Controllers above) did not engage on this flight."
                )
    return lines


def controllers_section(doc: Doc, names: list[str]) -> None:
    """Each controller of the report, introduced once, before any table names it (the registry's help)."""

    rows = []
    for name in names:
        try:
            base, path = split_filter(name)
        except ValueError:
            base, path = name, None
        text = CONTROLLERS[base].help if base in CONTROLLERS else "a controller registered by the user"
        if path is not None:
            text += f"; its measurements through {path.suffix.lstrip('+')} at {path.bandwidth_hz:g} Hz"
        rows.append((name, text))
    doc.table(["controller", "what it is"], rows, numeric=False)


def envelope_section(doc: Doc, env: dict) -> None:
    """Grid description and per-controller table of a ``harv-jax envelope`` envelope.json."""
    grid = env.get("grid") or {}
    rows = []
    for key in ("x", "y"):
        a = grid.get(key) or {}
        scale = a.get("display_scale") or 1.0
        lo, hi = (None if a.get(k) is None else a[k] * scale for k in ("low", "high"))
        rng = f"{fmt(lo)} .. {fmt(hi)}"
        rows.append(
            (f"{key}: {a.get('name', '?')}", f"{rng} {a.get('display_unit', '')} ({a.get('n')} points)")
        )
    fixed = grid.get("fixed_state") or {}
    rows.append(("fixed initial states", ", ".join(f"{k}0 = {v:g}" for k, v in fixed.items()) or "–"))
    rows.append(("runs per controller", fmt(env.get("runs_per_controller"), "int")))
    rows.append(("target alpha [rad]", fmt(env.get("target_alpha_rad"))))
    rows.append(("duration [s]", fmt(env.get("duration_s"))))
    rows.append(("aircraft", str(env.get("aircraft", "–"))))
    if env.get("policy") is not None:
        rows.append(("policy", str(env["policy"])))
    doc.table(["setting", "value"], rows, numeric=False)
    ctrls = env.get("controllers") or {}
    if not ctrls:
        return
    codes = list(dict.fromkeys(c for b in ctrls.values() for c in (b.get("outcome_counts") or {})))
    env_rows = envelope_rows(codes)
    doc.h(3, "Per controller (every grid point counts once)")
    doc.table(*controller_table(ctrls, env_rows))


def fly_section(doc: Doc, metrics_doc: dict) -> None:
    """Settings and scalar metrics of a ``harv-jax fly`` metrics.json."""
    keys = FLY_SETTING_KEYS

    def cell(v: Any) -> str:
        return ", ".join(fmt(x) for x in v) if isinstance(v, list) else fmt(v)

    doc.table(["setting", "value"], [(k, cell(metrics_doc[k])) for k in keys if k in metrics_doc], False)
    m = dict(metrics_doc.get("metrics") or {})
    if "outcome_name" in m:
        m["outcome"] = m.pop("outcome_name")  # the name instead of the integer code
    m.pop("outcome_code", None)
    rows = [(k, cell(v)) for k, v in m.items()]
    if rows:
        doc.h(3, "Metrics (lists: per channel alpha, beta, mu or de, da, dr)")
        doc.table(["metric", "value"], rows, numeric=False)


def reconstruct_fly_command(metrics_doc: dict) -> str | None:
    """The ``harv-jax fly`` command equivalent to a metrics.json's settings (it records none)."""

    if "controller" not in metrics_doc or "scenario" not in metrics_doc:
        return None
    parts = [
        "harv-jax",
        "fly",
        "--controller",
        str(metrics_doc["controller"]),
        "--scenario",
        str(metrics_doc["scenario"]),
    ]
    ref = metrics_doc.get("reference_rad")
    opts = (
        ("--target-alpha", ref[0] if ref else None),
        ("--duration", metrics_doc.get("duration_s")),
        ("--seed", metrics_doc.get("seed")),
        ("--switching", metrics_doc.get("switching")),
        ("--spin-s", metrics_doc.get("spin_s")),
    )
    if metrics_doc.get("aircraft") not in (None, DEFAULT_AIRCRAFT):
        opts += (("--aircraft", metrics_doc["aircraft"]),)
    for flag, v in opts:
        if v is not None:
            parts += [flag, str(v)]
    return " ".join(shlex.quote(p) for p in parts)
