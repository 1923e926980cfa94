"""`harv-jax report`: the figures and tables of a run directory as report.md and report.html.

- ``document``: the document model (``Doc``) and its Markdown and standalone-HTML rendering;
- ``sections``: the tables of each kind of run, read through ``harv_jax.evaluation.summary``'s layout;
- ``scan``: what a run directory holds (two levels of sub-directories), its kind and provenance;
- ``build``: the document of a scan and ``build_report`` (writes both files).

Recognized content, in RUN_DIR and its sub-directories (two levels, e.g. a ``quickstart`` dir's
``compare/`` and ``mc/``): ``summary.json`` of ``harv-jax mc`` (tables with one column per controller),
``compare.json`` of ``harv-jax compare`` (its settings, the aircraft among them), ``envelope.json`` of
``harv-jax envelope`` (the grid and a table per controller), ``metrics.json`` of
``harv-jax fly`` (the run's settings and scalar metrics), any other ``*.md`` (e.g. ``compare_metrics.md``
of ``harv-jax compare``: included as it is), every ``*.png`` (linked from report.md, embedded as base64 in
report.html) and ``*.csv`` / ``*.npz`` (listed as data files). The commands and seeds that produced the
run (``"command"`` and ``"seed"`` of the JSON files) head the report.
"""

from harv_jax.report.build import build_document, build_report
from harv_jax.report.document import Doc, markdown_to_html, to_html, to_markdown
from harv_jax.report.scan import REPORT_FILES, scan

__all__ = [
    "REPORT_FILES",
    "Doc",
    "build_document",
    "build_report",
    "markdown_to_html",
    "scan",
    "to_html",
    "to_markdown",
]
