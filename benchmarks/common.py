"""Helpers shared by the benchmark scripts (no side effects at import)."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

from harv_jax.machine import cpu_model as cpu_name
from harv_jax.machine import simd_level


def cpu_cores() -> int:
    """CPU cores this process may run on (its affinity; all cores where affinity is unknown)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def set_host_devices(n: int) -> None:
    """``n`` XLA host devices (unless XLA_FLAGS already sets a count); call before jax starts its backends."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_force_host_platform_device_count" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count={n}".strip()


def load_average_1min() -> float | None:
    """The 1-minute load average (None where the OS has none): how busy the machine was."""
    return os.getloadavg()[0] if hasattr(os, "getloadavg") else None


def cpu_model() -> str:
    """The CPU model and its SIMD level (``harv_jax.machine``), as the benchmark JSONs record it."""
    simd = simd_level()
    return f"{cpu_name()} ({simd})" if simd else cpu_name()


def write_json(out_dir: Path, file_name: str, result: dict[str, Any]) -> Path:
    """Write a benchmark result as indented JSON to ``out_dir/file_name``; returns the path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / file_name
    path.write_text(json.dumps(result, indent=2) + "\n")
    return path


def machine_name(override: str | None = None) -> str:
    """``override`` or a device label, e.g. ``cpu-2core`` / ``gpu-h100``, safe in a file name."""
    import jax

    if override:
        name = override
    else:
        dev = jax.devices()[0]
        if dev.platform == "cpu":
            name = f"cpu-{cpu_cores()}core"
        else:
            m = re.search(r"\b([a-z]\d{2,4}[a-z]?)\b", dev.device_kind.lower())  # h100, a100, h200, l4 ...
            name = f"{dev.platform}-{m.group(1) if m else dev.device_kind}"
    return re.sub(r"[^a-z0-9._-]+", "-", name.lower()).strip("-")


def result_header(
    benchmark: str, machine: str, note: str, load_before: float | None, device_count: int | None = None
) -> dict[str, Any]:
    """The fields every benchmark JSON opens with: what ran, where, when, on which CPU and how busy it was.

    ``device_count``: the devices recorded (default ``jax.local_device_count()``).
    """
    import datetime as dt
    import platform

    import jax

    dev = jax.devices()[0]
    return {
        "benchmark": benchmark,
        "machine": machine,
        "date": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "note": note,
        "jax": jax.__version__,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "cpu_model": cpu_model(),
        "device": {
            "platform": dev.platform,
            "kind": dev.device_kind,
            "count": jax.local_device_count() if device_count is None else device_count,
        },
        "load_average_1min_before_after": [load_before, load_average_1min()],
    }


def best_us_per_step(calls: dict[Any, dict], repeats: int, n_steps: int) -> dict[Any, float]:
    """Best µs per step of each entry's ``compiled(*args)`` (``n_steps`` steps per call), the entries called
    in turn ``repeats`` rounds over, so that a slow spell of the machine hits them alike."""
    import time

    import jax

    times: dict[Any, list[float]] = {key: [] for key in calls}
    for _ in range(repeats):
        for key, b in calls.items():
            t0 = time.perf_counter()
            jax.block_until_ready(b["compiled"](*b["args"]))
            times[key].append(time.perf_counter() - t0)
    return {key: 1e6 * min(v) / n_steps for key, v in times.items()}
