"""`harv-jax report RUN_DIR`: the figures and tables of a run directory as report.md and report.html.

Recognized content, in RUN_DIR and its sub-directories (two levels, e.g. a ``quickstart`` dir's
``spin/`` and ``mc/``):

- ``summary.json`` of ``harv-jax mc``: tables with one column per controller (recovery, terminal errors
  in degrees, altitude loss, control activity, outcomes, wall times);
- ``envelope.json`` of ``harv-jax envelope``: the grid and a table per controller;
- ``metrics.json`` of ``harv-jax fly``: the run's settings and scalar metrics;
- any other ``*.md`` (e.g. ``compare_metrics.md`` of ``harv-jax compare``): included as it is;
- every ``*.png``: linked from report.md, embedded as base64 in report.html (a standalone page);
- ``*.csv`` / ``*.npz``: listed as data files.

The commands and seeds that produced the run (``"command"`` and ``"seed"`` of the JSON files) head the
report. Without ``--out`` both files go into RUN_DIR itself (refused if they exist, unless ``--force``).
"""

from __future__ import annotations

import base64
import html
import json
import math
import os
import re
import shlex
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import typer

from harv_jax.errors import UsageError

REPORT_FILES = ("report.md", "report.html")
#: How deep sub-directories of RUN_DIR are searched.
MAX_DEPTH = 2
#: Figures shown first (then the rest alphabetically).
_FIGURE_ORDER = ("trajectory", "sliding", "bands_", "terminal_errors", "envelope_recovery", "envelope_time")
_GREEK = {"alpha": "α", "beta": "β", "mu": "μ"}


# ----------------------------------------------------------------------------------------------------
# A small document model rendered to Markdown and to HTML.


@dataclass
class Doc:
    """Blocks of a report: ("h", level, text), ("p", text), ("table", header, rows), ("code", text),
    ("img", path, caption), ("md", raw markdown text)."""

    blocks: list[tuple] = field(default_factory=list)

    def h(self, level: int, text: str) -> None:
        self.blocks.append(("h", level, text))

    def p(self, text: str) -> None:
        self.blocks.append(("p", text))

    def table(self, header: Sequence[str], rows: Sequence[Sequence[str]], numeric: bool = True) -> None:
        """``numeric``: columns after the first are right-aligned (numbers); else all left-aligned."""
        self.blocks.append(("table", list(header), [list(r) for r in rows], numeric))

    def code(self, text: str) -> None:
        self.blocks.append(("code", text))

    def img(self, path: Path, caption: str) -> None:
        self.blocks.append(("img", path, caption))

    def md(self, text: str) -> None:
        self.blocks.append(("md", text))


def _md_cell(s: str) -> str:
    return str(s).replace("|", "\\|").replace("\n", " ")


def to_markdown(doc: Doc, report_dir: Path) -> str:
    """Markdown text; images are linked relative to ``report_dir``."""
    out: list[str] = []
    for b in doc.blocks:
        kind = b[0]
        if kind == "h":
            out.append("#" * b[1] + " " + b[2])
        elif kind == "p":
            out.append(b[1])
        elif kind == "table":
            header, rows, numeric = b[1], b[2], b[3]
            out.append("| " + " | ".join(_md_cell(c) for c in header) + " |")
            out.append("|" + "|".join("---:" if i and numeric else "---" for i in range(len(header))) + "|")
            out.extend("| " + " | ".join(_md_cell(c) for c in r) + " |" for r in rows)
        elif kind == "code":
            out.append("```\n" + b[1].rstrip("\n") + "\n```")
        elif kind == "img":
            rel = Path(os.path.relpath(b[1], report_dir)).as_posix()
            out.append(f"![{b[2]}]({rel})")
        elif kind == "md":
            out.append(b[1].rstrip("\n"))
        out.append("")
    return "\n".join(out)


