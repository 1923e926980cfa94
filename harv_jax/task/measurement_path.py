"""What a controller measures through: the measurement paths a controller name's suffix or a policy's
metadata names (a Butterworth low-pass, the model-based observer, the extended-state observer).

The suffixes (``NAME+lpHZ``, ``+obsHZ``, ``+esoHZ``) are read by ``harv_jax.control.registry``, which builds
the paths (``control.filters``, ``control.observer``); a policy trained behind a path records it in its
metadata as ``{"kind": "lp"|"obs"|"eso", "bandwidth_hz": HZ}`` ([`path_record`][]), checked on load
([`path_from_record`][]).
"""

from __future__ import annotations

from typing import Any, NamedTuple

from harv_jax.errors import UsageError

#: Suffix of a measurement filter: ``<name>+lp<cutoff Hz>``.
FILTER_SUFFIX = "+lp"
#: Suffix of the model-based observer: ``<name>+obs<bandwidth Hz>``.
OBSERVER_SUFFIX = "+obs"
#: Suffix of the extended-state observer (with a rate-bias estimate): ``<name>+eso<bandwidth Hz>``.
ESO_SUFFIX = "+eso"
#: Order of the filter suffix's Butterworth low-pass.
FILTER_ORDER = 2
#: Cutoffs / bandwidths a suffix may name, Hz (below the plant rate's Nyquist frequency).
FILTER_CUTOFF_RANGE_HZ = (0.05, 40.0)


class MeasurementPath(NamedTuple):
    """What a controller name's suffix puts between the sensors and the controller."""

    suffix: str  # FILTER_SUFFIX, OBSERVER_SUFFIX or ESO_SUFFIX
    bandwidth_hz: float


#: The kinds of measurement path a policy can carry (the names its metadata uses), by suffix.
PATH_KINDS: dict[str, str] = {"lp": FILTER_SUFFIX, "obs": OBSERVER_SUFFIX, "eso": ESO_SUFFIX}


def path_record(path: MeasurementPath) -> dict[str, Any]:
    """A path as a policy's metadata records it: ``{"kind": "lp"|"obs"|"eso", "bandwidth_hz": HZ}``."""
    kind = next(k for k, v in PATH_KINDS.items() if v == path.suffix)
    return {"kind": kind, "bandwidth_hz": float(path.bandwidth_hz)}


def path_from_record(record: Any, where: str) -> MeasurementPath:
    """The path of a policy's metadata record, validated; UsageError naming ``where`` and what is wrong."""
    lo, hi = FILTER_CUTOFF_RANGE_HZ
    if not isinstance(record, dict) or set(record) != {"kind", "bandwidth_hz"}:
        raise UsageError(f"{where}: measurement_path {record!r} must be {{'kind': ..., 'bandwidth_hz': ...}}")
    kind, hz = record["kind"], record["bandwidth_hz"]
    if kind not in PATH_KINDS:
        raise UsageError(
            f"{where}: measurement path kind {kind!r} is unknown; allowed: {', '.join(PATH_KINDS)}"
        )
    if isinstance(hz, bool) or not isinstance(hz, int | float) or not (lo <= hz <= hi):  # also false for nan
        raise UsageError(
            f"{where}: measurement path bandwidth {hz!r} Hz; allowed: a number from {lo:g} to {hi:g}"
        )
    return MeasurementPath(PATH_KINDS[kind], float(hz))
