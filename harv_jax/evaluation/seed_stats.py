"""Statistics over training seeds: each seed's numbers, and the interquartile mean (IQM) with a 95%
stratified-bootstrap confidence interval (Agarwal et al. 2021, the ``rliable`` package).

A result over seeds is reported as every seed's value plus the IQM and its CI, never the best seed alone.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

#: Recovered fraction of the evaluation batch a seed must reach to count as meeting the criterion.
SEED_RECOVERY_BAR = 0.995
#: Bootstrap resamples of the IQM's confidence interval.
BOOTSTRAP_REPS = 2000


def iqm(values: Sequence[float]) -> float:
    """Interquartile mean of the finite ``values`` (the mean of the middle 50%, ``scipy.stats.trim_mean``
    with 25% cut at each end, as rliable's ``aggregate_iqm``); NaN if none is finite."""
    from rliable import metrics

    v = np.asarray(values, np.float64).reshape(-1)
    v = v[np.isfinite(v)]
    return float(metrics.aggregate_iqm(v)) if v.size else math.nan


def iqm_ci(values: Sequence[float], reps: int = BOOTSTRAP_REPS, seed: int = 0) -> dict[str, float]:
    """IQM of ``values`` (one per seed) and its 95% stratified-bootstrap CI (rliable).

    Returns:
        {"iqm", "ci_low", "ci_high", "n"}; with fewer than 2 finite values the CI is the value itself.
    """
    v = np.asarray(values, np.float64).reshape(-1)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"iqm": math.nan, "ci_low": math.nan, "ci_high": math.nan, "n": 0}
    if v.size < 2 or np.all(v == v[0]):
        return {"iqm": float(v.mean()), "ci_low": float(v.min()), "ci_high": float(v.max()), "n": int(v.size)}
    from rliable import library as rly
    from rliable import metrics

    np_state = np.random.get_state()
    np.random.seed(seed)  # rliable's bootstrap draws from numpy's global generator
    try:
        point, ci = rly.get_interval_estimates(
            {"x": v[:, None]}, lambda s: np.array([metrics.aggregate_iqm(s)]), reps=reps
        )
    finally:
        np.random.set_state(np_state)
    return {
        "iqm": float(point["x"][0]),
        "ci_low": float(ci["x"][0, 0]),
        "ci_high": float(ci["x"][1, 0]),
        "n": int(v.size),
    }


def seed_table(per_seed: dict[str, Sequence[float]], bar: float = SEED_RECOVERY_BAR) -> dict[str, Any]:
    """Per-seed values, IQM with CI per metric, and which seeds meet the recovery bar.

    Args:
        per_seed: metric name -> one value per seed; ``"recovered"`` (fraction) decides who meets ``bar``.
        bar: recovered fraction a seed must reach.

    Returns:
        {"per_seed": {name: [values]}, "iqm": {name: iqm_ci(...)}, "bar": bar,
        "seeds_meeting_bar": [indices], "all_seeds_meet_bar": bool}.
    """
    table = {k: [float(x) for x in np.asarray(v, np.float64).reshape(-1)] for k, v in per_seed.items()}
    rec = np.asarray(table.get("recovered", []), np.float64)
    meeting = [int(i) for i in np.flatnonzero(rec >= bar)]
    return {
        "per_seed": table,
        "iqm": {k: iqm_ci(v) for k, v in table.items()},
        "bar": bar,
        "seeds_meeting_bar": meeting,
        "all_seeds_meet_bar": bool(rec.size) and len(meeting) == rec.size,
    }
