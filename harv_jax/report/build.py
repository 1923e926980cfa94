"""The report of a run directory: its sections as one document, written as report.md and report.html."""

from __future__ import annotations

import shlex
from pathlib import Path

from harv_jax import atomic
from harv_jax.errors import UsageError
from harv_jax.outdir import note_incomplete, prepare_out_dir
from harv_jax.report.document import Doc, to_html, to_markdown
from harv_jax.report.robustness_section import robustness_section
from harv_jax.report.scan import MAX_DEPTH, REPORT_FILES, Section, provenance, run_kind, scan
from harv_jax.report.sections import (
    compare_section,
    controllers_section,
    envelope_section,
    fly_section,
    mc_section,
)
from harv_jax.report.train_section import train_section


def report_controllers(sections: list[Section]) -> list[str]:
    """Every controller the sections name, in order of first appearance."""
    names: list[str] = []
    for sec in sections:
        j = sec.jsons
        for doc_name in ("compare.json", "summary.json", "envelope.json", "robustness.json"):
            ctrls = j.get(doc_name, {}).get("controllers")
            if isinstance(ctrls, dict | list):
                names += [str(c) for c in ctrls]
        fly = j.get("metrics.json", {}).get("controller")
        if fly is not None:
            names.append(str(fly))
    return list(dict.fromkeys(names))


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
    names = report_controllers(sections)
    if names:
        doc.h(2, "Controllers")
        controllers_section(doc, names)
    for sec in sections:
        rel = sec.path.relative_to(run_dir).as_posix() if sec.path != run_dir else run_dir.name
        kind = run_kind(sec)
        doc.h(2, f"{rel}: {kind}")
        cmds, seeds, rec = provenance(sec)
        if cmds:
            doc.code("\n".join(cmds))
        if seeds:
            doc.p("seed: " + ", ".join(str(s) for s in seeds) + (" (command reconstructed)" if rec else ""))
        if "summary.json" in sec.jsons and "controllers" in sec.jsons["summary.json"]:
            mc_section(doc, sec.jsons["summary.json"])
        if "summary.json" in sec.jsons and "seeds" in sec.jsons["summary.json"]:
            train_section(doc, sec.jsons["summary.json"])
        if "compare.json" in sec.jsons:
            compare_section(doc, sec.jsons["compare.json"])
        if "envelope.json" in sec.jsons:
            envelope_section(doc, sec.jsons["envelope.json"])
        if "metrics.json" in sec.jsons and "metrics" in sec.jsons["metrics.json"]:
            fly_section(doc, sec.jsons["metrics.json"])
        if "robustness.json" in sec.jsons and "disturbances" in sec.jsons["robustness.json"]:
            robustness_section(doc, sec.jsons["robustness.json"])
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

    if out is None or out.resolve() == run_dir.resolve():
        existing = [n for n in REPORT_FILES if (run_dir / n).exists()]
        if existing and not force:
            raise UsageError(
                f"{', '.join(existing)} already exist in {str(run_dir)!r}; pass --force or choose --out"
            )
        from harv_jax import runlock

        runlock.acquire(run_dir, "RUN_DIR")  # refused while another harv-jax process writes there
        return run_dir
    if run_dir.resolve().is_relative_to(out.resolve()):
        raise UsageError(f"--out {str(out)!r} contains RUN_DIR {str(run_dir)!r}; choose another directory")
    return prepare_out_dir(out, force)


def build_report(
    run_dir: Path, out: Path | None = None, force: bool = False, report_cmd: str | None = None
) -> tuple[Path, Path]:
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

    note_incomplete(run_dir)
    if report_cmd is None:
        report_cmd = f"harv-jax report {shlex.quote(str(run_dir))}"
        if report_dir.resolve() != run_dir.resolve():
            report_cmd += f" --out {shlex.quote(str(report_dir))}"
    doc = build_document(run_dir, sections, report_cmd)
    md_path, html_path = report_dir / REPORT_FILES[0], report_dir / REPORT_FILES[1]
    atomic.write_text(md_path, to_markdown(doc, report_dir))
    atomic.write_text(html_path, to_html(doc, f"harv-jax report: {run_dir.name}"))
    return md_path, html_path
