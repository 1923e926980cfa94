"""The deterministic policy as serialized StableHLO (``jax.export``), for use without the model code.

[`export_stablehlo`][] writes ``policy.deterministic`` for a symbolic batch size with the weights baked in;
[`load_exported`][] reads such a file back as ``obs [b, O] -> action [b, A]``. Serialization needs the
``flatbuffers`` package ([`export_available`][]). ``harv_jax.policy`` re-exports all three.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp

from harv_jax import atomic
from harv_jax.errors import UsageError

if TYPE_CHECKING:
    from harv_jax.policy import Policy


def export_available() -> bool:
    """True if ``jax.export`` serialization works here (it needs the ``flatbuffers`` package)."""
    import importlib.util

    return importlib.util.find_spec("flatbuffers") is not None


def export_stablehlo(path: str | Path, policy: Policy) -> Path:
    """Serialize ``policy.deterministic`` for obs ``[b, O]`` float32 (symbolic b) with ``jax.export``.

    Raises:
        UsageError: the ``flatbuffers`` package (needed by jax.export serialization) is not installed, or
            the policy carries a measurement path (the export holds the network only).
    """
    if not export_available():
        raise UsageError("jax.export serialization needs the 'flatbuffers' package: pip install flatbuffers")
    if policy.meta.get("measurement_path") is not None:
        raise UsageError(
            f"the policy carries a measurement path ({policy.meta['measurement_path']}) that the export "
            "would leave out; fly it through harv_jax (--controller rl) or export one trained without it"
        )
    (b,) = jax.export.symbolic_shape("b")
    spec = jax.ShapeDtypeStruct((b, policy.networks.observation_size), jnp.float32)
    exported = jax.export.export(policy.deterministic)(spec)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic.write_bytes(path, exported.serialize())
    return path


def load_exported(path: str | Path) -> Callable[[jax.Array], jax.Array]:
    """Read a [`export_stablehlo`][] file: returns ``obs [b, O] -> action [b, A]``."""
    p = Path(path)
    if not p.is_file():
        raise UsageError(f"exported policy {str(p)!r} does not exist")
    exported = jax.export.deserialize(bytearray(p.read_bytes()))
    return exported.call
