"""Output directories: never silently overwrite what a previous run wrote, never delete what harv-jax
did not write, nor what the command itself reads.

Every directory [`prepare_out_dir`][] creates gets a marker file ([`MARKER`][]) and a manifest of the
files harv-jax writes into it ([`harv_jax.manifest`][]). ``--force`` replaces a non-empty directory only if
every file in it is harv-jax's (recorded and unchanged, or of a name harv-jax writes incrementally), no
other live harv-jax process holds its lock ([`harv_jax.runlock`][]), it is not, does not contain and does
not lie inside anything the command reads, and it is not the current directory, one of its parents, the
home directory or the filesystem root. The folder [`prepare_out_dir`][] returns is locked by this process
until it ends, and its manifest says ``running`` until [`finish_all`][] marks it ``complete``; a folder
whose command was interrupted or killed says so to ``--force``, ``report`` and a re-run.
"""

from __future__ import annotations

import shlex
import shutil
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from harv_jax import atomic, manifest, runlock
from harv_jax.errors import UsageError
from harv_jax.manifest import MARKER

#: How many foreign files a refusal names.
SHOWN_FOREIGN = 5


@dataclass(frozen=True)
class Prepared:
    """A run folder this process created (or resumed), and the command that continues it, if any."""

    path: Path
    resume_command: str | None = None


#: Folders this process prepared, in order ([`finish_all`][], [`interrupted_message`][]).
_PREPARED: list[Prepared] = []


def is_run_dir(path: str | Path) -> bool:
    """True if ``path`` is a directory that a harv-jax command created (it holds [`MARKER`][])."""
    p = Path(path)
    return p.is_dir() and (p / MARKER).is_file()


def _protected_reason(out: Path) -> str | None:
    """Why ``out`` (resolved) must never be removed, or None."""
    cwd = Path.cwd().resolve()
    if out == cwd:
        return "it is the current directory"
    if out in cwd.parents:
        return "it contains the current directory"
    if out == Path(out.anchor):
        return "it is the filesystem root"
    home = Path.home().resolve()
    if out == home or out in home.parents:
        return "it is the home directory" if out == home else "it contains the home directory"
    return None


def _incomplete(out: Path) -> str | None:
    """How ``out``'s command ended if it did not finish (None: finished, or not a manifest folder)."""
    doc = manifest.read(out)
    if doc is None or doc.get("status") == manifest.COMPLETE:
        return None
    cmd = str(doc.get("command", "harv-jax"))[:80]
    if doc.get("status") == manifest.INTERRUPTED:
        return f"an interrupted run of `{cmd}`"
    return f"an unfinished run of `{cmd}` (its process ended before it finished)"


def _what_to_do(out: Path) -> str:
    """What a user can do with the unfinished run folder ``out``."""
    doc = manifest.read(out) or {}
    q = shlex.quote(str(out))
    command = str(doc.get("command", "")).split()
    if command[1:2] == ["train"]:
        return f"continue it with `harv-jax train --resume {q}`, or pass --force to replace it"
    if command[1:2] == ["evaluate"]:
        return "continue it with the same command and --resume, or pass --force to replace it"
    return "pass --force to replace it, or choose another --out"


def incomplete_note(folder: str | Path) -> str | None:
    """One line for ``report`` and friends when ``folder``'s command did not finish, else None."""
    how = _incomplete(Path(folder))
    mine = any(p.path.resolve() == Path(folder).resolve() for p in _PREPARED)  # this process is writing it
    if how is None or mine or runlock.is_held_by_other(folder) is not None:
        return None
    return f"{str(folder)!r} holds {how}: it is incomplete; {_what_to_do(Path(folder))}"


