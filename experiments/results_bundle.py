"""A study's small JSON results in one file, keyed by the path each command wrote them to.

    python experiments/results_bundle.py pack DIR BUNDLE [--glob PATTERN] [--about TEXT]
    python experiments/results_bundle.py unpack BUNDLE DIR
    python experiments/results_bundle.py list BUNDLE [PATTERN]

A bundle is ``{"about": TEXT, "files": {KEY: DOCUMENT}}``: KEY is the file's path relative to the study's
``results/`` folder (``seed11/mc_simplex_zero_nominal.json``), DOCUMENT the file's JSON. ``pack`` moves the
files matching ``--glob`` under DIR into BUNDLE (added to what it holds) and removes each file only after
its document is written and read back equal; ``unpack`` writes the files back under DIR (2-space indented
JSON; it refuses to overwrite a file). The study scripts write their results with `add` and read them with
`select`.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import sys
from pathlib import Path
from typing import Any


def _read(bundle: Path) -> dict[str, Any]:
    """The whole bundle, ``{"about": ..., "files": ...}`` (empty for a bundle not yet written)."""
    if not bundle.exists():
        return {"about": "", "files": {}}
    doc = json.loads(bundle.read_text())
    if not isinstance(doc, dict) or not isinstance(doc.get("files"), dict):
        raise ValueError(f"{bundle}: not a results bundle (a JSON object with 'about' and 'files')")
    return doc


def load(bundle: Path) -> dict[str, Any]:
    """The bundle's files, KEY -> DOCUMENT (empty for a bundle not yet written)."""
    return _read(bundle)["files"]


def _write(bundle: Path, doc: dict[str, Any], about: str | None) -> None:
    """Write ``doc``'s files (in key order) with ``about`` (None: the one ``doc`` holds)."""
    about = doc.get("about", "") if about is None else about
    out = {"about": about, "files": dict(sorted(doc["files"].items()))}
    tmp = bundle.with_name(bundle.name + ".tmp")
    tmp.write_text(json.dumps(out, indent=1) + "\n")
    os.replace(tmp, bundle)


def add(bundle: Path, key: str, document: Any, about: str | None = None) -> None:
    """Store ``document`` under ``key`` (replacing an entry of that key)."""
    doc = _read(bundle)
    doc["files"][key] = document
    bundle.parent.mkdir(parents=True, exist_ok=True)
    _write(bundle, doc, about)


def select(bundle: Path, pattern: str = "*") -> dict[str, Any]:
    """The entries whose key matches the glob ``pattern`` (``fnmatch``), in key order."""
    return {k: v for k, v in sorted(load(bundle).items()) if fnmatch.fnmatchcase(k, pattern)}


def pack(folder: Path, bundle: Path, pattern: str, about: str | None) -> list[str]:
    """Move the JSON files under ``folder`` matching ``pattern`` into ``bundle``; the keys packed."""
    paths = [
        p
        for p in sorted(folder.rglob("*.json"))
        if fnmatch.fnmatchcase(p.relative_to(folder).as_posix(), pattern) and p.resolve() != bundle.resolve()
    ]
    bundled = _read(bundle)
    docs = {p.relative_to(folder).as_posix(): json.loads(p.read_text()) for p in paths}
    clash = sorted(set(docs) & set(bundled["files"]))
    if clash:
        raise SystemExit(f"pack: {bundle} already holds {clash[0]}; allowed: keys it does not hold")
    bundled["files"].update(docs)
    _write(bundle, bundled, about)
    stored = load(bundle)
    for p in paths:
        key = p.relative_to(folder).as_posix()
        if stored[key] != docs[key]:
            raise SystemExit(f"pack: {key} read back different from {p}; nothing removed after it")
        p.unlink()
        if not any(p.parent.iterdir()) and p.parent != folder:
            p.parent.rmdir()
    return list(docs)


def unpack(bundle: Path, folder: Path) -> list[str]:
    """Write the bundle's files under ``folder``; refuses (before writing any) if one exists."""
    files = load(bundle)
    taken = [k for k in files if (folder / k).exists()]
    if taken:
        raise SystemExit(f"unpack: {folder / taken[0]} exists; allowed: a folder without the bundle's files")
    for key, doc in files.items():
        path = folder / key
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(doc, indent=2) + "\n")
    return list(files)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("pack", help="move JSON files under DIR into BUNDLE")
    p.add_argument("folder", type=Path)
    p.add_argument("bundle", type=Path)
    p.add_argument("--glob", default="*", help="which files, by their path under DIR (default: all)")
    p.add_argument("--about", default=None, help="what the bundle holds (kept if not given)")
    u = sub.add_parser("unpack", help="write BUNDLE's files under DIR")
    u.add_argument("bundle", type=Path)
    u.add_argument("folder", type=Path)
    ls = sub.add_parser("list", help="the keys of BUNDLE")
    ls.add_argument("bundle", type=Path)
    ls.add_argument("pattern", nargs="?", default="*")
    a = ap.parse_args(argv)
    if a.cmd == "pack":
        keys = pack(a.folder, a.bundle, a.glob, a.about)
        print(f"packed {len(keys)} files into {a.bundle}")
    elif a.cmd == "unpack":
        keys = unpack(a.bundle, a.folder)
        print(f"wrote {len(keys)} files under {a.folder}")
    else:
        print("\n".join(select(a.bundle, a.pattern)))


if __name__ == "__main__":
    sys.exit(main())
