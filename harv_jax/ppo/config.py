"""PPO configuration: a frozen dataclass, validation, derived sizes, and a generic TOML loader.

A config file ([`load_file`][]) has a ``[ppo]`` table (fields of [`PPOConfig`][]) and whatever other
tables its caller accepts (the HARV recipes in ``harv_jax.training.presets`` add ``[env]``, ``[reward]``
...). Every bad value raises `harv_jax.errors.UsageError` with a one-line message naming the value
and what is allowed. Derived quantities (updates, periods, batch sizes) are computed by functions and never
written back into the config.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass
from importlib.resources.abc import Traversable
from pathlib import Path
from typing import Any

from harv_jax.errors import UsageError
from harv_jax.guards import check_network, check_seed, check_train

LR_SCHEDULES = ("constant", "linear")


@dataclass(frozen=True)
class PPOConfig:
    """PPO hyperparameters. Shapes and loop lengths are static (closed over by ``make_train``)."""

    total_steps: int = 1_000_000  # env steps per seed (rounded up to whole log periods)
    num_envs: int = 256  # parallel envs per seed (sharded over devices)
    unroll: int = 32  # env steps per env per update (rollout length)
    epochs: int = 4  # passes over each rollout
    minibatches: int = 8  # minibatches per epoch (num_envs * unroll must divide)
    lr: float = 3e-4  # Adam learning rate
    lr_schedule: str = "constant"  # "constant" or "linear" (linear decay to 0 over the run)
    max_grad_norm: float = 0.5  # global-norm gradient clip
    gamma: float = 0.99  # discount (the paper's)
    gae_lambda: float = 0.95  # GAE lambda
    clip_eps: float = 0.2  # PPO ratio clip
    clip_value_eps: float = 0.0  # value-loss clip range; 0 disables value clipping
    vf_coef: float = 0.5  # value-loss coefficient
    ent_coef: float = 0.0  # entropy bonus (SB3 default 0)
    reward_scale: float = 0.01  # multiplies env rewards before GAE
    normalize_advantage: bool = True  # standardise advantages per minibatch
    normalize_observations: bool = True  # running mean/std normalisation in the learner
    init_log_std: float = -0.5  # initial Gaussian log std (actions in [-1, 1])
    stagger_episodes: bool = False  # start each env at a random step of its first episode (see make_train)
    hidden_sizes: tuple[int, ...] = (256, 128)  # actor and critic hidden widths (tanh)
    num_seeds: int = 1  # independent policies trained together (vmap over seeds)
    seed: int = 0  # base seed; seed s uses fold_in(key(seed), s)
    num_periods: int = 20  # host log periods over the run
    checkpoint_every: int = 1  # checkpoint every K periods (and at the end)
    bc_coef: float = 0.0  # weight of behaviour cloning toward a teacher's action at the start; 0: off
    bc_coef_end: float = 0.0  # its weight at the end of the run (linear in the update count in between)
    pg_start: float = 0.0  # fraction of the run before the policy-gradient term turns on (BC and critic only)
    demos: str | None = None  # demonstrations (.npz) to clone with the bc_coef schedule; None: none

    def replace(self, **changes: Any) -> PPOConfig:
        """Copy with fields changed, validated."""
        return validate(dataclasses.replace(self, **changes))


_FIELDS = {f.name: f for f in dataclasses.fields(PPOConfig)}
_POSITIVE_INT = (
    "total_steps",
    "num_envs",
    "unroll",
    "epochs",
    "minibatches",
    "num_seeds",
    "num_periods",
    "checkpoint_every",
)
_POSITIVE_FLOAT = ("lr", "max_grad_norm", "clip_eps", "reward_scale")
_NONNEG_FLOAT = (
    "clip_value_eps",
    "vf_coef",
    "ent_coef",
    "bc_coef",
    "bc_coef_end",
)
#: Bounds of float settings beyond their sign: an Adam step above 1 or a log std outside these diverges.
_FLOAT_RANGES = {
    "lr": (0.0, 1.0),
    "init_log_std": (-20.0, 5.0),
    "pg_start": (0.0, 0.99),
}
#: Largest value of an integer setting (beyond it float arithmetic on the derived sizes is inexact).
MAX_INT_SETTING = 2**53
#: Most PPO epochs per update.
MAX_EPOCHS = 1000
#: Most env steps per seed (``--steps``): about two days on two CPU cores, hours on a GPU.
MAX_TOTAL_STEPS = 10_000_000_000


#: Config fields whose command-line flag has a different name.
_FLAG_NAMES = {"total_steps": "--steps", "num_seeds": "--seeds", "num_periods": "--periods"}


def flag_name(name: str) -> str:
    """The ``harv-jax train`` flag of config field ``name`` (``total_steps`` -> ``--steps``)."""
    return _FLAG_NAMES.get(name, "--" + name.replace("_", "-"))


_flag = flag_name


def validate(cfg: PPOConfig) -> PPOConfig:
    """Check every field; return ``cfg`` or raise a one-line UsageError."""
    for name in _POSITIVE_INT:
        v = getattr(cfg, name)
        if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
            raise UsageError(f"{_flag(name)} {v!r} must be a positive integer")
        if v > MAX_INT_SETTING:
            raise UsageError(
                f"{_flag(name)} {v} is too large; give a whole number in [1, {MAX_INT_SETTING:,}]"
            )
    if cfg.total_steps > MAX_TOTAL_STEPS:
        raise UsageError(
            f"--steps {cfg.total_steps:,} is past the maximum of {MAX_TOTAL_STEPS:,} env steps per seed; "
            f"give a whole number in [1, {MAX_TOTAL_STEPS:,}]"
        )
    if cfg.epochs > MAX_EPOCHS:
        raise UsageError(f"--epochs {cfg.epochs} is too large; give a whole number in [1, {MAX_EPOCHS}]")
    for name in _POSITIVE_FLOAT + _NONNEG_FLOAT + ("gamma", "gae_lambda", "init_log_std", "pg_start"):
        v = getattr(cfg, name)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise UsageError(f"{_flag(name)} {v!r} must be a finite number")
    for name in _POSITIVE_FLOAT:
        if getattr(cfg, name) <= 0:
            raise UsageError(f"{_flag(name)} {getattr(cfg, name)} must be > 0")
    for name, (lo, hi) in _FLOAT_RANGES.items():
        if not lo <= getattr(cfg, name) <= hi:
            raise UsageError(f"{_flag(name)} {getattr(cfg, name)} is outside the allowed [{lo:g}, {hi:g}]")
    for name in _NONNEG_FLOAT:
        if getattr(cfg, name) < 0:
            raise UsageError(f"{_flag(name)} {getattr(cfg, name)} must be >= 0")
    if not 0.0 < cfg.gamma <= 1.0:
        raise UsageError(f"--gamma {cfg.gamma} must be in (0, 1]")
    if not 0.0 <= cfg.gae_lambda <= 1.0:
        raise UsageError(f"--gae-lambda {cfg.gae_lambda} must be in [0, 1]")
    if cfg.lr_schedule not in LR_SCHEDULES:
        raise UsageError(f"--lr-schedule {cfg.lr_schedule!r} is not one of {', '.join(LR_SCHEDULES)}")
    if (
        not isinstance(cfg.hidden_sizes, tuple)
        or not cfg.hidden_sizes
        or any(isinstance(h, bool) or not isinstance(h, int) or h <= 0 for h in cfg.hidden_sizes)
    ):
        raise UsageError(f"hidden_sizes {cfg.hidden_sizes!r} must be a non-empty list of positive integers")
    check_network(cfg.hidden_sizes, cfg.num_seeds)
    if isinstance(cfg.seed, bool) or not isinstance(cfg.seed, int) or cfg.seed < 0:
        raise UsageError(f"--seed {cfg.seed!r} must be a non-negative integer")
    for name in ("normalize_advantage", "normalize_observations", "stagger_episodes"):
        if not isinstance(getattr(cfg, name), bool):
            raise UsageError(f"{name} {getattr(cfg, name)!r} must be true or false")
    if (cfg.num_envs * cfg.unroll) % cfg.minibatches:
        raise UsageError(
            f"--minibatches {cfg.minibatches} must divide num_envs * unroll = {cfg.num_envs * cfg.unroll}"
        )
    if cfg.demos is not None:
        if not isinstance(cfg.demos, str) or not cfg.demos.strip():
            raise UsageError(f"--demos {cfg.demos!r} must be the path of a demonstrations .npz file")
        if cfg.bc_coef <= 0 and cfg.bc_coef_end <= 0:
            raise UsageError(
                f"--demos {cfg.demos!r} is cloned with weight bc_coef, and bc_coef and bc_coef_end are 0; "
                "set bc_coef > 0 in the preset's [ppo] table"
            )
    check_seed(cfg.seed)
    check_train(
        cfg.total_steps,
        cfg.num_envs,
        cfg.unroll,
        cfg.num_seeds,
        total_updates(cfg) * cfg.epochs * cfg.minibatches,
    )
    return cfg


def check_devices(cfg: PPOConfig, num_devices: int) -> None:
    """Raise UsageError unless ``num_envs`` splits evenly over ``num_devices``."""
    if cfg.num_envs % num_devices:
        raise UsageError(f"--num-envs {cfg.num_envs} is not divisible by the {num_devices} available devices")


def from_dict(values: dict[str, Any], base: PPOConfig | None = None, source: str = "config") -> PPOConfig:
    """Build a validated config from ``base`` (default PPOConfig()) and a dict of field values."""
    if not isinstance(values, dict):
        raise UsageError(f"the PPO settings in {source} must be a table of name = value, got {values!r}")
    changes: dict[str, Any] = {}
    for k, v in values.items():
        if k not in _FIELDS:
            raise UsageError(f"unknown PPO setting {k!r} in {source}; allowed: {', '.join(_FIELDS)}")
        if k == "hidden_sizes" and isinstance(v, list):
            v = tuple(v)
        if _FIELDS[k].type in ("float",) and isinstance(v, int) and not isinstance(v, bool):
            v = float(v) if abs(v) < 2**1023 else math.inf  # an integer beyond any float is not finite
        changes[k] = v
    try:
        return validate(dataclasses.replace(base or PPOConfig(), **changes))
    except UsageError as e:
        if source in ("config", "command line"):
            raise
        raise UsageError(f"{source}: {e}") from None


def to_dict(cfg: PPOConfig) -> dict[str, Any]:
    """Plain JSON-able dict of the config (``demos`` only when set)."""
    d = dataclasses.asdict(cfg)
    d["hidden_sizes"] = list(cfg.hidden_sizes)
    if d["demos"] is None:
        del d["demos"]
    return d


#: How many ``base`` files a preset may chain (a preset naming a base that names a base ...).
MAX_BASE_DEPTH = 8


def _read_toml(path: Path | Traversable) -> dict[str, Any]:
    """The TOML document of ``path``; UsageError naming the file for unreadable or bad TOML."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise UsageError(f"preset {str(path)!r} is not UTF-8 text; expected a TOML file") from None
    except OSError as e:
        raise UsageError(f"preset {str(path)!r} cannot be read ({e.strerror or type(e).__name__})") from None
    except tomllib.TOMLDecodeError as e:
        raise UsageError(f"preset {str(path)!r} is not valid TOML: {e}") from None