def _html_table(header: Sequence[str], rows: Sequence[Sequence[str]], numeric: bool = True) -> str:
    th = "".join(f"<th>{html.escape(str(c))}</th>" for c in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    cls = "" if numeric else ' class="text"'
    return f"<table{cls}><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>"


_MD_RULE = re.compile(r"^\|?\s*:?-{3,}:?\s*(\|\s*:?-{3,}:?\s*)*\|?\s*$")


def _split_md_row(line: str) -> list[str]:
    s = line.strip()
    s = s[1:] if s.startswith("|") else s
    s = s[:-1] if s.endswith("|") and not s.endswith("\\|") else s
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", s)]


def markdown_to_html(text: str) -> str:
    """The Markdown subset of the run directories' tables: pipe tables, ``#`` headings, fenced code and
    paragraphs (everything else is shown as escaped text)."""
    lines = text.splitlines()
    out: list[str] = []
    i = 0
    para: list[str] = []

    def flush() -> None:
        if para:
            out.append("<p>" + html.escape(" ".join(para)) + "</p>")
            para.clear()

    while i < len(lines):
        line = lines[i]
        if line.strip().startswith("```"):
            flush()
            j = i + 1
            while j < len(lines) and not lines[j].strip().startswith("```"):
                j += 1
            out.append("<pre><code>" + html.escape("\n".join(lines[i + 1 : j])) + "</code></pre>")
            i = j + 1
            continue
        if line.lstrip().startswith("|") and i + 1 < len(lines) and _MD_RULE.match(lines[i + 1]):
            flush()
            header = _split_md_row(line)
            j = i + 2
            rows = []
            while j < len(lines) and lines[j].lstrip().startswith("|"):
                rows.append(_split_md_row(lines[j]))
                j += 1
            out.append(_html_table(header, rows))
            i = j
            continue
        m = re.match(r"^(#{1,6})\s+(.*)$", line)
        if m:
            flush()
            level = min(6, len(m.group(1)) + 2)  # included files sit below the report's own headings
            out.append(f"<h{level}>{html.escape(m.group(2))}</h{level}>")
        elif line.strip():
            para.append(line.strip())
        else:
            flush()
        i += 1
    flush()
    return "\n".join(out)


_CSS = """body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:0.6em 0 1.2em}th,td{border:1px solid #ccc;padding:3px 8px}
td{text-align:right}td:first-child,table.text td{text-align:left}th{background:#f0f0f0}
pre{background:#f6f6f6;padding:0.6em;overflow-x:auto}figure{margin:1em 0}img{max-width:100%}
figcaption{color:#555;font-size:0.9em}"""


def to_html(doc: Doc, title: str) -> str:
    """A standalone HTML page: tables as HTML, PNGs embedded as base64 data URIs."""
    body: list[str] = []
    for b in doc.blocks:
        kind = b[0]
        if kind == "h":
            body.append(f"<h{b[1]}>{html.escape(b[2])}</h{b[1]}>")
        elif kind == "p":
            body.append(f"<p>{html.escape(b[1])}</p>")
        elif kind == "table":
            body.append(_html_table(b[1], b[2], b[3]))
        elif kind == "code":
            body.append(f"<pre><code>{html.escape(b[1])}</code></pre>")
        elif kind == "img":
            data = base64.b64encode(Path(b[1]).read_bytes()).decode("ascii")
            cap = html.escape(b[2])
            body.append(
                f'<figure><img src="data:image/png;base64,{data}" alt="{cap}">'
                f"<figcaption>{cap}</figcaption></figure>"
            )
        elif kind == "md":
            body.append(markdown_to_html(b[1]))
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>\n"
        + "\n".join(body)
        + "\n</body></html>\n"
    )


# ----------------------------------------------------------------------------------------------------
# Number formatting and the tables of each kind of run directory.


def fmt(v: Any, spec: str = ".4g") -> str:
    """A table cell: '–' for missing/NaN; spec 'pct' (fraction -> percent), 'int' or a format spec."""
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, str):
        return v
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    if x != x:  # NaN
        return "–"
    if spec == "pct":
        return f"{100.0 * x:.1f}%"
    if spec == "int":
        return f"{int(round(x)):,}"
    return format(x, spec)


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


