"""The acceptance criteria of a trained policy, defined once: `CRITERIA`.

``harv-jax evaluate`` (``harv_jax.evaluation.seeds.conditions``) computes, for every seed of a training run,
a flat dict of numbers named ``<condition>.<controller>.<metric>`` (``clean.rl.recovered``,
``disturbed.rl.mean_over_ref``, ...); each criterion reads one of them and compares it with its bar. A seed
passes a criterion when its number is at or on the good side of the bar; a number that could not be
computed (a condition not evaluated) leaves the criterion unjudged (None), never passed.

The bars (RL-only ``rl`` and the default hybrid ``hybrid``; the reference controller of each condition is
the SMC, behind its measurement path ``smc+lp2`` in the disturbed conditions; times with a run not
recovered counted at the run length; "slower" = slower than the reference by more than 1 s, paired):

- clean, nominal aircraft: ``rl`` recovers >= 99.5%, mean <= 0.75x the SMC's, slower on <= 20% of runs,
  p95 <= the SMC's, control TV <= 1.1x the SMC's; the 30 s spin recovered within the SMC's time + 0.5 s;
  ``hybrid`` >= 99.9%, mean <= 0.75x;
- clean, randomized aircraft: ``rl`` >= 99.5%;
- disturbed (``--disturbances default``): ``rl`` >= 99.5%, ``hybrid`` >= 99.9%, ``rl`` mean <= 0.75x the
  reference's; TV <= 1.5x and chatter <= 2x their own clean values (``rl`` and ``hybrid``);
- each disturbance alone: sensor noise x3: ``rl`` >= 99%, ``hybrid`` >= 99.9%; model error x2: both >= 99%;
- stretch (reported, not required): ``rl``'s mean at or below ``smc-brake-zoom``'s, clean and disturbed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Criterion:
    """One bar.

    Attributes:
        name: short identifier (JSON key).
        metric: the per-seed number it reads (``<condition>.<controller>.<metric>``).
        op: ``">="`` (at least the bar) or ``"<="`` (at most the bar).
        bar: the threshold.
        text: what it says, for tables.
        stretch: reported, not part of the pass.
    """

    name: str
    metric: str
    op: str
    bar: float
    text: str
    stretch: bool = False

    def judge(self, metrics: dict[str, Any]) -> bool | None:
        """True/False for a seed's metrics; None when the number is missing or not finite."""
        v = metrics.get(self.metric)
        if v is None or not isinstance(v, int | float) or not math.isfinite(v):
            return None
        return bool(v >= self.bar) if self.op == ">=" else bool(v <= self.bar)


def _c(name: str, metric: str, op: str, bar: float, text: str, stretch: bool = False) -> Criterion:
    if op not in (">=", "<="):
        raise ValueError(f"criterion {name}: op {op!r}; allowed: >=, <=")
    return Criterion(name, metric, op, bar, text, stretch)


#: Every criterion, in report order.
CRITERIA: tuple[Criterion, ...] = (
    _c("clean_rl_recovered", "clean.rl.recovered", ">=", 0.995, "clean: RL recovers >= 99.5%"),
    _c("randomized_rl_recovered", "randomized.rl.recovered", ">=", 0.995, "randomized aircraft: RL >= 99.5%"),
    _c("clean_rl_mean", "clean.rl.mean_over_ref", "<=", 0.75, "clean: RL mean <= 0.75x the SMC's"),
    _c("clean_rl_slower", "clean.rl.slower_than_ref", "<=", 0.20, "clean: RL slower by > 1 s on <= 20%"),
    _c("clean_rl_p95", "clean.rl.p95_over_ref", "<=", 1.0, "clean: RL p95 <= the SMC's"),
    _c("clean_rl_tv", "clean.rl.tv_over_ref", "<=", 1.1, "clean: RL control TV <= 1.1x the SMC's"),
    _c("spin_rl", "spin.rl.time_minus_ref_s", "<=", 0.5, "30 s spin: RL within the SMC's time + 0.5 s"),
    _c("clean_hybrid_recovered", "clean.hybrid.recovered", ">=", 0.999, "clean: hybrid >= 99.9%"),
    _c("clean_hybrid_mean", "clean.hybrid.mean_over_ref", "<=", 0.75, "clean: hybrid mean <= 0.75x"),
    _c("disturbed_rl_recovered", "disturbed.rl.recovered", ">=", 0.995, "disturbed: RL >= 99.5%"),
    _c("disturbed_hybrid_recovered", "disturbed.hybrid.recovered", ">=", 0.999, "disturbed: hybrid >= 99.9%"),
    _c(
        "disturbed_rl_mean",
        "disturbed.rl.mean_over_ref",
        "<=",
        0.75,
        "disturbed: RL mean <= 0.75x smc+lp2's",
    ),
    _c("disturbed_rl_tv", "disturbed.rl.tv_over_clean", "<=", 1.5, "disturbed: RL TV <= 1.5x its clean TV"),
    _c(
        "disturbed_hybrid_tv",
        "disturbed.hybrid.tv_over_clean",
        "<=",
        1.5,
        "disturbed: hybrid TV <= 1.5x its clean TV",
    ),
    _c(
        "disturbed_rl_chatter",
        "disturbed.rl.chatter_over_clean",
        "<=",
        2.0,
        "disturbed: RL chatter <= 2x its clean chatter",
    ),
    _c(
        "disturbed_hybrid_chatter",
        "disturbed.hybrid.chatter_over_clean",
        "<=",
        2.0,
        "disturbed: hybrid chatter <= 2x its clean chatter",
    ),
    _c("noise3_rl_recovered", "noise3.rl.recovered", ">=", 0.99, "noise x3: RL >= 99%"),
    _c("noise3_hybrid_recovered", "noise3.hybrid.recovered", ">=", 0.999, "noise x3: hybrid >= 99.9%"),
    _c("model2_rl_recovered", "model2.rl.recovered", ">=", 0.99, "model error x2: RL >= 99%"),
    _c("model2_hybrid_recovered", "model2.hybrid.recovered", ">=", 0.99, "model error x2: hybrid >= 99%"),
    _c(
        "clean_rl_vs_zoom",
        "clean.rl.mean_over_smc_brake_zoom",
        "<=",
        1.0,
        "stretch, clean: RL mean <= smc-brake-zoom's",
        stretch=True,
    ),
    _c(
        "disturbed_rl_vs_zoom",
        "disturbed.rl.mean_over_smc_brake_zoom",
        "<=",
        1.0,
        "stretch, disturbed: RL mean <= smc-brake-zoom's",
        stretch=True,
    ),
)


def judge(metrics: dict[str, Any], criteria: tuple[Criterion, ...] = CRITERIA) -> dict[str, bool | None]:
    """Each criterion's verdict on one seed's metrics (None: not judged)."""
    return {c.name: c.judge(metrics) for c in criteria}


def passes(verdicts: dict[str, bool | None], criteria: tuple[Criterion, ...] = CRITERIA) -> bool | None:
    """Whether a seed passes every required criterion that was judged; None if none was."""
    required = [verdicts[c.name] for c in criteria if not c.stretch and verdicts.get(c.name) is not None]
    return all(required) if required else None
