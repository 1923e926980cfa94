"""Output directories: never silently overwrite what a previous run wrote."""

from __future__ import annotations

import shutil
from pathlib import Path

from harv_jax.errors import UsageError


def prepare_out_dir(path: str | Path, force: bool = False) -> Path:
    """Create ``path`` for a new run's outputs.

    Raises:
        UsageError: ``path`` exists and is not empty, and ``force`` is False.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {str(out)!r} exists and is not a directory")
    if out.exists() and any(out.iterdir()):
        if not force:
            raise UsageError(
                f"--out {str(out)!r} already exists and is not empty; choose another or pass --force"
            )
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)
    return out
