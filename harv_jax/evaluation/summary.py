"""The layout of every summary the commands write, owned here: the writers and ``harv_jax.report`` read it.

- ``summary.json`` of ``harv-jax mc``: [`mc_summary`][] with one [`summarize_controller`][] block
  per controller (and, when ``smc`` is in the run, a ``vs_smc`` block of
  ``harv_jax.evaluation.montecarlo.paired.paired_vs_reference`` in every other controller's);
- ``envelope.json`` of ``harv-jax envelope``: [`envelope_summary`][] with [`summarize_envelope`][]
  blocks;
- ``metrics.json`` of ``harv-jax fly``: [`flight_summary`][] (settings `FLY_SETTING_KEYS` and the
  run's [`metrics_to_dict`][]);
- ``compare.json`` / ``compare_metrics.csv`` of ``harv-jax compare``: rows with `COMPARE_COLUMNS`.

The top level of each document (its settings; the compare columns) is built in ``summary_documents`` and
re-exported here. The report's tables (label, key path, format) are the ``*_ROWS`` below, next to the keys
they read. One name per quantity: the fraction of runs recovered is ``recovery_rate``
(`RECOVERY_RATE`) everywhere.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from harv_jax.evaluation.metrics import RunMetrics
from harv_jax.evaluation.montecarlo.paired import mean_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import MCRunOutput, gate_summary, simplex_summary
from harv_jax.evaluation.summary_documents import COMPARE_COLUMNS as COMPARE_COLUMNS
from harv_jax.evaluation.summary_documents import FLY_SETTING_KEYS as FLY_SETTING_KEYS
from harv_jax.evaluation.summary_documents import controllers_setting as controllers_setting
from harv_jax.evaluation.summary_documents import envelope_summary as envelope_summary
from harv_jax.evaluation.summary_documents import flight_settings as flight_settings
from harv_jax.evaluation.summary_documents import flight_summary as flight_summary
from harv_jax.evaluation.summary_documents import mc_summary as mc_summary
from harv_jax.task.criteria import OUTCOME_NAMES
from harv_jax.task.spec import DT_S

#: Key of the fraction of runs recovered, in every summary.
RECOVERY_RATE = "recovery_rate"

# ----------------------------------------------------------------------------------------------------
# Per-controller blocks.


def _pct(a: np.ndarray, q: float) -> float | None:
    return float(np.percentile(a, q)) if a.size else None


def _by_channel(per_run: Any) -> dict[str, float]:
    """Mean over runs of a per-channel [N, 3] metric, keyed by surface."""
    means = np.mean(np.asarray(per_run, np.float64), axis=0)
    return {name: float(v) for name, v in zip(("elevator", "aileron", "rudder"), means, strict=True)}


def summarize_controller(
    out: MCRunOutput, wall: dict[str, float], n_steps: int | None = None, duration_s: float | None = None
) -> dict[str, Any]:
    """The per-controller block of ``summary.json`` (names relied on by users' scripts).

    ``n_steps`` (steps per run) turns the hybrid's per-step flags into counts per run. ``duration_s`` (the
    run length, s; default ``n_steps * DT_S``) is where not-recovered runs count in
    ``t_recover_mean_nr_at_run_s`` (None when neither is given).
    """
    m = out.metrics
    outcome = np.asarray(m.outcome)
    n = int(outcome.size)
    rec = np.asarray(m.recovered)
    t_rec = np.asarray(m.t_recover_s)[rec]
    t_alpha = np.asarray(m.t_recover_alpha_s, dtype=float)
    term_deg = np.degrees(np.asarray(out.terminal_error_rad))
    term = {}
    for i, name in enumerate(("alpha", "beta", "mu")):
        e = term_deg[:, i]
        e = e[np.isfinite(e)]
        term[name] = {
            "mean": float(e.mean()) if e.size else None,
            "std": float(e.std()) if e.size else None,
            "p5": _pct(e, 5),
            "p50": _pct(e, 50),
            "p95": _pct(e, 95),
            "within_0p5": float(np.mean(np.abs(term_deg[:, i]) <= 0.5)),
            "within_2": float(np.mean(np.abs(term_deg[:, i]) <= 2.0)),
        }
    counts = {name: int((outcome == code).sum()) for code, name in enumerate(OUTCOME_NAMES)}
    info = out.info_means
    run_length_s = duration_s if duration_s is not None else (n_steps * DT_S if n_steps else None)
    t_mean_nr = None if run_length_s is None else mean_nr_at_run_s(m.t_recover_s, rec, run_length_s)

    def per_run(key: str) -> float | None:
        """Mean over runs of the per-run count (n_steps given) or step fraction of a per-step flag."""
        if key not in info:
            return None
        return float(np.mean(info[key]) * (n_steps if n_steps else 1))

    hybrid = {
        "zeta_active_fraction": float(np.mean(info["zeta"])) if "zeta" in info else None,
        "zeta_switches_per_run": per_run("zeta_switched"),
        "zeta_handovers_per_run": per_run("zeta_handed_over"),
        "fallback_fraction": float(np.mean(info["fallback"])) if "fallback" in info else None,
        "fallbacks_per_run": per_run("fallback_entered"),
        **gate_summary(info),
        **simplex_summary(info),
    }
    return {
        RECOVERY_RATE: float(rec.mean()) if n else None,
        "recovery_time_s": {
            "mean": float(t_rec.mean()) if t_rec.size else None,
            "p50": _pct(t_rec, 50),
            "p95": _pct(t_rec, 95),
        },
        "t_recover_mean_nr_at_run_s": t_mean_nr,  # not-recovered runs counted at the run length
        "alpha_recovery_time_s": {  # |e_alpha| < 2 deg and ||omega|| < 0.17 rad/s from then on
            "fraction": float(np.mean(np.isfinite(t_alpha))),
            "p50": _pct(t_alpha[np.isfinite(t_alpha)], 50),
            "p95": _pct(t_alpha[np.isfinite(t_alpha)], 95),
        },
        "terminal_error_deg": term,
        "altitude_loss_ft": {
            "mean": float(np.mean(m.altitude_loss_ft)),
            "p95": _pct(np.asarray(m.altitude_loss_ft), 95),
        },
        "control_tv": {
            "mean": float(np.mean(np.sum(m.control_tv_rad, axis=-1))),
            "by_channel": _by_channel(m.control_tv_rad),
            "unit": "rad",
        },
        "chatter_index": {
            "mean": float(np.mean(np.sum(m.chatter_index_rad2, axis=-1))),
            "by_channel": _by_channel(m.chatter_index_rad2),
            "unit": "rad^2",
        },
        "saturation_fraction": float(np.mean(m.sat_position_fraction)),
        "rate_saturation_fraction": float(np.mean(m.sat_rate_fraction)),
        "safety_interventions": per_run("intervened") or 0.0,
        "safety_interventions_unit": "steps with an intervention per run" if n_steps else "step fraction",
        "hybrid": hybrid,
        "outcomes": {
            "recovered": counts["RECOVERED"],
            "departed": counts["DEPARTED"] + counts["GROUND_HIT"],
            "nonfinite": counts["NONFINITE"],
            "timeout": counts["TIMEOUT"],
        },
        "ground_hits_in_departed": counts["GROUND_HIT"],
        "left_envelope_fraction": float(np.mean(m.left_envelope)),
        "wall_time_s": {"compile": wall["compile"], "run": wall["run"]},
        "chunk_runs": wall.get("chunk_runs"),
    }


def summarize_envelope(
    out: MCRunOutput, wall: dict[str, float], n_steps: int | None = None
) -> dict[str, Any]:
    """Per-controller block of ``envelope.json``: ``recovery_rate``, counts of every ``Outcome``
    (``outcome_counts``) and the Monte Carlo block of ``summarize_controller`` (recovery time, terminal
    errors, altitude loss, control activity, wall times); ``n_steps``: steps per run."""
    outcome = np.asarray(out.metrics.outcome)
    block = summarize_controller(out, wall, n_steps)
    return {
        RECOVERY_RATE: block[RECOVERY_RATE],
        "outcome_counts": {name: int((outcome == code).sum()) for code, name in enumerate(OUTCOME_NAMES)},
        **block,
    }


def metrics_to_dict(m: RunMetrics) -> dict[str, Any]:
    """One run's metrics as JSON-ready Python values (NaN -> None; ``outcome`` is the name, e.g.
    ``RECOVERED``, ``outcome_code`` the ``Outcome`` integer)."""

    def conv(v):
        a = np.asarray(v)
        if a.dtype == bool:
            return a.tolist()
        if np.issubdtype(a.dtype, np.integer):
            return a.tolist()
        a = a.astype(float)
        if a.ndim == 0:
            return None if not np.isfinite(a) else float(a)
        return [None if not np.isfinite(z) else float(z) for z in a.ravel()]

    out = {k: conv(getattr(m, k)) for k in m.__dataclass_fields__}
    code = int(np.asarray(m.outcome))
    out["outcome"] = OUTCOME_NAMES[code]
    out["outcome_code"] = code
    out["outcome_name"] = OUTCOME_NAMES[code]  # older readers
    return out


def summarize(m: RunMetrics) -> Mapping[str, Any]:
    """Host-side summary of a batch of runs (leading axis): outcome counts, recovery rate and
    recovery-time percentiles (recovered runs only)."""
    outcome = np.asarray(m.outcome)
    n = int(outcome.shape[0])
    rec = np.asarray(m.recovered)
    t_rec = np.asarray(m.t_recover_s)[rec]
    pct = (5, 25, 50, 75, 95, 100)
    return {
        "n_runs": n,
        RECOVERY_RATE: float(rec.mean()) if n else float("nan"),
        "outcome_counts": {name: int((outcome == code).sum()) for code, name in enumerate(OUTCOME_NAMES)},
        "recovered_and_in_envelope_fraction": float((rec & ~np.asarray(m.left_envelope)).mean()),
        "t_recover_s_percentiles": (
            {f"p{p}": float(np.percentile(t_rec, p)) for p in pct} if t_rec.size else {}
        ),
        "t_recover_s_mean": float(t_rec.mean()) if t_rec.size else None,
    }


# ----------------------------------------------------------------------------------------------------
# The report's tables: (label, key path in a controller block, format).

Row = tuple[str, tuple[str, ...], str]

#: Recovery time and altitude loss (the envelope table shows them too).
MC_TIME_ROWS: tuple[Row, ...] = (
    ("recovery time mean [s]", ("recovery_time_s", "mean"), ".2f"),
    ("recovery time p50 [s]", ("recovery_time_s", "p50"), ".2f"),
    ("recovery time mean, not recovered at run length [s]", ("t_recover_mean_nr_at_run_s",), ".2f"),
    ("recovery time p95 [s]", ("recovery_time_s", "p95"), ".2f"),
    ("altitude loss mean [ft]", ("altitude_loss_ft", "mean"), ",.0f"),
    ("altitude loss p95 [ft]", ("altitude_loss_ft", "p95"), ",.0f"),
)
MC_RECOVERY_ROWS: tuple[Row, ...] = (
    ("recovery rate", (RECOVERY_RATE,), "pct"),
    *MC_TIME_ROWS,
    ("control total variation mean [rad]", ("control_tv", "mean"), ".3g"),
    ("chatter index mean [rad²]", ("chatter_index", "mean"), ".3g"),
    ("position saturation fraction", ("saturation_fraction",), ".3f"),
    ("rate saturation fraction", ("rate_saturation_fraction",), ".3f"),
    ("safety-filter interventions", ("safety_interventions",), ".4g"),
    ("left envelope (fraction of runs)", ("left_envelope_fraction",), ".3f"),
)
#: Against the SMC on the same runs (``vs_smc``; not-recovered runs at the run length).
MC_VS_SMC_ROWS: tuple[Row, ...] = (
    ("runs faster than smc by > 1 s", ("vs_smc", "faster_fraction"), "pct"),
    ("runs slower than smc by > 1 s", ("vs_smc", "slower_fraction"), "pct"),
    ("mean recovery time / smc's", ("vs_smc", "mean_ratio"), ".3f"),
)
#: Hybrid diagnostics (present for every controller in newer summaries; '–' where not applicable).
MC_HYBRID_ROWS: tuple[Row, ...] = (
    ("ζ mean (over steps and channels)", ("hybrid", "zeta_active_fraction"), ".3f"),
    ("ζ hand-overs per run", ("hybrid", "zeta_handovers_per_run"), ".3g"),
    ("tube switches per run (hysteresis)", ("hybrid", "zeta_switches_per_run"), ".3g"),
    ("supervisor fallback (fraction of steps)", ("hybrid", "fallback_fraction"), ".3f"),
    ("supervisor fallbacks per run", ("hybrid", "fallbacks_per_run"), ".3g"),
)
MC_OUTCOME_ROWS: tuple[Row, ...] = tuple(
    (name, ("outcomes", name), "int") for name in ("recovered", "departed", "nonfinite", "timeout")
) + (("ground hits (in departed)", ("ground_hits_in_departed",), "int"),)
WALL_ROWS: tuple[Row, ...] = (
    ("compile [s]", ("wall_time_s", "compile"), ".1f"),
    ("run [s]", ("wall_time_s", "run"), ".2f"),
)
_GREEK = {"alpha": "α", "beta": "β", "mu": "μ"}


def terminal_rows() -> tuple[Row, ...]:
    """Rows of the terminal-error table (format "p5/p50/p95" and "within" span several keys)."""
    rows: list[Row] = []
    for ch in ("alpha", "beta", "mu"):
        g = _GREEK[ch]
        base = ("terminal_error_deg", ch)
        rows += [
            (f"{g} mean", base + ("mean",), ".3f"),
            (f"{g} std", base + ("std",), ".3f"),
            (f"{g} p5 / p50 / p95", base, "p5/p50/p95"),
            (f"{g} within 0.5° / 2°", base, "within"),
        ]
    return tuple(rows)


def envelope_rows(outcome_codes: list[str]) -> tuple[Row, ...]:
    """Rows of the envelope table for the outcome codes present."""
    return (
        ("recovery rate", (RECOVERY_RATE,), "pct"),
        *((f"outcome {c.lower()}", ("outcome_counts", c), "int") for c in outcome_codes),
        *MC_TIME_ROWS,
        *MC_HYBRID_ROWS,
        *WALL_ROWS,
    )