def check_reads(out: Path, reads: Iterable[str | Path], flag: str) -> None:
    """Raise UsageError if ``out`` is, contains or lies inside one of the paths the command reads."""
    o = out.resolve()
    for r in reads:
        rp = Path(r).resolve()
        if o == rp:
            how = "is"
        elif o in rp.parents:
            how = "contains"
        elif rp in o.parents:
            how = "lies inside"
        else:
            continue
        raise UsageError(
            f"{flag} {str(out)!r} {how} {str(r)!r}, which this command reads; --force would delete it: "
            "choose another --out"
        )


def check_force_target(path: str | Path, reads: Iterable[str | Path] = ()) -> None:
    """Raise UsageError unless ``--force`` may empty ``path``: a run folder harv-jax wrote (every file in
    it its own), not protected, not read by this command, not in use by another harv-jax process."""
    out = Path(path)
    flag = f"--out {str(path)!r}"
    if out.is_symlink():
        raise UsageError(
            f"{flag} is a symbolic link; --force replaces only a real run folder; choose another --out"
        )
    reason = _protected_reason(out.resolve())
    if reason is not None:
        raise UsageError(f"{flag} cannot be replaced with --force: {reason}; choose a new folder for --out")
    check_reads(out, reads, "--out")
    if not is_run_dir(out):
        raise UsageError(
            f"{flag} is not empty and was not written by harv-jax (no {MARKER} file); --force replaces only "
            "harv-jax run folders: choose another --out or remove it yourself"
        )
    holder = runlock.is_held_by_other(out)
    if holder is not None:
        raise UsageError(
            f"{flag} is in use by harv-jax {runlock.holder_text(holder)}; --force does not replace a folder "
            "another harv-jax process is writing: wait for it to finish, stop it, or choose another --out"
        )
    try:
        foreign = manifest.foreign_entries(out)
    except ValueError:
        raise UsageError(
            f"{flag} was written by an older harv-jax that kept no list of its files, so --force cannot tell "
            f"them from yours: remove it yourself (rm -r {shlex.quote(str(out))}) or choose another --out"
        ) from None
    if foreign:
        more = f" and {len(foreign) - SHOWN_FOREIGN} more" if len(foreign) > SHOWN_FOREIGN else ""
        raise UsageError(
            f"{flag} holds files harv-jax did not write: {', '.join(foreign[:SHOWN_FOREIGN])}{more}; --force "
            "deletes only what harv-jax wrote: move them out, or choose another --out"
        )


def _check_parents(out: Path) -> None:
    """Raise UsageError if an existing ancestor of ``out`` is a file (mkdir would fail half-way)."""
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                raise UsageError(
                    f"--out {str(out)!r} lies below {str(parent)!r}, which is a file, not a folder"
                )
            return


