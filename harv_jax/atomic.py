"""Atomic output files: each is written to a temporary file beside it, then renamed over its name, so a
killed command leaves either the old file, the new one, or a temporary file harv-jax recognizes as its own
([`harv_jax.manifest.OWN_PATTERNS`][]), never half a file. Each file is recorded in the manifest of the run
folder it lies in ([`harv_jax.manifest.record`][])."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from harv_jax import manifest

#: Suffix of the temporary file of an atomic write.
TMP_SUFFIX = ".harv_jax_tmp"


def tmp_path(path: str | Path) -> Path:
    """The temporary file an atomic write of ``path`` fills: ``.<name>.<pid>.harv_jax_tmp`` beside it."""
    p = Path(path)
    return p.with_name(f".{p.name}.{os.getpid()}{TMP_SUFFIX}")


@contextlib.contextmanager
def replacing(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path to write; on success it is renamed to ``path`` and recorded, on an error
    removed."""
    final = Path(path)
    tmp = tmp_path(final)
    try:
        yield tmp
        os.replace(tmp, final)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    manifest.record(final)


@contextlib.contextmanager
def open_atomic(path: str | Path, mode: str = "w", **kwargs: Any) -> Iterator[IO[Any]]:
    """``open(path, mode)`` that replaces ``path`` only when the block ends without an error."""
    with replacing(path) as tmp, open(tmp, mode, **kwargs) as f:
        yield f


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (UTF-8)."""
    with open_atomic(path, "w", encoding="utf-8") as f:
        f.write(text)
    return Path(path)


def write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    with open_atomic(path, "wb") as f:
        f.write(data)
    return Path(path)


def save_figure(fig: Any, path: str | Path, **kwargs: Any) -> Path:
    """``fig.savefig(path, **kwargs)`` atomically (the format from the suffix of ``path``)."""
    p = Path(path)
    kwargs.setdefault("format", p.suffix.lstrip(".") or None)
    with open_atomic(p, "wb") as f:
        fig.savefig(f, **kwargs)
    return p


def savez(path: str | Path, compressed: bool = False, **arrays: Any) -> Path:
    """``numpy.savez`` (or ``savez_compressed``) to exactly ``path``, atomically."""
    import numpy as np

    with open_atomic(path, "wb") as f:
        (np.savez_compressed if compressed else np.savez)(f, **arrays)
    return Path(path)


def savetxt(path: str | Path, x: Any, **kwargs: Any) -> Path:
    """``numpy.savetxt(path, x, **kwargs)`` atomically."""
    import numpy as np

    with open_atomic(path, "w", encoding="utf-8") as f:
        np.savetxt(f, x, **kwargs)
    return Path(path)
