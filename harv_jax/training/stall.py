"""The watchdog of ``harv-jax train``: a stalled run ends with a one-line error and exit code 3.

[`Watchdog`][harv_jax.ppo.watchdog.Watchdog] (generic) watches for finished periods and CPU use; the handler
here dumps every thread's Python stack to ``stall_traceback.txt`` in the run folder, prints one line naming
the newest intact checkpoint, and exits with [`STALL_EXIT_CODE`][] (its checkpoints stay intact, so
``--resume`` continues the run).
"""

from __future__ import annotations

import faulthandler
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from harv_jax.ppo import checkpoint
from harv_jax.ppo.watchdog import Watchdog

#: Exit code of a run that the watchdog stopped.
STALL_EXIT_CODE = 3


def stall_handler(out_dir: Path, console: Any) -> Callable[[str], None]:
    """``on_stall`` for the CLI: all threads' Python stacks to ``stall_traceback.txt``, one line, exit 3.

    ``console`` is the progress display (anything with a ``file`` to flush before the line is printed).

    The process ends with ``os._exit`` (a deadlocked XLA runtime cannot be unwound); a checkpoint is written
    atomically, so the newest complete one stays loadable whenever this fires.
    """

    def on_stall(reason: str) -> None:
        try:
            with open(out_dir / "stall_traceback.txt", "w") as f:
                faulthandler.dump_traceback(f, all_threads=True)
        except OSError:
            pass
        try:
            console.file.flush()
        except Exception:  # noqa: BLE001 - the progress display must not stop the exit
            pass
        files = checkpoint.checkpoint_paths(out_dir / "checkpoints")
        kept = f"its newest checkpoint {files[-1].name} is intact" if files else "no checkpoint written yet"
        line = (
            f"harv-jax: error: training stalled: {reason}; {kept}: continue with "
            f"harv-jax train --resume {out_dir}"
        )
        print(line, file=sys.stderr, flush=True)
        os._exit(STALL_EXIT_CODE)

    return on_stall


def make_watchdog(watchdog_s: float | None, out_dir: Path, console: Any) -> Watchdog | None:
    """The CLI's [`Watchdog`][harv_jax.ppo.watchdog.Watchdog] (not started); ``watchdog_s`` 0 turns it off."""
    if watchdog_s == 0:
        return None
    # an explicit limit also shortens the no-CPU-use limit (so a short --watchdog-s acts quickly)
    idle_s = None if watchdog_s is None else watchdog_s
    kw = {} if idle_s is None else {"idle_s": min(idle_s, 300.0), "poll_s": min(5.0, max(0.2, idle_s / 5))}
    return Watchdog(stall_handler(out_dir, console), limit_s=watchdog_s, **kw)
