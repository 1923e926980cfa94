"""A watchdog that turns a stalled training period into a clear error instead of a hang.

The training loop calls [`Watchdog.beat`][] after every period. A background thread declares a stall and
calls ``on_stall(reason)`` when either

* no beat came for ``limit_s`` seconds of wall time (``limit_s=None``: automatic, ``first_limit_s`` until
  the first beat, which includes compilation, then ``max(min_limit_s, 20 x`` the first period's time``)``),
  or
* the process's compute threads used less than ``idle_cpu_fraction`` of one core for ``idle_s`` seconds
  in a row while a period was due. A period always keeps at least one core busy; a deadlocked XLA runtime
  (every thread parked on a futex, the state of the one CPU hang we observed) uses none, so this finds that
  hang within minutes whatever the wall-time limit. "Compute threads" are all threads but the Python
  threads other than the main one (the progress display's refresh thread alone uses about 1% of a core on
  a terminal; TensorBoard's writer, this watchdog): on Linux the CPU times of the other threads
  (``/proc/self/task/*/stat``, which do not change while a thread sleeps) are summed; elsewhere the whole
  process counts.

Time in which the process did not run at all (suspended with SIGSTOP/Ctrl-Z, a laptop asleep: the sampling
thread sees a gap of more than ``max(3 x poll_s, poll_s + 2 s)``) counts towards neither limit. As a
backstop for a stall that keeps the GIL (the Python thread could then not run),
``faulthandler.dump_traceback_later`` is armed to print every thread's stack and exit the process
``backstop_s`` seconds after the wall-time limit.
"""

from __future__ import annotations

import faulthandler
import math
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

#: Defaults of the automatic limits (seconds).
FIRST_LIMIT_S = 3600.0
MIN_LIMIT_S = 600.0
FIRST_PERIOD_FACTOR = 20.0
IDLE_S = 300.0
IDLE_CPU_FRACTION = 0.01


def _thread_cpu_s(tid: int) -> float:
    """CPU seconds (user + system) of thread ``tid`` of this process from /proc; 0 if unavailable."""
    try:
        fields = Path(f"/proc/self/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime
    except (OSError, IndexError, ValueError):
        return 0.0


def compute_cpu_s() -> float:
    """CPU seconds of this process's threads except its Python threads other than the main one (Linux;
    elsewhere the CPU time of the whole process)."""
    tasks = Path("/proc/self/task")
    if not tasks.is_dir():
        return time.process_time()
    main = threading.main_thread()
    helpers = {str(t.native_id) for t in threading.enumerate() if t is not main}
    try:
        tids = [p.name for p in tasks.iterdir()]
    except OSError:
        return time.process_time()
    return sum(_thread_cpu_s(int(tid)) for tid in tids if tid not in helpers)


class Watchdog:
    """Stall detector for a loop that calls [`beat`][] after each unit of progress (see module doc).

    Args:
        on_stall: called once, from the watchdog thread, with a one-line reason (e.g. print and ``os._exit``).
        limit_s: wall seconds without a beat that count as a stall (None: automatic; 0: no wall limit).
        idle_s: seconds of (almost) no CPU use that count as a stall (0: off).
        first_limit_s: the automatic limit before the first beat.
        min_limit_s: the automatic limit after the first beat is ``max(min_limit_s, 20 x first period)``.
        idle_cpu_fraction: below this many CPU-seconds per second the process counts as idle.
        poll_s: sampling interval of the watchdog thread.
        backstop_s: the faulthandler backstop fires this long after the wall limit (None: no backstop).
    """

    def __init__(
        self,
        on_stall: Callable[[str], None],
        *,
        limit_s: float | None = None,
        idle_s: float = IDLE_S,
        first_limit_s: float = FIRST_LIMIT_S,
        min_limit_s: float = MIN_LIMIT_S,
        idle_cpu_fraction: float = IDLE_CPU_FRACTION,
        poll_s: float = 5.0,
        backstop_s: float | None = 300.0,
    ) -> None:
        for name, v in (
            ("limit_s", limit_s),
            ("idle_s", idle_s),
            ("first_limit_s", first_limit_s),
            ("min_limit_s", min_limit_s),
            ("poll_s", poll_s),
        ):
            if v is not None and (not math.isfinite(v) or v < 0):
                raise ValueError(f"{name} {v!r} must be a finite number >= 0")
        if poll_s <= 0:
            raise ValueError(f"poll_s {poll_s!r} must be > 0")
        self.on_stall = on_stall
        self.limit_s = limit_s
        self.idle_s = idle_s
        self.first_limit_s = first_limit_s
        self.min_limit_s = min_limit_s
        self.idle_cpu_fraction = idle_cpu_fraction
        self.poll_s = poll_s
        self.backstop_s = backstop_s
        self.beats = 0
        self.stalled: str | None = None
        self._first_period_s: float | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._reset_clocks()

    def _reset_clocks(self) -> None:
        self._since_beat_s = 0.0  # wall seconds (process running) since the last beat
        self._idle_for_s = 0.0  # seconds in a row with (almost) no CPU use

    def current_limit_s(self) -> float:
        """The wall-time limit that applies now (0: none)."""
        if self.limit_s is not None:
            return self.limit_s
        if self._first_period_s is None:
            return self.first_limit_s
        return max(self.min_limit_s, FIRST_PERIOD_FACTOR * self._first_period_s)

    def start(self) -> Watchdog:
        """Start the watchdog thread (and the backstop); returns self."""
        self._t_start = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="harv-jax-watchdog", daemon=True)
        self._thread.start()
        self._arm_backstop()
        return self

    def beat(self) -> None:
        """Progress: one more period done."""
        with self._lock:
            if self._first_period_s is None:
                self._first_period_s = time.monotonic() - self._t_start
            self.beats += 1
            self._reset_clocks()
        self._arm_backstop()

    def stop(self) -> None:
        """Stop watching (idempotent); cancels the backstop."""
        self._stop.set()
        if self.backstop_s is not None:
            faulthandler.cancel_dump_traceback_later()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2 * self.poll_s)

    def __enter__(self) -> Watchdog:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _arm_backstop(self) -> None:
        limit = self.current_limit_s()
        if self.backstop_s is not None and limit > 0 and not self._stop.is_set():
            faulthandler.dump_traceback_later(limit + self.backstop_s, exit=True)

    def _run(self) -> None:
        wall, cpu = time.monotonic(), compute_cpu_s()
        while not self._stop.wait(self.poll_s):
            now_wall, now_cpu = time.monotonic(), compute_cpu_s()
            d_wall, d_cpu = now_wall - wall, now_cpu - cpu
            wall, cpu = now_wall, now_cpu
            with self._lock:
                if d_wall > max(3 * self.poll_s, self.poll_s + 2.0):  # the process did not run: count nothing
                    self._idle_for_s = 0.0
                    continue
                self._since_beat_s += d_wall
                idle = d_cpu < self.idle_cpu_fraction * d_wall
                self._idle_for_s = self._idle_for_s + d_wall if idle else 0.0
                limit = self.current_limit_s()
                reason = None
                if limit > 0 and self._since_beat_s >= limit:
                    reason = f"no progress for {self._since_beat_s:.0f} s (limit {limit:.0f} s)"
                elif self.idle_s > 0 and self._idle_for_s >= self.idle_s:
                    reason = (
                        f"no CPU use for {self._idle_for_s:.0f} s while a period was running "
                        "(deadlocked, not slow)"
                    )
            if reason is not None:
                self.stalled = reason
                self._stop.set()
                self.on_stall(reason)
                return