Row = tuple[str, tuple[str, ...], str]

MC_RECOVERY_ROWS: tuple[Row, ...] = (
    ("recovery rate", ("recovery_rate",), "pct"),
    ("recovery time mean [s]", ("recovery_time_s", "mean"), ".2f"),
    ("recovery time p50 [s]", ("recovery_time_s", "p50"), ".2f"),
    ("recovery time p95 [s]", ("recovery_time_s", "p95"), ".2f"),
    ("altitude loss mean [ft]", ("altitude_loss_ft", "mean"), ",.0f"),
    ("altitude loss p95 [ft]", ("altitude_loss_ft", "p95"), ",.0f"),
    ("control total variation mean [rad]", ("control_tv", "mean"), ".3g"),
    ("chatter index mean [rad²]", ("chatter_index", "mean"), ".3g"),
    ("position saturation fraction", ("saturation_fraction",), ".3f"),
    ("rate saturation fraction", ("rate_saturation_fraction",), ".3f"),
    ("safety interventions", ("safety_interventions",), ".4g"),
    ("left envelope (fraction of runs)", ("left_envelope_fraction",), ".3f"),
)
#: Hybrid diagnostics (present for every controller in newer summaries; '–' where not applicable).
MC_HYBRID_ROWS: tuple[Row, ...] = (
    ("ζ active (fraction of steps)", ("hybrid", "zeta_active_fraction"), ".3f"),
    ("ζ switches per run", ("hybrid", "zeta_switches_per_run"), ".3g"),
    ("supervisor fallback (fraction of steps)", ("hybrid", "fallback_fraction"), ".3f"),
    ("supervisor fallbacks per run", ("hybrid", "fallbacks_per_run"), ".3g"),
)
MC_OUTCOME_ROWS: tuple[Row, ...] = tuple(
    (name, ("outcomes", name), "int") for name in ("recovered", "departed", "nonfinite", "timeout")
) + (("ground hits (in departed)", ("ground_hits_in_departed",), "int"),)
WALL_ROWS: tuple[Row, ...] = (
    ("compile [s]", ("wall_time_s", "compile"), ".1f"),
    ("run [s]", ("wall_time_s", "run"), ".2f"),
)


def _terminal_rows() -> tuple[Row, ...]:
    rows: list[Row] = []
    for ch in ("alpha", "beta", "mu"):
        g = _GREEK[ch]
        base = ("terminal_error_deg", ch)
        rows += [
            (f"{g} mean", base + ("mean",), ".3f"),
            (f"{g} std", base + ("std",), ".3f"),
            (f"{g} p5 / p50 / p95", base, "p5/p50/p95"),
            (f"{g} within 0.5° / 2°", base, "within"),
        ]
    return tuple(rows)


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


def mc_section(doc: Doc, summary: dict) -> None:
    """Tables of a ``harv-jax mc`` summary.json."""
    ctrls = summary.get("controllers") or {}
    settings = [
        ("runs", fmt(summary.get("runs"), "int")),
        ("target alpha [rad]", fmt(summary.get("target_alpha_rad"))),
        ("target alpha [deg]", fmt(_deg(summary.get("target_alpha_rad")), ".1f")),
        ("initial altitude h0 [ft]", fmt(summary.get("h0_ft", 25_000.0), "int")),
        ("duration [s]", fmt(summary.get("duration_s"))),
        ("step [s]", fmt(summary.get("dt_s"))),
        ("seed", str(summary["seed"]) if summary.get("seed") is not None else "–"),
        ("randomized aircraft", fmt(summary.get("randomize"))),
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
        (f"{label} [{', '.join(sorted(units))}]", path, spec) if label == "safety interventions" and units
        else (label, path, spec)
        for label, path, spec in MC_RECOVERY_ROWS + MC_HYBRID_ROWS
    )  # fmt: skip
    doc.table(*controller_table(ctrls, rows))
    doc.h(3, "Terminal tracking errors [deg] (mean over the last second of each run)")
    doc.table(*controller_table(ctrls, _terminal_rows()))
    doc.h(3, "Outcomes [runs]")
    doc.table(*controller_table(ctrls, MC_OUTCOME_ROWS))
    doc.h(3, "Wall time (compile and run separately)")
    doc.table(*controller_table(ctrls, WALL_ROWS))


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
    env_rows: tuple[Row, ...] = (
        ("recovery fraction", ("recovery_fraction",), "pct"),
        *((f"outcome {c.lower()}", ("outcome_counts", c), "int") for c in codes),
        *MC_RECOVERY_ROWS[1:6],
        *MC_HYBRID_ROWS,
        *WALL_ROWS,
    )
    doc.h(3, "Per controller (every grid point counts once)")
    doc.table(*controller_table(ctrls, env_rows))