def _resolve_base(path: Path | Traversable, data: dict[str, Any], chain: tuple[str, ...]) -> dict[str, Any]:
    """``data`` on top of its ``base`` file (a file name in the same folder), tables merged key by key."""
    if "base" not in data:
        return data
    base = data["base"]
    if not (isinstance(base, str) and base.endswith(".toml") and Path(base).name == base):
        raise UsageError(
            f"preset {str(path)!r}: base = {base!r}; allowed: the name of a .toml file in the same folder"
        )
    base_path = (Path(str(path)).parent / base).resolve()
    if str(base_path) in chain or len(chain) >= MAX_BASE_DEPTH:
        raise UsageError(
            f"preset {str(path)!r}: base = {base!r} makes a chain of {len(chain) + 1} files "
            f"({' -> '.join(Path(c).name for c in (*chain, str(base_path)))}); allowed: at most "
            f"{MAX_BASE_DEPTH} files, none twice"
        )
    if not base_path.is_file():
        raise UsageError(f"preset {str(path)!r}: base = {base!r} is not a file in {str(base_path.parent)!r}")
    merged = dict(_resolve_base(base_path, _read_toml(base_path), (*chain, str(base_path))))
    for key, value in data.items():
        if key == "base":
            continue
        if isinstance(value, dict) and isinstance(merged.get(key), dict):
            merged[key] = {**merged[key], **value}
        else:
            merged[key] = value
    return merged


