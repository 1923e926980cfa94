"""Closed-loop evaluation: owns the rollouts of a ``Controller`` on the flight model (``closed_loop``),
the per-run metrics (``metrics``), the Monte Carlo (``montecarlo``), the envelope maps (``envelope``),
every seed of a training run judged (``seeds``), the empirical certificate (``certificate``) and the policy
evaluation during training (``policy_eval``). The recovery criterion, envelope and outcome codes come from
``harv_jax.task.criteria``; ``evaluation`` never imports ``env``."""

from harv_jax.evaluation.closed_loop import ClosedLoopResult, Trajectory, closed_loop, evaluate
from harv_jax.evaluation.metrics import RunMetrics, compute_metrics
from harv_jax.evaluation.summary import summarize

__all__ = [
    "ClosedLoopResult",
    "RunMetrics",
    "Trajectory",
    "closed_loop",
    "compute_metrics",
    "evaluate",
    "summarize",
]
