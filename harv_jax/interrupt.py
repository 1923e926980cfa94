"""Ctrl-C and ``kill``: every command ends within seconds, says so in one line and exits 130 (SIGINT) or 143
(SIGTERM); a second signal ends it at once.

The signals are not delivered to the main thread as Python exceptions: that thread may sit in a compiled
computation for minutes, and unwinding it while XLA's threads still run ended in segmentation faults. A
watcher thread wakes on the signal (``signal.set_wakeup_fd``), marks the run folders of this process
``interrupted`` ([`harv_jax.outdir.interrupted_message`][]), prints the line and ends the process with
``os._exit``. What was written stays consistent: every output file is replaced atomically
([`harv_jax.atomic`][]) and every checkpoint is intact or absent, so an interrupted training run resumes
from its last checkpoint, as after any other kill.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator

#: Exit code of a command ended by each signal (128 + the signal number, as shells report it).
EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}


def _stop(signum: int, message: Callable[[str], str]) -> None:
    """The first signal: the message, then the exit code, from its own thread (a second signal may come)."""
    name = signal.Signals(signum).name
    try:
        line = message(name)
    except Exception as e:  # the exit must happen whatever the bookkeeping does
        line = f"interrupted ({name}); {type(e).__name__} while marking the run folders: {e}"
    _exit(signum, f"harv-jax: {line}")


def _exit(signum: int, line: str) -> None:
    with contextlib.suppress(Exception):
        sys.stdout.flush()
    with contextlib.suppress(Exception):
        sys.stderr.write("\n" + line + "\n")
        sys.stderr.flush()
    with contextlib.suppress(Exception):
        from harv_jax import runlock

        runlock.release_all()
    os._exit(EXIT_CODES.get(signum, 128 + signum))


@contextlib.contextmanager
def handled(message: Callable[[str], str]) -> Iterator[None]:
    """While the block runs, SIGINT and SIGTERM end the process: ``message(signal_name)`` gives the line
    (printed after ``harv-jax: ``). Outside the main thread this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    r, w = os.pipe()
    os.set_blocking(w, False)
    old_fd = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
    old = {s: signal.signal(s, lambda *_: None) for s in EXIT_CODES}
    stopping = threading.Event()

    def watch() -> None:
        while True:
            data = os.read(r, 64)
            for signum in data:
                if signum == 0:  # the block ended
                    return
                if signum not in EXIT_CODES:
                    continue
                if stopping.is_set():  # a second signal: at once
                    _exit(signum, f"harv-jax: interrupted again ({signal.Signals(signum).name}); exiting now")
                stopping.set()
                threading.Thread(target=_stop, args=(signum, message), daemon=True).start()

    watcher = threading.Thread(target=watch, name="harv-jax-signals", daemon=True)
    watcher.start()
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        signal.set_wakeup_fd(old_fd)
        os.write(w, b"\0")
        watcher.join(timeout=5)
        os.close(r)
        os.close(w)