def load_file(path: Path | Traversable, tables: tuple[str, ...] = ()) -> tuple[PPOConfig, dict[str, Any]]:
    """Read a TOML config file: its ``[ppo]`` table as a validated config, and its other tables.

    A file may name a ``base = "other.toml"`` (a file in the same folder): the file's tables are then read
    on top of the base's, key by key (``[ppo]`` ``lr`` of the file replaces the base's ``lr`` and keeps the
    base's other ``[ppo]`` keys); a base may itself name a base.

    Args:
        path: the ``.toml`` file (a path or a package-data resource).
        tables: names of the other tables the caller accepts (besides ``ppo`` and ``description``).

    Returns:
        (validated PPOConfig, dict of the other top-level entries by name).

    Raises:
        UsageError: the file or its base is not valid TOML, a base is missing or chains back, a table is not
            in ``tables``, or a ``[ppo]`` value is bad.
    """
    data = _resolve_base(path, _read_toml(path), (str(Path(str(path)).resolve()),))
    unknown = set(data) - {"ppo", "description", *tables}
    if unknown:
        allowed = ", ".join(("ppo", *tables))
        raise UsageError(f"preset {str(path)!r} has unknown tables {sorted(unknown)}; allowed: {allowed}")
    for name in ("ppo", *tables):
        if name in data and not isinstance(data[name], dict):
            raise UsageError(f"preset {str(path)!r}: {name} = {data[name]!r} must be a table ([{name}])")
    if not isinstance(data.get("description", ""), str):
        raise UsageError(f"preset {str(path)!r}: description = {data['description']!r} must be a string")
    cfg = from_dict(data.get("ppo", {}), source=f"preset {path.name}")
    return cfg, {k: v for k, v in data.items() if k != "ppo"}


# ------------------------------------------------------------------------------------------ derived values


def batch_size(cfg: PPOConfig) -> int:
    """Transitions per update per seed: num_envs * unroll."""
    return cfg.num_envs * cfg.unroll


def minibatch_size(cfg: PPOConfig) -> int:
    """Transitions per minibatch per seed."""
    return batch_size(cfg) // cfg.minibatches


def updates_per_period(cfg: PPOConfig) -> int:
    """PPO updates inside one compiled period."""
    updates = math.ceil(cfg.total_steps / batch_size(cfg))
    return max(1, math.ceil(updates / cfg.num_periods))


def num_periods(cfg: PPOConfig) -> int:
    """Host periods needed to reach ``total_steps`` with whole periods."""
    return math.ceil(cfg.total_steps / (updates_per_period(cfg) * batch_size(cfg)))


def steps_per_period(cfg: PPOConfig) -> int:
    """Env steps per seed in one period."""
    return updates_per_period(cfg) * batch_size(cfg)


def total_updates(cfg: PPOConfig) -> int:
    """PPO updates in the whole run (whole periods)."""
    return num_periods(cfg) * updates_per_period(cfg)
