"""The HARV training recipes (presets), shipped as package data in ``harv_jax/training/presets/*.toml``.

A preset file has a ``[ppo]`` table (fields of [`PPOConfig`][harv_jax.ppo.config.PPOConfig]), an optional
``[env]`` table that is passed to the environment's config, and optional ``[reward]``, ``[randomization]``,
``[spin]`` and ``[eval]`` tables, returned nested inside the env settings (``harv_jax.env.settings``
validates them). A preset is named by its file name without ``.toml`` (``smoke``, ``paper-partial``,
``paper-full``, ``recovery``) or given as a path to a ``.toml`` file. A relative ``[ppo] demos`` path
([`harv_jax.training.demos`][]) is taken from the preset file's folder.
"""

from __future__ import annotations

import importlib.resources
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from harv_jax.aircraft.registry import DEFAULT_AIRCRAFT
from harv_jax.errors import UsageError
from harv_jax.ppo import config as ppo_config
from harv_jax.ppo.config import PPOConfig
from harv_jax.training.demos import resolve_demos_path
from harv_jax.training.in_loop import LOOP_KEY, parse_loop
from harv_jax.training.spec import TrainSpec, check_env_table

if TYPE_CHECKING:  # the preset files are read without jax (the command-line help does)
    from harv_jax.training.spec import TrainSpec

#: Folder of the preset files (package data: ``pyproject.toml`` [tool.setuptools.package-data]).
PRESET_DIR: Traversable = importlib.resources.files("harv_jax.training") / "presets"
#: Tables of a preset besides ``[ppo]``; all but ``env`` are stored nested inside the env settings.
NESTED_TABLES = ("reward", "randomization", "spin", "eval")
#: Name of the preset used when none is given.
DEFAULT_PRESET = "robust"


def _preset_files() -> dict[str, Traversable]:
    if not PRESET_DIR.is_dir():
        return {}
    return {
        f.name[: -len(".toml")]: f for f in PRESET_DIR.iterdir() if f.name.endswith(".toml") and f.is_file()
    }


def available_presets() -> list[str]:
    """Names of the shipped presets."""
    return sorted(_preset_files())


def preset_path(name: str) -> Traversable | None:
    """The file of preset ``name``, or None."""
    return _preset_files().get(name)


def _preset_file(name: str) -> Path | Traversable:
    """The file of a preset name or ``.toml`` path; UsageError naming it and what is allowed if none."""
    allowed = ", ".join(available_presets()) or "(none found)"
    if not name.endswith(".toml"):
        path = preset_path(name)
        if path is None:
            raise UsageError(f"unknown preset {name!r}; available: {allowed} (or a path to a .toml file)")
        return path
    path = Path(name)
    if path.is_dir():
        raise UsageError(f"preset {name!r} is a directory; give a .toml file or a shipped preset: {allowed}")
    if not path.is_file():
        what = "is not a regular file" if path.exists() else "does not exist"
        raise UsageError(f"preset file {name!r} {what}; give a .toml file or a shipped preset: {allowed}")
    return path


def load_preset(name: str, check_env: bool = True) -> tuple[PPOConfig, dict[str, Any]]:
    """Load a preset by name (``smoke``, ``paper-partial`` ...) or by path to a ``.toml`` file.

    Args:
        name: a shipped preset's name or a path ending in ``.toml``.
        check_env: also validate the env settings and the wrapper keys
            ([`check_env_table`][harv_jax.training.spec.check_env_table]; imports jax). False reads
            the ``[ppo]`` table's values only (the command-line help does).

    Returns:
        (validated PPOConfig, env settings: the ``[env]`` table with the nested tables inside).

    Raises:
        UsageError: unknown name, missing or unreadable file, bad TOML, unknown table, or a bad value in any
            table, named with the preset.
    """
    path = _preset_file(name)
    cfg, tables = ppo_config.load_file(path, ("env", *NESTED_TABLES))
    if (
        cfg.demos is not None
    ):  # a relative path is the preset folder's (a preset and its demos travel together)
        cfg = cfg.replace(demos=resolve_demos_path(cfg.demos, Path(str(path)).parent))
    env = dict(tables.get("env", {}))
    for table in NESTED_TABLES:  # stored inside the env settings (checkpoints keep them for --resume)
        if table in tables:
            env[table] = dict(tables[table])
    if check_env:  # every table and the wrapper keys' rules (those with [ppo] settings: in the spec)
        try:
            check_env_table(env)
        except UsageError as e:
            raise UsageError(f"preset {path.name}: {e}") from None
    return cfg, env


def load_spec(
    preset: str | None = None,
    overrides: dict[str, Any] | None = None,
    in_loop: str | None = None,
    aircraft: str | None = None,
    init_policy: str | None = None,
    target_recovery: float | None = None,
) -> TrainSpec:
    """The [`TrainSpec`][harv_jax.training.spec.TrainSpec] of a preset (None: the default) and the
    command line: ``overrides`` of ``[ppo]`` fields (None values: not given), ``--in-loop``, ``--aircraft``
    (None: the preset's ``[env] aircraft``, else the registry's default; always recorded),
    ``--init-policy`` and ``--target-recovery``. UsageError naming the first bad value."""

    name = preset or DEFAULT_PRESET
    cfg, env_table = load_preset(name)
    changes = {k: v for k, v in (overrides or {}).items() if v is not None}
    cfg = ppo_config.from_dict(changes, base=cfg, source="command line")
    if in_loop is not None:
        env_table = {**env_table, LOOP_KEY: parse_loop(in_loop)}
    env_table = {**env_table, "aircraft": aircraft or env_table.get("aircraft", DEFAULT_AIRCRAFT)}
    return TrainSpec.from_settings(name, cfg, env_table, init_policy, target_recovery)