def fly_section(doc: Doc, metrics_doc: dict) -> None:
    """Settings and scalar metrics of a ``harv-jax fly`` metrics.json."""
    keys = ("controller", "scenario", "switching", "seed", "duration_s", "dt_s", "reference_rad", "spin_s",
            "t_engage_s")  # fmt: skip

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
    parts = ["harv-jax", "fly", "--controller", str(metrics_doc["controller"]), "--scenario",
             str(metrics_doc["scenario"])]  # fmt: skip
    ref = metrics_doc.get("reference_rad")
    opts = (("--target-alpha", ref[0] if ref else None), ("--duration", metrics_doc.get("duration_s")),
            ("--seed", metrics_doc.get("seed")), ("--switching", metrics_doc.get("switching")),
            ("--spin-s", metrics_doc.get("spin_s")))  # fmt: skip
    for flag, v in opts:
        if v is not None:
            parts += [flag, str(v)]
    return " ".join(shlex.quote(p) for p in parts)


# ----------------------------------------------------------------------------------------------------
# Finding the content of a run directory.


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


def _kind(sec: Section) -> str:
    if "summary.json" in sec.jsons and "controllers" in sec.jsons["summary.json"]:
        return "Monte Carlo (harv-jax mc)"
    if "envelope.json" in sec.jsons:
        return "recovery envelope map (harv-jax envelope)"
    if any(p.name.startswith("compare_metrics") for p in sec.mds + sec.data):
        return "controller comparison (harv-jax compare)"
    if "metrics.json" in sec.jsons and "metrics" in sec.jsons["metrics.json"]:
        return "closed-loop flight (harv-jax fly)"
    return "files"


def build_document(run_dir: Path, sections: list[Section], report_cmd: str) -> Doc:
    """The report of ``sections`` of ``run_dir`` as a ``Doc``."""
    doc = Doc()
    doc.h(1, f"Report: {run_dir.name or run_dir}")
    doc.p(f"Run directory: {run_dir}")
    doc.h(2, "How it was produced")
    rows = []
    for sec in sections:
        cmds, seeds, rec = provenance(sec)
        rel = sec.path.relative_to(run_dir).as_posix() if sec.path != run_dir else "."
        for c in cmds or ["(not recorded)"]:
            rows.append(
                [rel, c + (" (reconstructed)" if rec else ""), ", ".join(str(s) for s in seeds) or "–"]
            )
    doc.table(["directory", "command", "seed"], rows, numeric=False)
    doc.p(f"This report: {report_cmd}")
    for sec in sections:
        rel = sec.path.relative_to(run_dir).as_posix() if sec.path != run_dir else run_dir.name
        kind = _kind(sec)
        doc.h(2, f"{rel}: {kind}")
        cmds, seeds, rec = provenance(sec)
        if cmds:
            doc.code("\n".join(cmds))
        if seeds:
            doc.p("seed: " + ", ".join(str(s) for s in seeds) + (" (command reconstructed)" if rec else ""))
        if "summary.json" in sec.jsons and "controllers" in sec.jsons["summary.json"]:
            mc_section(doc, sec.jsons["summary.json"])
        if "envelope.json" in sec.jsons:
            envelope_section(doc, sec.jsons["envelope.json"])
        if "metrics.json" in sec.jsons and "metrics" in sec.jsons["metrics.json"]:
            fly_section(doc, sec.jsons["metrics.json"])
        for md in sec.mds:
            doc.h(3, md.name)
            doc.md(md.read_text())
        if sec.pngs:
            doc.h(3, "Figures")
            for png in sec.pngs:
                doc.img(png, png.name)
        if sec.data:
            doc.p(
                "Data files: " + ", ".join(f"{p.name} ({p.stat().st_size / 1024:,.0f} KiB)" for p in sec.data)
            )
    return doc


