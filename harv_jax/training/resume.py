"""How ``harv-jax train --resume DIR`` continues a run: from its newest intact checkpoint, or from period 0.

A damaged newer checkpoint is skipped (named in a message; ``harv_jax.ppo.runner`` renames it
``*.corrupt``); a run folder killed before its first checkpoint is restarted from period 0 with the
configuration in its ``config.json``. A run with demonstrations reads the recorded file again (its SHA-256
must be the one in ``config.json``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, NamedTuple

from harv_jax.errors import UsageError
from harv_jax.ppo import checkpoint
from harv_jax.training.spec import TrainSpec


class ResumePlan(NamedTuple):
    """How ``--resume DIR`` continues: from a checkpoint (``from_checkpoint``) or from period 0.

    Attributes:
        spec: the run's stored spec (from the checkpoint or ``config.json``).
        from_checkpoint: whether a checkpoint holds the state to continue from.
        period: the periods done.
        env_steps: the env steps per seed done.
        messages: lines to show (skipped damaged checkpoints, where the run resumes).
    """

    spec: TrainSpec
    from_checkpoint: bool
    period: int
    env_steps: int
    messages: tuple[str, ...]


def resume_plan(run_dir: Path) -> ResumePlan:
    """Decide how to continue the run in ``run_dir``: its newest intact checkpoint, or, if it was stopped
    before writing one, a restart from period 0 with its ``config.json``. UsageError if neither exists."""
    ckpt_dir = run_dir / "checkpoints"
    choice = checkpoint.latest_intact(ckpt_dir)
    if choice is not None:
        messages = [
            f"skipping checkpoint {p.name}: {reason.removeprefix(f'checkpoint {str(p)!r} ')}; "
            f"it is kept as {p.name}.corrupt"
            for p, reason in choice.skipped
        ]
        period, steps = int(choice.payload["period"]), int(choice.payload["env_steps"])
        messages.append(f"resuming from period {period} (env steps {steps:,}) of {choice.path}")
        # the preset, target and demonstrations the run was started with (config.json); the settings the
        # checkpoint was written with; the state: the checkpoint's (no initial policy to load)
        checkpointed = {
            "ppo": json.loads(choice.payload["config"]),
            "env": json.loads(choice.payload["env_config"]),
            "init_policy": None,
        }
        spec = TrainSpec.from_record({**(_record(run_dir) or {}), **checkpointed}, choice.path.name)
        return ResumePlan(spec, True, period, steps, tuple(messages))
    record_path = run_dir / "config.json"
    if not record_path.is_file():
        raise UsageError(
            f"no checkpoint found in {str(ckpt_dir)!r} and no config.json in {str(run_dir)!r}: "
            "not a harv-jax train run folder; start a new run with --out"
        )
    try:
        spec = TrainSpec.from_record(json.loads(record_path.read_text()), str(record_path))
    except UsageError:
        raise
    except (ValueError, KeyError, TypeError, AttributeError, OSError) as e:
        raise UsageError(
            f"no checkpoint found in {str(ckpt_dir)!r} and {str(record_path)!r} is unreadable "
            f"({type(e).__name__}); start the run again with --out {str(run_dir)!r} --force"
        ) from None
    msg = (
        f"no checkpoint in {ckpt_dir} (the run stopped before its first one): restarting it from "
        "period 0 with the configuration in its config.json"
    )
    return ResumePlan(spec, False, 0, 0, (msg,))


def _record(run_dir: Path) -> dict[str, Any] | None:
    """``run_dir/config.json`` as a dict, or None if it is missing or unreadable."""
    try:
        record = json.loads((run_dir / "config.json").read_text())
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None
