"""Output directories: never silently overwrite what a previous run wrote, never delete what harv-jax
did not write.

Every directory :func:`prepare_out_dir` creates gets a marker file (:data:`MARKER`). ``--force`` replaces a
non-empty directory only if it holds that marker, no other live harv-jax process holds its lock
(:mod:`harv_jax.runlock`), and it is not the current directory, one of its parents, the home directory or
the filesystem root. The folder :func:`prepare_out_dir` returns is locked by this process until it ends.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from harv_jax import runlock
from harv_jax.errors import UsageError

#: Marker file written into every output directory a harv-jax command creates.
MARKER = ".harv_jax_run"


def is_run_dir(path: str | Path) -> bool:
    """True if ``path`` is a directory that a harv-jax command created (it holds :data:`MARKER`)."""
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


def check_force_target(path: str | Path) -> None:
    """Raise UsageError unless ``--force`` may remove ``path`` (a marked run directory, not protected)."""
    out = Path(path)
    flag = f"--out {str(path)!r}"
    if out.is_symlink():
        raise UsageError(
            f"{flag} is a symbolic link; --force replaces only a real run folder; choose another --out"
        )
    reason = _protected_reason(out.resolve())
    if reason is not None:
        raise UsageError(f"{flag} cannot be replaced with --force: {reason}; choose a new folder for --out")
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


def _check_parents(out: Path) -> None:
    """Raise UsageError if an existing ancestor of ``out`` is a file (mkdir would fail half-way)."""
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                raise UsageError(
                    f"--out {str(out)!r} lies below {str(parent)!r}, which is a file, not a folder"
                )
            return


def check_out_dir(path: str | Path, force: bool = False) -> Path:
    """Validate ``--out`` without touching the disk; returns it as a Path.

    Raises:
        UsageError: empty path; ``path`` or an ancestor is a file; ``path`` is non-empty and ``force`` is
            False; ``force`` is True but ``path`` may not be removed (:func:`check_force_target`).
    """
    if str(path).strip() == "":
        raise UsageError("--out '' is empty; give the name of a new folder, e.g. --out runs/mine")
    out = Path(path)
    _check_parents(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {str(out)!r} exists and is a file, not a folder; choose another --out")
    if out.is_dir() and any(out.iterdir()):
        if not force:
            raise UsageError(
                f"--out {str(out)!r} already exists and is not empty; choose another or pass --force"
            )
        check_force_target(out)
    elif force and out.exists():
        reason = _protected_reason(out.resolve())
        if reason is not None:
            raise UsageError(f"--out {str(out)!r} cannot be used with --force: {reason}")
    return out


def prepare_out_dir(path: str | Path, force: bool = False) -> Path:
    """Create ``path`` for a new run's outputs and write the run marker into it.

    A non-empty ``path`` is replaced only with ``force`` and only if harv-jax wrote it (see the module
    docstring).

    Raises:
        UsageError: see :func:`check_out_dir`; or the folder cannot be created.
    """
    out = check_out_dir(path, force)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"--out {str(out)!r} cannot be created ({e.strerror or e})") from None
    runlock.acquire(out)  # raises if another live harv-jax process took the folder since the check
    if any(p.name not in runlock.LOCK_FILES for p in out.iterdir()):
        check_force_target(out) if force else check_out_dir(out, force)  # re-checked under the lock
        for child in out.iterdir():  # a marked, unprotected run folder that nobody else holds
            if child.name in runlock.LOCK_FILES:
                continue
            if child.is_dir() and not child.is_symlink():
                shutil.rmtree(child)
            else:
                child.unlink()
    try:
        (out / MARKER).write_text("written by harv-jax; `--force` may replace this folder\n")
    except OSError as e:
        raise UsageError(f"--out {str(out)!r} cannot be written ({e.strerror or e})") from None
    return out
