"""Numbers for people: float32 results rounded to the digits they carry (no ``23.51999855041504``)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from harv_jax import atomic

#: Significant digits kept in JSON outputs: float32 carries about 7, so 6 keeps every meaningful one.
JSON_DIGITS = 6


def round_sig(x: float, digits: int = JSON_DIGITS) -> float:
    """``x`` rounded to ``digits`` significant digits (0, NaN and inf unchanged)."""
    if x == 0 or not math.isfinite(x):
        return x
    return round(x, digits - 1 - math.floor(math.log10(abs(x))))


def round_floats(obj: Any, digits: int = JSON_DIGITS) -> Any:
    """A copy of a JSON-like tree with every float rounded by [`round_sig`][]."""
    if isinstance(obj, float):
        return round_sig(obj, digits)
    if isinstance(obj, dict):
        return {k: round_floats(v, digits) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [round_floats(v, digits) for v in obj]
    return obj


def write_json(path: str | Path, doc: Any, digits: int = JSON_DIGITS) -> Path:
    """Write ``doc`` as indented JSON with floats rounded to ``digits`` significant digits."""
    path = Path(path)
    atomic.write_text(path, json.dumps(round_floats(doc, digits), indent=2) + "\n")
    return path


def fmt_num(x: float | None, digits: int = 4, unit: str = "", missing: str = "-") -> str:
    """``x`` with ``digits`` significant digits and an optional unit for a message or table (``missing``
    for None/NaN)."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return missing
    return f"{x:.{digits}g}" + (f" {unit}" if unit else "")
