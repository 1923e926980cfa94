"""Documentation hygiene: docs and code comments state the present and point only at what ships.

Scans the text files (``.py .md .toml .sh .yml .yaml .txt``; results stored as JSON, CSV, NPZ or images are
skipped) of README.md, mkdocs.yml, docs/, harv_jax/, experiments/ and benchmarks/ for

- history words: "session N", "issue N" (also "issue #N", "issue-N", "pre-issue-N"), "until now";
- references to files outside the repository: ``../shared``, ``MODEL.md``, ``FINDINGS``,
  ``rl_smc_harv_paper.tex``, ``STYLE.md``.

Also checks that every relative link in the READMEs that users read first points at an existing file.
History belongs in git; facts a user needs from outside files are written into docs/.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: What is scanned, relative to the repository root (files or folders).
SCANNED = ("README.md", "mkdocs.yml", "docs", "harv_jax", "experiments", "benchmarks")
#: Text files that are read; anything else (JSON, CSV, NPZ, PNG, logs of numbers) is skipped.
TEXT_SUFFIXES = frozenset({".py", ".md", ".toml", ".sh", ".yml", ".yaml", ".txt"})
#: Folders never scanned (build outputs, caches).
SKIPPED_DIRS = frozenset({"__pycache__", ".venv", "site", ".pytest_cache", ".ruff_cache"})

#: History narration: "when", not "what". Case-insensitive; "issue" and "session" only with a number, so
#: "an issue with", "a training session" and "sessions" stay allowed.
HISTORY_PATTERNS = {
    "session N": re.compile(r"\bsessions?\s+#?\d+", re.IGNORECASE),
    "issue N": re.compile(r"\b(?:pre-)?issues?[\s\-]+#?\d+", re.IGNORECASE),
    "until now": re.compile(r"\buntil now\b", re.IGNORECASE),
    "the issue's": re.compile(r"\b(?:the|this) issue(?:'s|\b(?! with))", re.IGNORECASE),
}

#: References to files that do not ship with the repository. Case-sensitive: "findings" and "model.md"-like
#: words in prose stay allowed; ``MODEL_CARD.md`` (shipped) does not match ``MODEL.md``.
OUTSIDE_PATTERNS = {
    "../shared": re.compile(r"\.\./shared\b"),
    "MODEL.md": re.compile(r"\bMODEL\.md\b"),
    "FINDINGS": re.compile(r"\bFINDINGS\b"),
    "the paper's .tex": re.compile(r"rl_smc_harv_paper\.tex\b"),
    "STYLE.md": re.compile(r"\bSTYLE\.md\b"),
}

PATTERNS = {**HISTORY_PATTERNS, **OUTSIDE_PATTERNS}

#: Strings each pattern must catch (the self-check: the test can fail).
BAD_SAMPLES = {
    "session N": ["measured in session 14", "Session 9's code", "sessions 11 to 14"],
    "issue N": ["issue 18's targets", "Issue #17, item 3", "the pre-issue-18 SMC", "(issue 3)"],
    "until now": ["the default until now", "Until now the"],
    "the issue's": ["the issue's criterion", "The issue's targets", "as this issue asks"],
    "../shared": ["see ../shared/MODEL.md", "``../shared/FINDINGS.md``"],
    "MODEL.md": ["MODEL.md trim table", "(MODEL.md verified forms)"],
    "FINDINGS": ["FINDINGS: 0.1 settles", "FINDINGS.md probe", "FINDINGS' probe"],
    "the paper's .tex": ["paper/rl_smc_harv_paper.tex"],
    "STYLE.md": ["the house style (STYLE.md)"],
}

#: Strings no pattern may catch: ordinary words near the forbidden ones.
GOOD_SAMPLES = [
    "an issue with the table",
    "each training session",
    "sessions",
    "findings of the study",
    "harv_jax/policies/MODEL_CARD.md",
    "docs/model.md, equation (3)",
    "the shared 2-core CPU",
    "reissue 3 commands",
    "until nowhere",
    "the issue with the table",
    "a known issue",
    "session_14_runs",
]


def _scanned_files() -> list[Path]:
    files = []
    for name in SCANNED:
        path = ROOT / name
        if path.is_file():
            files.append(path)
        elif path.is_dir():
            for f in sorted(path.rglob("*")):
                if f.is_file() and f.suffix in TEXT_SUFFIXES and not SKIPPED_DIRS.intersection(f.parts):
                    files.append(f)
    return files


def _offences(text: str) -> list[tuple[int, str, str]]:
    """Every (line number, pattern name, line) of ``text`` that a pattern matches."""
    found = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        for name, pattern in PATTERNS.items():
            if pattern.search(line):
                found.append((lineno, name, line.strip()))
    return found


@pytest.mark.parametrize("name", sorted(BAD_SAMPLES))
def test_patterns_catch_bad_samples(name):
    for sample in BAD_SAMPLES[name]:
        assert PATTERNS[name].search(sample), f"{name!r} misses {sample!r}"


@pytest.mark.parametrize("sample", GOOD_SAMPLES)
def test_patterns_allow_good_samples(sample):
    assert not [n for n, p in PATTERNS.items() if p.search(sample)], sample


def test_scan_finds_an_offence_in_a_file(tmp_path):
    bad = tmp_path / "bad.md"
    bad.write_text("ok line\nmeasured in session 3 (see ../shared/MODEL.md)\n", encoding="utf-8")
    names = {n for _, n, _ in _offences(bad.read_text(encoding="utf-8"))}
    assert names == {"session N", "../shared", "MODEL.md"}


def test_scan_covers_the_documented_folders():
    rel = {f.relative_to(ROOT).as_posix() for f in _scanned_files()}
    assert "README.md" in rel
    for folder in ("docs/", "harv_jax/", "experiments/", "benchmarks/"):
        assert any(r.startswith(folder) for r in rel), folder
    assert not any(r.endswith((".json", ".csv", ".npz", ".png")) for r in rel)


@pytest.mark.parametrize("path", _scanned_files(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_history_words_or_outside_references(path):
    offences = _offences(path.read_text(encoding="utf-8", errors="replace"))
    rel = path.relative_to(ROOT).as_posix()
    assert not offences, "\n".join(f"{rel}:{n}: [{name}] {line}" for n, name, line in offences)


#: Markdown inline links ``[text](target)``; images too.
_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def _relative_links(markdown: str) -> list[str]:
    targets = []
    for target in _LINK.findall(markdown):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.IGNORECASE) or target.startswith("#"):
            continue  # http(s):, mailto:, in-page anchors
        targets.append(target.split("#", 1)[0])
    return targets


def test_link_parser_finds_relative_links():
    md = "[a](docs/x.md) [b](https://x.org) [c](#here) ![d](img/p.png) [e](y.md#sec)"
    assert _relative_links(md) == ["docs/x.md", "img/p.png", "y.md"]


@pytest.mark.parametrize("readme", ["README.md", "experiments/README.md", "benchmarks/README.md"])
def test_readme_relative_links_exist(readme):
    path = ROOT / readme
    missing = [t for t in _relative_links(path.read_text(encoding="utf-8")) if not (path.parent / t).exists()]
    assert not missing, f"{readme}: links to missing files: {missing}"


#: A Sphinx role (``:class:`X```), which mkdocstrings shows as raw text; write ``[`X`][path]`` instead.
SPHINX_ROLE = re.compile(r":(class|func|data|mod|meth|attr|obj|exc|py:\w+):`")


def test_sphinx_role_pattern_catches_a_sample():
    assert SPHINX_ROLE.search("see :func:`monte_carlo` and :class:`~harv_jax.x.Y`")
    assert not SPHINX_ROLE.search("see [`monte_carlo`][] and [`Y`][harv_jax.x.Y]")


def test_docstrings_use_cross_references_mkdocstrings_renders():
    """The API pages render every docstring: no raw Sphinx roles, and long signatures wrap."""
    offences = [
        f"{p.relative_to(ROOT)}:{i}"
        for p in sorted((ROOT / "harv_jax").rglob("*.py"))
        for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
        if SPHINX_ROLE.search(line)
    ]
    assert offences == []
    mkdocs = (ROOT / "mkdocs.yml").read_text()
    assert re.search(r"separate_signature: true\s+line_length: \d+", mkdocs)
