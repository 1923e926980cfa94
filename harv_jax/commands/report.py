"""`harv-jax report RUN_DIR`: the figures and tables of a run directory as report.md and report.html.

The work is ``harv_jax.report`` (document model, sections, scan). Without ``--out`` both files go into
RUN_DIR itself (refused if they exist, unless ``--force``).
"""

from __future__ import annotations

from pathlib import Path

import typer

from harv_jax.cli_options import command_line, force_option
from harv_jax.report import build_report


def report(
    run_dir: Path = typer.Argument(..., help="A run directory (mc, compare, envelope, fly, quickstart)."),
    out: Path = typer.Option(None, help="Report directory (default: RUN_DIR itself)."),
    force: bool = force_option("report / non-empty --out directory"),
) -> None:
    """Markdown + standalone HTML report of a run directory's figures and tables, with its commands."""
    md_path, html_path = build_report(run_dir, out, force, command_line())
    typer.echo(f"wrote {md_path} and {html_path}")


def register(app: typer.Typer) -> None:
    """Add the command(s) of this module to ``app``."""
    app.command()(report)
