"""The manifest of a run folder: which files harv-jax wrote there, and whether the command finished.

Every folder that [`harv_jax.outdir.prepare_out_dir`][] creates holds ``.harv_jax_manifest.json``: the
command line, a status (``running``, ``complete``, ``interrupted``) and each file written through
[`harv_jax.atomic`][] with its size and modification time. ``--force`` replaces a folder only if every
file in it is harv-jax's ([`foreign_entries`][]): recorded and unchanged since, or one of the names a
command writes incrementally or temporarily ([`OWN_PATTERNS`][]: checkpoints, TensorBoard event files,
temporary files a crash left behind).

Only the process that holds a folder's lock ([`harv_jax.runlock`][]) writes its manifest.
"""

from __future__ import annotations

import fnmatch
import json
import os
import threading
import time
from pathlib import Path
from typing import Any

from harv_jax import runlock

#: The manifest file inside a run folder.
MANIFEST = ".harv_jax_manifest.json"
#: The marker file of a run folder (written before the manifest; an older harv-jax wrote only the marker).
MARKER = ".harv_jax_run"
FORMAT = "harv-jax-manifest"
VERSION = 1
#: Statuses of a run folder.
RUNNING, COMPLETE, INTERRUPTED = "running", "complete", "interrupted"
#: Files of the folder's own bookkeeping (never reported as foreign).
BOOKKEEPING = (MARKER, MANIFEST, *runlock.LOCK_FILES)
#: Relative paths (``fnmatch``) harv-jax writes without recording them file by file: checkpoints and their
#: temporary or set-aside files, TensorBoard event files, a stalled run's traceback, and the temporary file
#: of any atomic write ([`harv_jax.atomic.tmp_path`][]).
OWN_PATTERNS = (
    "checkpoints/ckpt_*.msgpack",
    "checkpoints/ckpt_*.msgpack.corrupt",
    "checkpoints/.tmp-*",
    "tb/events.out.tfevents.*",
    "stall_traceback.txt",
    "*.harv_jax_tmp",
)
#: Folders harv-jax creates before it writes into them.
OWN_DIRS = ("checkpoints", "tb", "policy")

_LOCK = threading.Lock()
#: Manifests this process writes, by resolved folder.
_DOCS: dict[Path, dict[str, Any]] = {}


def _write(folder: Path, doc: dict[str, Any]) -> None:
    tmp = folder / f".{MANIFEST}.{os.getpid()}.harv_jax_tmp"
    tmp.write_text(json.dumps(doc, indent=1) + "\n")
    os.replace(tmp, folder / MANIFEST)


def start(folder: str | Path, command: str) -> None:
    """Write a fresh manifest (status ``running``) into ``folder``, which this process has locked."""
    key = Path(folder).resolve()
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "command": command,
        "status": RUNNING,
        "started_utc": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
        "files": {},
    }
    with _LOCK:
        _DOCS[key] = doc
        _write(key, doc)


def adopt(folder: str | Path) -> bool:
    """Keep the existing manifest of ``folder`` (locked by this process) and set it ``running``; False if
    the folder has none (an older harv-jax wrote it)."""
    key = Path(folder).resolve()
    doc = read(key)
    if doc is None:
        return False
    with _LOCK:
        _DOCS[key] = doc
    set_status(key, RUNNING)
    return True


def read(folder: str | Path) -> dict[str, Any] | None:
    """The manifest of ``folder``, or None if there is none or it is not a harv-jax manifest."""
    try:
        doc = json.loads((Path(folder) / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    if not (isinstance(doc, dict) and doc.get("format") == FORMAT and isinstance(doc.get("files"), dict)):
        return None
    return doc


def _owner(path: Path) -> Path | None:
    """The nearest run folder above ``path`` that this process holds and keeps a manifest of."""
    for parent in path.parents:
        if (parent / MARKER).is_file():
            if not runlock.holds(parent):
                return None
            if parent not in _DOCS:
                doc = read(parent)
                if doc is None:  # a folder of an older harv-jax: nothing to record into
                    return None
                _DOCS[parent] = doc
            return parent
    return None


def record(path: str | Path) -> None:
    """Record ``path`` (just written) in the manifest of the run folder this process holds it in."""
    p = Path(path).resolve()
    with _LOCK:
        folder = _owner(p)
        if folder is None:
            return
        st = p.stat()
        _DOCS[folder]["files"][p.relative_to(folder).as_posix()] = [st.st_size, st.st_mtime_ns]
        _write(folder, _DOCS[folder])


def set_status(folder: str | Path, status: str, timeout_s: float = -1) -> bool:
    """Set the status of ``folder``'s manifest (kept by this process); False if not done in ``timeout_s``."""
    key = Path(folder).resolve()
    if not _LOCK.acquire(timeout=timeout_s):
        return False
    try:
        doc = _DOCS.get(key)
        if doc is None:
            return False
        doc["status"] = status
        doc[f"{status}_utc"] = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
        _write(key, doc)
        return True
    finally:
        _LOCK.release()


def forget(folder: str | Path) -> None:
    """Stop keeping ``folder``'s manifest in memory (its lock was released)."""
    with _LOCK:
        _DOCS.pop(Path(folder).resolve(), None)


def _own(rel: str) -> bool:
    return any(fnmatch.fnmatchcase(rel, pat) for pat in OWN_PATTERNS) or rel.endswith(".harv_jax_tmp")


def foreign_entries(folder: str | Path) -> list[str]:
    """What in ``folder`` harv-jax did not write (paths relative to it; a changed file says so).

    A sub-folder with its own marker is checked against its own manifest. Symbolic links are foreign.
    Raises ValueError if ``folder`` (or such a sub-folder) has a marker but no manifest.
    """
    root = Path(folder)
    doc = read(root)
    if doc is None:
        raise ValueError(f"{str(root)!r} has no harv-jax manifest")
    files: dict[str, Any] = doc["files"]
    recorded_dirs = {str(Path(r).parent.as_posix()) for r in files}
    recorded_dirs |= {p.as_posix() for r in files for p in Path(r).parents}
    out: list[str] = []
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        d = Path(dirpath)
        rel_dir = d.relative_to(root).as_posix()
        prefix = "" if rel_dir == "." else rel_dir + "/"
        for name in list(dirnames):
            sub = d / name
            rel = prefix + name
            if sub.is_symlink():
                out.append(rel + " (a symbolic link)")
                dirnames.remove(name)
            elif (sub / MARKER).is_file():
                dirnames.remove(name)
                if read(sub) is None:
                    out.append(rel + " (a run folder of an older harv-jax, without a manifest)")
                else:
                    out += [f"{rel}/{e}" for e in foreign_entries(sub)]
            elif rel not in recorded_dirs and name not in OWN_DIRS and not any(True for _ in sub.iterdir()):
                out.append(rel + "/ (an empty folder)")
        for name in filenames:
            rel = prefix + name
            p = d / name
            if prefix == "" and name in BOOKKEEPING:
                continue
            if p.is_symlink():
                out.append(rel + " (a symbolic link)")
                continue
            entry = files.get(rel)
            if entry is not None:
                st = p.stat()
                if [st.st_size, st.st_mtime_ns] != list(entry):
                    out.append(rel + " (changed since harv-jax wrote it)")
            elif not _own(rel):
                out.append(rel)
    return sorted(out)