def _prepare(run_dir: Path, out: Path | None, force: bool) -> Path:
    """The report directory (created); UsageError when it would overwrite something without --force."""
    from harv_jax.outdir import prepare_out_dir

    if out is None or out.resolve() == run_dir.resolve():
        existing = [n for n in REPORT_FILES if (run_dir / n).exists()]
        if existing and not force:
            raise UsageError(
                f"{', '.join(existing)} already exist in {str(run_dir)!r}; pass --force or choose --out"
            )
        return run_dir
    if run_dir.resolve().is_relative_to(out.resolve()):
        raise UsageError(f"--out {str(out)!r} contains RUN_DIR {str(run_dir)!r}; choose another directory")
    return prepare_out_dir(out, force)


def build_report(run_dir: Path, out: Path | None = None, force: bool = False,
                 report_cmd: str | None = None) -> tuple[Path, Path]:  # fmt: skip
    """Write report.md and report.html for ``run_dir`` (into ``out``, default ``run_dir``).

    Args:
        run_dir: the run directory.
        out: report directory; None or ``run_dir``: the files go into ``run_dir``.
        force: replace existing report files / a non-empty ``out``.
        report_cmd: the command shown as producing the report (default: ``harv-jax report RUN_DIR``).

    Returns:
        (report.md path, report.html path).

    Raises:
        UsageError: RUN_DIR missing or without recognizable content; output exists without ``force``.
    """
    run_dir = Path(run_dir)
    out = None if out is None else Path(out)
    if not run_dir.is_dir():
        raise UsageError(f"RUN_DIR {str(run_dir)!r} is not a directory")
    # a report directory inside RUN_DIR (from an earlier report) is not part of the run
    skip = [out] if out is not None and out.exists() and out.resolve() != run_dir.resolve() else []
    sections = scan(run_dir, skip)
    if not sections:
        raise UsageError(
            f"RUN_DIR {str(run_dir)!r} holds no summary.json, envelope.json, metrics.json, *.png or *.md "
            f"(searched {MAX_DEPTH} levels of sub-directories)"
        )
    report_dir = _prepare(run_dir, out, force)
    if report_cmd is None:
        report_cmd = f"harv-jax report {shlex.quote(str(run_dir))}"
        if report_dir.resolve() != run_dir.resolve():
            report_cmd += f" --out {shlex.quote(str(report_dir))}"
    doc = build_document(run_dir, sections, report_cmd)
    md_path, html_path = report_dir / REPORT_FILES[0], report_dir / REPORT_FILES[1]
    md_path.write_text(to_markdown(doc, report_dir))
    html_path.write_text(to_html(doc, f"harv-jax report: {run_dir.name}"))
    return md_path, html_path


def register(app: typer.Typer) -> None:
    @app.command()
    def report(
        run_dir: Path = typer.Argument(..., help="A run directory (mc, compare, envelope, fly, quickstart)."),
        out: Path = typer.Option(None, help="Report directory (default: RUN_DIR itself)."),
        force: bool = typer.Option(False, help="Replace an existing report / non-empty --out directory."),
    ) -> None:
        """Markdown + standalone HTML report of a run directory's figures and tables, with its commands."""
        cmd = "harv-jax " + " ".join(shlex.quote(a) for a in sys.argv[1:])
        md_path, html_path = build_report(run_dir, out, force, cmd)
        typer.echo(f"wrote {md_path} and {html_path}")
