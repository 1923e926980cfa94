"""The options the closed-loop study commands share: one definition, one check, one object.

``mc``, ``robustness``, ``envelope``, ``optimal``, ``compare``, ``fly``, ``quickstart`` and ``evaluate`` each
take some of ``--runs``, ``--seed``, ``--duration``, ``--target-alpha`` and ``--chunk``. The decorator
``study_options`` gives a command the ones it names (its defaults and help where they differ) and hands it
one checked, frozen ``StudyOptions`` as the keyword ``study``.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import typer

from harv_jax.cli_options import (
    MAX_DURATION_S,
    chunk_option,
    real_number,
    whole_number,
    with_options,
)
from harv_jax.errors import UsageError
from harv_jax.guards import check_seed
from harv_jax.task.spec import ALPHA_MAX_RAD, ALPHA_MIN_RAD, ALPHA_TARGET_RAD, RECOVERY_HOLD_S

#: Largest ``--runs`` of a study.
MAX_RUNS = 1_000_000

_HELP = {
    "runs": "Monte Carlo runs.",
    "seed": "Seed of the runs' initial states, aircraft and controller keys.",
    "duration": "Run length, s.",
    "target_alpha": "Target angle of attack alpha_d, rad (beta_d = mu_d = 0).",
}


def check_duration(duration_s: float) -> None:
    """``--duration`` of a closed-loop command: longer than the recovery criterion's hold (a shorter run
    could never be scored recovered) and at most ``MAX_DURATION_S``."""
    if not (math.isfinite(duration_s) and RECOVERY_HOLD_S < duration_s <= MAX_DURATION_S):
        raise UsageError(
            f"--duration {duration_s} s: allowed ({RECOVERY_HOLD_S:g}, {MAX_DURATION_S:g}] s (longer than "
            f"the recovery criterion's {RECOVERY_HOLD_S:g} s hold, or no run could be scored recovered)"
        )


@dataclass(frozen=True)
class StudyOptions:
    """The shared options of a study command, checked on construction (one-line ``UsageError``).

    Attributes:
        seed: seed of the runs (initial states, aircraft, controller keys, disturbance draws).
        runs: Monte Carlo runs, or None where the command has no ``--runs``.
        duration_s: run length, s.
        target_alpha_rad: target angle of attack, rad.
        chunk: runs per compiled call, None: sized from the machine.
    """

    seed: int = 0
    runs: int | None = None
    duration_s: float = 60.0
    target_alpha_rad: float = ALPHA_TARGET_RAD
    chunk: int | None = None

    def __post_init__(self) -> None:
        check_seed(self.seed)
        if self.runs is not None and not 1 <= self.runs <= MAX_RUNS:
            raise UsageError(f"--runs {self.runs} must be in [1, {MAX_RUNS}]")
        alpha = self.target_alpha_rad
        if not (math.isfinite(alpha) and ALPHA_MIN_RAD <= alpha <= ALPHA_MAX_RAD):
            raise UsageError(
                f"--target-alpha {alpha} rad is outside the envelope [{ALPHA_MIN_RAD}, {ALPHA_MAX_RAD}]"
            )
        check_duration(self.duration_s)
        if self.chunk is not None and self.chunk < 1:
            raise UsageError(f"--chunk {self.chunk} must be >= 1")


def study_options(
    *,
    runs: int | None = None,
    duration: bool = True,
    target_alpha: bool = True,
    chunk: bool = False,
    help: dict[str, str] | None = None,  # noqa: A002 (the typer word)
) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Give a typer command the shared study options it takes and fill its keyword ``study``.

    Args:
        runs: the default of ``--runs``; None: the command has no ``--runs``.
        duration, target_alpha, chunk: whether the command has ``--duration``, ``--target-alpha``,
            ``--chunk`` (otherwise ``StudyOptions``' defaults).
        help: help texts that differ from the shared ones, by option name (``runs``, ``seed``, ...).
    """
    texts = {**_HELP, **(help or {})}
    keyword = inspect.Parameter.KEYWORD_ONLY

    def option(name: str, default: Any, parser: Callable[[str], Any], annotation: Any) -> inspect.Parameter:
        opt = typer.Option(default, parser=parser, help=texts[name])
        return inspect.Parameter(name, keyword, default=opt, annotation=annotation)

    added = []
    if runs is not None:
        added.append(option("runs", runs, whole_number, int))
    added.append(option("seed", 0, whole_number, int))
    if duration:
        added.append(option("duration", 60.0, real_number, float))
    if target_alpha:
        added.append(option("target_alpha", ALPHA_TARGET_RAD, real_number, float))
    if chunk:
        added.append(inspect.Parameter("chunk", keyword, default=chunk_option(), annotation=int | None))
    names = [p.name for p in added]

    def decorate(command: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(command)
        def wrapper(**kwargs: Any) -> Any:
            given = {name: kwargs.pop(name) for name in names}
            study = StudyOptions(
                seed=given["seed"],
                runs=given.get("runs"),
                duration_s=given.get("duration", 60.0),
                target_alpha_rad=given.get("target_alpha", ALPHA_TARGET_RAD),
                chunk=given.get("chunk"),
            )
            return command(**kwargs, study=study)

        return with_options(command, wrapper, "study", added)

    return decorate
