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
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo.config import PPOConfig


class ResumePlan(NamedTuple):
    """How ``--resume DIR`` continues: from a checkpoint (``from_checkpoint``) or from period 0."""

    cfg: PPOConfig
    env_table: dict[str, Any]
    from_checkpoint: bool
    period: int
    env_steps: int
    init_policy: str | None
    messages: tuple[str, ...]
    demos_sha256: str | None = None


def _checked_env(env_table: Any, source: str) -> dict[str, Any]:
    """A run's stored env settings, validated (``harv_jax.env.settings``); UsageError naming ``source``."""
    from harv_jax.env.settings import check_env_settings
    from harv_jax.training.in_loop import split_loop

    if not isinstance(env_table, dict):
        raise UsageError(f"{source}: the stored env settings {env_table!r} are not a table")
    try:
        check_env_settings(split_loop(env_table)[1])
    except UsageError as e:
        raise UsageError(f"{source}: {e}") from None
    return dict(env_table)


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
        cfg = ppo_config.from_dict(json.loads(choice.payload["config"]), source=choice.path.name)
        env_table = _checked_env(json.loads(choice.payload["env_config"]), choice.path.name)
        return ResumePlan(cfg, env_table, True, period, steps, None, tuple(messages), _demos_sha256(run_dir))
    record_path = run_dir / "config.json"
    if not record_path.is_file():
        raise UsageError(
            f"no checkpoint found in {str(ckpt_dir)!r} and no config.json in {str(run_dir)!r}: "
            "not a harv-jax train run folder; start a new run with --out"
        )
    try:
        record = json.loads(record_path.read_text())
        cfg = ppo_config.from_dict(record["ppo"], source=str(record_path))
        env_table = _checked_env(record.get("env", {}), str(record_path))
        init_policy = record.get("init_policy")
        if init_policy is not None and not isinstance(init_policy, str):
            raise TypeError("init_policy")
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
    return ResumePlan(cfg, env_table, False, 0, 0, init_policy, (msg,), _demos_sha256(run_dir))


def _demos_sha256(run_dir: Path) -> str | None:
    """The SHA-256 of the demonstrations recorded in ``run_dir/config.json`` (None: none recorded)."""
    try:
        digest = json.loads((run_dir / "config.json").read_text())["demos"]["sha256"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return digest if isinstance(digest, str) else None
