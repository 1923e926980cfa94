"""What machine a result was measured on: the CPU's model name and its widest SIMD level."""

from __future__ import annotations

import platform
import re
from pathlib import Path


def _cpuinfo() -> str:
    try:
        return Path("/proc/cpuinfo").read_text()
    except OSError:
        return ""


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``; ``platform.processor()`` elsewhere, or ``unknown``)."""
    found = re.search(r"^model name\s*:\s*(.+)$", _cpuinfo(), re.M)
    return found.group(1).strip() if found else platform.processor() or "unknown"


def simd_level() -> str:
    """``avx512f``, ``avx2`` or ``""`` (unknown or neither), from the CPU's flags."""
    found = re.search(r"^flags\s*:\s*(.+)$", _cpuinfo(), re.M)
    flags = f" {found.group(1)} " if found else ""
    return "avx512f" if " avx512f " in flags else "avx2" if " avx2 " in flags else ""
