"""The report's document model: blocks (headings, paragraphs, tables, code, images, included Markdown)
rendered to Markdown and to a standalone HTML page (PNGs embedded), and the table-cell formatting."""

from __future__ import annotations

import base64
import html
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


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
    table = f"<table{cls}><thead><tr>{th}</tr></thead><tbody>{body}</tbody></table>"
    return f'<div class="table">{table}</div>'  # scrolls on its own if a cell cannot wrap


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
table{border-collapse:collapse;margin:0.6em 0 1.2em;max-width:100%}div.table{max-width:100%;overflow-x:auto}
th,td{border:1px solid #ccc;padding:3px 8px;overflow-wrap:anywhere}
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