def check_out_dir(path: str | Path, force: bool = False, reads: Iterable[str | Path] = ()) -> Path:
    """Validate ``--out`` without touching the disk; returns it as a Path.

    ``reads``: the files and folders the command reads (policies, presets, state files); ``--force`` never
    replaces a folder that is, contains or lies inside one of them.

    Raises:
        UsageError: empty path; ``path`` or an ancestor is a file; ``path`` is non-empty and ``force`` is
            False; ``force`` is True but ``path`` may not be emptied ([`check_force_target`][]).
    """
    if str(path).strip() == "":
        raise UsageError("--out '' is empty; give the name of a new folder, e.g. --out runs/mine")
    out = Path(path)
    _check_parents(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {str(out)!r} exists and is a file, not a folder; choose another --out")
    if force:
        check_reads(out, reads, "--out")
    if out.is_dir() and any(out.iterdir()):
        if not force:
            note = incomplete_note(out)
            if note is not None:
                raise UsageError(f"--out {note}")
            raise UsageError(
                f"--out {str(out)!r} already exists and is not empty; choose another or pass --force"
            )
        check_force_target(out, reads)
    elif force and out.exists():
        reason = _protected_reason(out.resolve())
        if reason is not None:
            raise UsageError(f"--out {str(out)!r} cannot be used with --force: {reason}")
    return out


def prepare_out_dir(
    path: str | Path,
    force: bool = False,
    reads: Iterable[str | Path] = (),
    resume_command: str | None = None,
) -> Path:
    """Create ``path`` for a new run's outputs, with its marker and a fresh manifest (status ``running``).

    A non-empty ``path`` is emptied only with ``force`` and only if everything in it is harv-jax's (see the
    module docstring). ``resume_command``: the command that continues this run if it is interrupted
    (``train``), named in the interruption message.

    Raises:
        UsageError: see [`check_out_dir`][]; or the folder cannot be created.
    """
    reads = list(reads)
    out = check_out_dir(path, force, reads)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"--out {str(out)!r} cannot be created ({e.strerror or e})") from None
    runlock.acquire(out)  # raises if another live harv-jax process took the folder since the check
    if any(p.name not in runlock.LOCK_FILES for p in out.iterdir()):
        check_force_target(out, reads) if force else check_out_dir(out, force)  # re-checked under the lock
        for child in out.iterdir():  # every file in it is harv-jax's, and nobody else holds it
            if child.name in runlock.LOCK_FILES:
                continue
            if child.is_dir() and not child.is_symlink():
                shutil.rmtree(child)
            else:
                child.unlink()
    try:
        atomic.write_text(out / MARKER, "written by harv-jax; `--force` may replace this folder\n")
        manifest.start(out, runlock.command_line())
    except OSError as e:
        raise UsageError(f"--out {str(out)!r} cannot be written ({e.strerror or e})") from None
    _PREPARED.append(Prepared(out, resume_command))
    return out


def adopt(folder: str | Path, resume_command: str | None = None) -> None:
    """Take over the manifest of an existing run folder this process has locked (``train --resume``): its
    status is ``running`` again until [`finish_all`][]."""
    folder = Path(folder)
    if manifest.adopt(folder):
        _PREPARED.append(Prepared(folder, resume_command))


def finish_all() -> None:
    """Mark every folder this process prepared ``complete`` (the command succeeded)."""
    while _PREPARED:
        manifest.set_status(_PREPARED.pop(0).path, manifest.COMPLETE)


def forget_all() -> None:
    """Forget the folders this process prepared (a command that failed leaves them as they are)."""
    _PREPARED.clear()


def interrupted_message(signal_name: str, timeout_s: float = 3.0) -> str:
    """Mark every folder this process prepared ``interrupted``; one line saying what was kept and what the
    user can do with it."""
    if not _PREPARED:
        return f"interrupted ({signal_name}); nothing was written"
    parts = []
    for prep in _PREPARED:
        manifest.set_status(prep.path, manifest.INTERRUPTED, timeout_s)
    top = _PREPARED[0]
    q = shlex.quote(str(top.path))
    if top.resume_command is not None:
        parts.append(f"{q} kept with its last checkpoint; it can be resumed: {top.resume_command}")
    else:
        parts.append(
            f"{q} kept, incomplete (marked so); it can be removed (rm -r {q}) or replaced by the same "
            "command with --force"
        )
    return f"interrupted ({signal_name}); " + "; ".join(parts)


def note_incomplete(folder: str | Path) -> None:
    """Print [`incomplete_note`][] for ``folder`` on stderr, if it applies."""
    note = incomplete_note(folder)
    if note is not None:
        print(f"harv-jax: note: {note}", file=sys.stderr)


def read_paths(*specs: str | Path | None) -> list[Path]:
    """The files and folders named by input options (``--policy``, ``--scenario``, ``--preset``, ...): shipped
    policies and built-in names are skipped, a checkpoint's ``@SEED`` is dropped; only existing paths."""
    out = []
    for spec in specs:
        if spec is None:
            continue
        text = str(spec)
        if text.startswith("shipped"):
            continue
        path, sep, seed = text.rpartition("@")
        if sep and seed.isdigit():
            text = path
        if text and Path(text).exists():
            out.append(Path(text))
    return out
