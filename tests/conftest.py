"""Shared fixtures. Rank promotion raises (rlax habit); x64 is opt-in per test via ``x64``."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import jax
import pytest

jax.config.update("jax_numpy_rank_promotion", "raise")

#: Set by the first pytest process of a run; its xdist workers (and subprocesses) inherit it.
_CACHE_ENV = "HARV_JAX_TEST_XLA_CACHE"


def pytest_configure(config):
    """One persistent XLA compilation cache per test run, in a fresh temporary folder shared by the xdist
    workers: a program compiled again with the same HLO (the same command flown twice, a determinism check,
    a rebuilt controller) is read back instead of compiled. It holds nothing from earlier runs and is removed
    at the end. A cache the user configured (``JAX_COMPILATION_CACHE_DIR``) is left as it is."""
    if os.environ.get("JAX_COMPILATION_CACHE_DIR") and not os.environ.get(_CACHE_ENV):
        return
    if not os.environ.get(_CACHE_ENV):
        os.environ[_CACHE_ENV] = tempfile.mkdtemp(prefix="harv_jax_test_xla_cache_")
        config._harv_jax_xla_cache = os.environ[_CACHE_ENV]  # this process removes it
    os.environ["JAX_COMPILATION_CACHE_DIR"] = os.environ[_CACHE_ENV]
    jax.config.update("jax_compilation_cache_dir", os.environ[_CACHE_ENV])


def pytest_unconfigure(config):
    path = getattr(config, "_harv_jax_xla_cache", None)
    if path:
        shutil.rmtree(path, ignore_errors=True)
        os.environ.pop(_CACHE_ENV, None)
        os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)


@pytest.fixture
def x64():
    """Run the test body with float64 enabled (restored afterwards)."""
    with jax.enable_x64(True):
        yield


@pytest.fixture
def damper():
    """``cheap_controller.make_damper`` registered as the controller ``damper`` (removed afterwards): for the
    command-line tests whose point is the command's files and flags, not the SMC (it compiles in seconds)."""
    from cheap_controller import make_damper, registered

    with registered("damper", make_damper, "rate damper (tests)") as name:
        yield name


@pytest.fixture
def figure_texts(monkeypatch):
    """Every figure harv-jax saves during the test, checked as a reader sees it before it is written:
    file name -> the texts drawn outside the figure (``figure_checks.texts_outside``; [] when all fit).
    ``figure_texts.figures`` holds the figures themselves by file name."""
    from figure_checks import texts_outside

    from harv_jax import atomic

    class Outside(dict):
        def __init__(self) -> None:
            super().__init__()
            self.figures: dict = {}

    save, outside = atomic.save_figure, Outside()

    def checked(fig, path, **kw):
        outside[Path(path).name] = texts_outside(fig)
        outside.figures[Path(path).name] = fig
        return save(fig, path, **kw)

    monkeypatch.setattr(atomic, "save_figure", checked)
    return outside
