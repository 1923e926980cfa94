"""mkdocs hook: array shapes in docstrings (``[..., 3]``, ``[alpha_d, beta_d, mu_d]``) are not links.

Markdown reads ``x [3] [alpha_d, beta_d, mu_d]`` as a reference-style link, and mkdocs-autorefs warns that
it cannot find the target, which ``mkdocs build --strict`` turns into an error. This hook drops only those
warnings whose target is not a Python identifier path (it contains a comma, a space, ``...`` or starts with a
digit); a missing cross-reference to a real name (``harv_jax.x.renamed``) still fails the build.
"""

from __future__ import annotations

import logging
import re

_TARGET = re.compile(r"Could not find cross-reference target '([^']*)'")
_IDENTIFIER_PATH = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")


class _ShapeRefFilter(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        match = _TARGET.search(record.getMessage())
        return not (match and not _IDENTIFIER_PATH.match(match.group(1)))


def on_startup(command: str, dirty: bool) -> None:
    for name in ("mkdocs.plugins.mkdocs_autorefs", "mkdocs.plugins.mkdocs_autorefs._internal.plugin"):
        logging.getLogger(name).addFilter(_ShapeRefFilter())
