"""A lock on every run folder a harv-jax process writes, so that no other harv-jax process replaces,
resumes or writes into it at the same time.

The lock is an OS file lock (``filelock``, ``flock`` on POSIX) on ``<folder>/.harv_jax_lock``, held until the
process ends; the kernel drops it when the process dies, however it dies. Beside it,
``<folder>/.harv_jax_lock.json`` names the holder (PID, host, command, start time). A folder whose lock is
held by a live process is refused with one line naming that process. A holder file left by a process that
is gone (killed before it could clean up) is a *stale* lock: it is reported in one line, naming the dead
PID, and taken over.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import socket
import sys
import time
from pathlib import Path
from typing import Any

from filelock import FileLock, Timeout

from harv_jax.errors import UsageError

#: The lock file inside a run folder.
LOCK_NAME = ".harv_jax_lock"
#: Who holds the lock (JSON), beside the lock file.
HOLDER_NAME = ".harv_jax_lock.json"
#: The files of the lock itself (kept when ``--force`` empties a folder it holds).
LOCK_FILES = (LOCK_NAME, HOLDER_NAME)

#: Locks this process holds, by resolved folder (held until the process ends or [`release`][]).
_HELD: dict[Path, FileLock] = {}


def holder_text(info: dict[str, Any]) -> str:
    """'PID 123 on host (harv-jax train ..., started 2026-12-03 07:01:02 UTC)'."""
    when = info.get("started_utc", "?")
    cmd = info.get("command", "?")
    return f"PID {info.get('pid', '?')} on {info.get('host', '?')} ({cmd!s:.80}, started {when})"


def read_holder(folder: str | Path) -> dict[str, Any] | None:
    """The holder record of ``folder``'s lock, or None if there is none or it cannot be read."""
    try:
        info = json.loads((Path(folder) / HOLDER_NAME).read_text())
    except (OSError, ValueError):
        return None
    return info if isinstance(info, dict) else None


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by another user
        return True
    return True


def is_held_by_other(folder: str | Path) -> dict[str, Any] | None:
    """The holder record if another live process holds ``folder``'s lock, else None (no side effects
    beyond opening the lock file, which exists already when anyone ever held it)."""
    folder = Path(folder)
    if folder.resolve() in _HELD or not (folder / LOCK_NAME).is_file():
        return None
    probe = FileLock(str(folder / LOCK_NAME), timeout=0, thread_local=False)
    try:
        probe.acquire()
    except Timeout:
        return read_holder(folder) or {"pid": "?", "host": "?"}
    except OSError:
        return None
    probe.release()
    return None


def command_line() -> str:
    """This process's command line as a user typed it (``harv-jax train --out runs/x``)."""
    if not sys.argv:
        return "python"
    name = Path(sys.argv[0]).name
    return " ".join(["harv-jax" if name in ("cli.py", "harv-jax") else name, *sys.argv[1:]])


def holds(folder: str | Path) -> bool:
    """Whether this process holds ``folder``'s lock."""
    return Path(folder).resolve() in _HELD


def _in_use(folder: Path, flag: str, info: dict[str, Any]) -> UsageError:
    """The one-line error for a folder another live harv-jax process holds."""
    return UsageError(
        f"{flag} {str(folder)!r} is in use by harv-jax {holder_text(info)}; wait for it to finish, "
        "stop it, or choose another folder"
    )


def check_free(folder: str | Path, flag: str = "--out") -> None:
    """Raise UsageError naming the holder if another live process holds ``folder``'s lock; writes nothing."""
    info = is_held_by_other(folder)
    if info is not None:
        raise _in_use(Path(folder), flag, info)


def acquire(folder: str | Path, flag: str = "--out") -> FileLock:
    """Hold the lock of ``folder`` (an existing directory) for the rest of this process.

    Returns the lock (already held: a second call for the same folder returns it again).

    Raises:
        UsageError: another live process holds it (the message names its PID, host and command), or the
            lock file cannot be created.
    """
    folder = Path(folder)
    key = folder.resolve()
    if key in _HELD:
        return _HELD[key]
    lock = FileLock(str(folder / LOCK_NAME), timeout=0, thread_local=False)
    try:
        lock.acquire()
    except Timeout:
        raise _in_use(folder, flag, read_holder(folder) or {"pid": "?", "host": "?"}) from None
    except OSError as e:
        raise UsageError(f"{flag} {str(folder)!r}: cannot create its lock file ({e.strerror or e})") from None
    old = read_holder(folder)
    if old is not None and old.get("pid") != os.getpid():
        same_host = old.get("host") == socket.gethostname()
        gone = same_host and isinstance(old.get("pid"), int) and not _pid_alive(old["pid"])
        state = "no longer running" if gone else "its lock was free"
        print(
            f"harv-jax: note: {flag} {str(folder)!r} had a stale lock of {holder_text(old)}, {state}; "
            "taken over",
            file=sys.stderr,
        )
    info = {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "command": command_line(),
        "started_utc": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
    }
    with contextlib.suppress(OSError):
        (folder / HOLDER_NAME).write_text(json.dumps(info) + "\n")
    _HELD[key] = lock
    return lock


def release(folder: str | Path) -> None:
    """Release this process's lock of ``folder`` (if held) and remove its holder record."""
    key = Path(folder).resolve()
    lock = _HELD.pop(key, None)
    if lock is None:
        return
    with contextlib.suppress(OSError):
        (key / HOLDER_NAME).unlink()
    lock.release()


@atexit.register
def release_all() -> None:
    """Release every lock this process holds."""
    for folder in list(_HELD):
        release(folder)
