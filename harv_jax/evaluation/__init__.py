"""Closed-loop evaluation: rollouts of a Controller, outcome codes and recovery metrics."""

from harv_jax.evaluation.closed_loop import ClosedLoopResult, Trajectory, closed_loop, evaluate
from harv_jax.evaluation.metrics import (
    OUTCOME_NAMES,
    Envelope,
    Outcome,
    RecoveryCriterion,
    RunMetrics,
    compute_metrics,
    default_criterion,
    default_envelope,
    recovered_mask,
    tracking_errors,
)
from harv_jax.evaluation.summary import summarize

__all__ = [
    "OUTCOME_NAMES",
    "ClosedLoopResult",
    "Envelope",
    "Outcome",
    "RecoveryCriterion",
    "RunMetrics",
    "Trajectory",
    "closed_loop",
    "compute_metrics",
    "default_criterion",
    "default_envelope",
    "evaluate",
    "recovered_mask",
    "summarize",
    "tracking_errors",
]
