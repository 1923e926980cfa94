"""The studies' shared options: one check per value, one object, one signature for typer."""

from __future__ import annotations

import inspect

import pytest

from harv_jax.errors import UsageError
from harv_jax.study_options import StudyOptions, study_options
from harv_jax.task.spec import ALPHA_MAX_RAD, ALPHA_TARGET_RAD, RECOVERY_HOLD_S


def test_defaults_are_the_monte_carlo_defaults() -> None:
    s = StudyOptions()
    assert (s.seed, s.runs, s.duration_s, s.target_alpha_rad, s.chunk) == (
        0,
        None,
        60.0,
        ALPHA_TARGET_RAD,
        None,
    )


@pytest.mark.parametrize(
    ("kwargs", "flag"),
    [
        ({"runs": 0}, "--runs 0"),
        ({"runs": 1_000_001}, "--runs 1000001"),
        ({"seed": -1}, "--seed -1"),
        ({"duration_s": RECOVERY_HOLD_S}, "--duration"),
        ({"duration_s": float("nan")}, "--duration nan"),
        ({"target_alpha_rad": ALPHA_MAX_RAD + 0.01}, "--target-alpha"),
        ({"chunk": 0}, "--chunk 0"),
    ],
)
def test_a_bad_value_is_one_line_naming_its_flag(kwargs: dict, flag: str) -> None:
    with pytest.raises(UsageError) as err:
        StudyOptions(**kwargs)
    assert str(err.value).startswith(flag) and "\n" not in str(err.value)
    assert isinstance(err.value, ValueError)  # the API's error type


def test_the_edges_pass() -> None:
    StudyOptions(seed=2**31 - 1, runs=1, duration_s=600.0, target_alpha_rad=ALPHA_MAX_RAD, chunk=1)


def test_the_decorator_adds_only_the_named_options_and_fills_study() -> None:
    seen = {}

    @study_options(runs=256, target_alpha=False, help={"runs": "Runs per level."})
    def command(out: str = "x", study: StudyOptions = StudyOptions()) -> None:
        seen["study"] = study

    names = list(inspect.signature(command).parameters)
    assert names == ["out", "runs", "seed", "duration"]
    assert inspect.signature(command).parameters["runs"].default.help == "Runs per level."
    command(out="y", runs=7, seed=3, duration=30.0)
    assert seen["study"] == StudyOptions(seed=3, runs=7, duration_s=30.0)
    with pytest.raises(UsageError, match="--runs 0"):
        command(out="y", runs=0, seed=3, duration=30.0)
