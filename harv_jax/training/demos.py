"""Demonstrations as a behaviour-cloning source: ``harv-jax train --demos FILE`` or ``[ppo] demos = "FILE"``.

The file is what ``harv-jax optimal --save-demos`` writes ([`harv_jax.optimal.demos`][], read with its
validating, pickle-free reader). The pairs (observation, action) of every step of the recovered runs become
the demonstration set; every SGD step of the PPO update clones a minibatch of them (the behaviour-cloning
loss term, ``harv_jax.ppo.loss_terms.BehaviourCloning``) with the ``bc_coef`` schedule, besides the online
teacher's labels if the env has a teacher.

A relative ``--demos`` path is taken from the current directory, a relative ``[ppo] demos`` path from the
preset file's folder; the run records the absolute path (``config.json``'s ``ppo.demos``), and the file's
SHA-256 and the runs used (``config.json`` and ``summary.json`` ``demos``, the policy files' ``meta``).
``--resume`` reads the recorded file again and refuses one whose SHA-256 differs.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from harv_jax.errors import UsageError


class RunDemos(NamedTuple):
    """The demonstration set of a run.

    Attributes:
        path: absolute path of the file.
        sha256: SHA-256 hex digest of its bytes.
        runs: recovered runs used; runs_in_file: N.
        observations: [M, O] float32 observations of every step of the recovered runs.
        actions: [M, A] float32 actions in [-1, 1] at those observations.
    """

    path: str
    sha256: str
    runs: int
    runs_in_file: int
    observations: np.ndarray
    actions: np.ndarray

    def record(self) -> dict[str, Any]:
        """What the run records: path, SHA-256, runs used, runs in the file, pairs."""
        pairs = int(self.observations.shape[0])
        return {
            "path": self.path,
            "sha256": self.sha256,
            "runs": self.runs,
            "runs_in_file": self.runs_in_file,
            "pairs": pairs,
        }


def resolve_demos_path(path: str | Path, base: str | Path | None = None) -> str:
    """Absolute, normalized ``path``; a relative one is taken from ``base`` (None: the current directory)."""
    p = Path(os.path.expanduser(str(path)))
    if not p.is_absolute() and base is not None:
        p = Path(base) / p
    return os.path.abspath(p)


def load_run_demos(
    path: str, observation_size: int, action_size: int, expect_sha256: str | None = None
) -> RunDemos:
    """The demonstration pairs of the recovered runs in ``path``, checked against the env's sizes.

    Raises:
        UsageError: one line naming the file: missing, not a pickle-free npz, wrong format or version,
            wrong shapes (observation size other than ``observation_size``, action size other than
            ``action_size``), non-finite values, actions outside [-1, 1], no recovered run, or a SHA-256
            other than ``expect_sha256`` (``--resume``).
    """
    from harv_jax.optimal.demos import load_demos_with_digest

    try:
        demos, digest = load_demos_with_digest(path)
    except ValueError as e:
        raise UsageError(str(e)) from None
    obs_size, act_size = demos.observations.shape[-1], demos.actions.shape[-1]
    if (obs_size, act_size) != (observation_size, action_size):
        raise UsageError(
            f"demos {path!r} have {obs_size} observations and {act_size} actions per step; this run's env "
            f"has {observation_size} and {action_size}"
        )
    if expect_sha256 is not None and digest != expect_sha256:
        raise UsageError(
            f"demos {path!r} changed since the run started (SHA-256 {digest[:12]}..., recorded "
            f"{expect_sha256[:12]}...); restore that file to resume, or start a new run with --out"
        )
    rec = np.asarray(demos.recovered, bool)
    if not rec.any():
        raise UsageError(
            f"demos {path!r} hold no recovered run (recovered is false for all {demos.n_runs}); behaviour "
            "cloning needs at least one: make demos with more runs or iterations (harv-jax optimal)"
        )
    obs = np.asarray(demos.observations[rec], np.float32).reshape(-1, obs_size)
    act = np.asarray(demos.actions[rec], np.float32).reshape(-1, act_size)
    return RunDemos(os.path.abspath(path), digest, int(rec.sum()), demos.n_runs, obs, act)
