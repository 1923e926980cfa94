"""Helpers shared by the benchmark scripts (no side effects at import)."""

from __future__ import annotations

import os
import re


def machine_name(override: str | None = None) -> str:
    """``override`` or a device label, e.g. ``cpu-2core`` / ``gpu-h100``, safe in a file name."""
    import jax

    if override:
        name = override
    else:
        dev = jax.devices()[0]
        if dev.platform == "cpu":
            try:
                n = len(os.sched_getaffinity(0))
            except AttributeError:  # not on Linux
                n = os.cpu_count() or 0
            name = f"cpu-{n}core"
        else:
            m = re.search(r"\b([a-z]\d{2,4}[a-z]?)\b", dev.device_kind.lower())  # h100, a100, h200, l4 ...
            name = f"{dev.platform}-{m.group(1) if m else dev.device_kind}"
    return re.sub(r"[^a-z0-9._-]+", "-", name.lower()).strip("-")
