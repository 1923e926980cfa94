"""Recovery times compared run by run: not-recovered runs at the run length, and a controller against a
reference controller on the same runs.

Every controller of a Monte Carlo flies the same sampled aircraft and initial states (common random
numbers), so run i of one controller and run i of another form a pair. A run that does not recover is
counted at the run length (the Monte Carlo's duration): it took at least that long, so the mean stays
finite and a controller that loses runs is not flattered by averaging only the runs it recovered.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

#: Controller the paired comparisons are made against (when it is part of the run).
REFERENCE_CONTROLLER = "smc"
#: A pair counts as faster / slower when the times differ by more than this, s.
PAIRED_MARGIN_S = 1.0


def times_nr_at_run_s(t_recover_s: Any, recovered: Any, run_length_s: float) -> np.ndarray:
    """Per-run recovery times [N] (float64), s, with not-recovered runs at ``run_length_s``."""
    t = np.asarray(t_recover_s, np.float64)
    rec = np.asarray(recovered, bool) & np.isfinite(t)
    return np.where(rec, t, float(run_length_s))


def mean_nr_at_run_s(t_recover_s: Any, recovered: Any, run_length_s: float) -> float | None:
    """Mean recovery time, s, with not-recovered runs at ``run_length_s`` (None for no runs)."""
    t = times_nr_at_run_s(t_recover_s, recovered, run_length_s)
    return float(t.mean()) if t.size else None


def paired_vs_reference(
    t_recover_s: Any,
    recovered: Any,
    t_reference_s: Any,
    recovered_reference: Any,
    run_length_s: float,
    margin_s: float = PAIRED_MARGIN_S,
) -> dict[str, float | int | None]:
    """A controller against a reference on the same runs (not-recovered runs at ``run_length_s``).

    Args:
        t_recover_s, recovered: the controller's per-run recovery times [N] (s; NaN when not recovered)
            and recovered flags [N].
        t_reference_s, recovered_reference: the reference's, on the same N runs in the same order.
        run_length_s: run length, s.
        margin_s: a run counts as faster (slower) when the controller's time is below (above) the
            reference's by more than this, s.

    Returns:
        ``faster_fraction`` and ``slower_fraction`` (shares of the N runs), ``mean_ratio`` (the
        controller's mean over the reference's; None when the reference's mean is 0), ``runs`` (N),
        ``margin_s``, ``run_length_s``. Fractions and ratio are None for no runs.
    """
    t = times_nr_at_run_s(t_recover_s, recovered, run_length_s)
    t_ref = times_nr_at_run_s(t_reference_s, recovered_reference, run_length_s)
    if t.shape != t_ref.shape:
        raise ValueError(f"paired runs differ in number: {t.shape} vs {t_ref.shape}")
    n = int(t.size)
    ref_mean = float(t_ref.mean()) if n else 0.0
    return {
        "faster_fraction": float(np.mean(t < t_ref - margin_s)) if n else None,
        "slower_fraction": float(np.mean(t > t_ref + margin_s)) if n else None,
        "mean_ratio": float(t.mean() / ref_mean) if n and ref_mean > 0 else None,
        "runs": n,
        "margin_s": float(margin_s),
        "run_length_s": float(run_length_s),
    }


def paired_vs_smc(
    times: Mapping[str, tuple[Any, Any]], run_length_s: float, margin_s: float = PAIRED_MARGIN_S
) -> dict[str, dict[str, float | int | None]]:
    """[`paired_vs_reference`][] against ``smc`` for every other controller.

    Args:
        times: controller -> (t_recover_s [N], recovered [N]), the same N runs for every controller.
        run_length_s: run length, s.
        margin_s: see [`paired_vs_reference`][].

    Returns:
        controller -> comparison block, for every controller but ``smc``; empty when ``smc`` is not in
        ``times``.
    """
    if REFERENCE_CONTROLLER not in times:
        return {}
    t_ref, rec_ref = times[REFERENCE_CONTROLLER]
    return {
        name: paired_vs_reference(t, rec, t_ref, rec_ref, run_length_s, margin_s)
        for name, (t, rec) in times.items()
        if name != REFERENCE_CONTROLLER
    }
