"""A training preset's environment: its ``[env]``, ``[reward]``, ``[randomization]``, ``[spin]`` tables.

A preset's ``[env]`` table sets [`EnvConfig`][] (static); the other tables are stored inside the env
settings dict as nested tables (``{"episode_steps": 3000, "reward": {...}, "spin": {...}}``), so that a
checkpoint's stored env settings rebuild the same environment on resume. Every value is checked here: a bad
key or a value out of its range raises `UsageError` naming the key and what is allowed.

- ``[reward]``: any field of [`RewardParams`][] (traced: changing it does not recompile). Scalars, or
  lists of 3 (per channel alpha, beta, mu) for ``bonus_width_rad``, ``w_track``, ``track_clip_rad`` and
  of 4 for ``recovered_tol``.
- ``[randomization]``: any field of [`RandomizationParams`][] (switches and ranges; only read when
  ``domain_randomization`` is on), but the turbulence's: ``turbulence`` sets them, a named intensity
  (light, moderate, severe) or a sigma in ft/s, the largest an episode flies (each flies U(0, 1) times it);
  it turns the env's turbulence on (``EnvConfig.turbulence``: the env then observes air data) and needs
  ``domain_randomization``. ``lag_max_s``: the largest first-order actuator lag, s. The disturbances and
  their keys are the table of ``harv_jax.task.disturbance_table``.
- ``[spin]``: ``reset_prob`` (probability that an episode starts in a developed spin from the bank),
  ``bank_size``, ``spin_s_min``/``spin_s_max`` (time flown in the spin), ``bank_seed``,
  ``randomize_aircraft`` (draw the bank's aircraft with the mass/inertia/aero ranges).
- ``[eval]``: evaluation during training (read by ``harv-jax train``): ``every`` (periods), ``upset_runs``,
  ``spin_runs``, ``duration_s``.

[`check_env_settings`][] validates all of it with plain Python (no jax array is made), so a preset is
checked before anything is built.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import jax.numpy as jnp
import numpy as np

from harv_jax.dynamics.turbulence import INTENSITIES, turbulence_params
from harv_jax.env.config import (
    DEFAULT_GUST_TAU_S,
    DEFAULT_NOISE_STD_MAX,
    EnvConfig,
    EnvParams,
    RandomizationParams,
    default_params,
    strip_weak_type,
)
from harv_jax.env.reward_params import RewardParams, reward_fields
from harv_jax.errors import UsageError
from harv_jax.guards import check_seed
from harv_jax.task.disturbance_table import ADDED_NAMES, BY_NAME

#: Nested tables of the env settings and what they hold.
TABLES = ("reward", "randomization", "spin", "eval")

#: Allowed range of every ``[env]`` setting (None: a switch, true or false); a setting whose
#: [`EnvConfig`][] default is an int must be a whole number. ``h_floor_ft`` may also be ``-inf`` (no
#: ground) and must lie below ``h0_ft``.
ENV_RANGES: dict[str, tuple[float, float] | None] = {
    "dt_s": (1e-4, 0.05),
    "episode_steps": (1, 1_000_000),
    "max_delay_steps": (0, 100),
    "domain_randomization": None,
    "throttle": (0.0, 1.0),
    "h0_ft": (1.0, 65_000.0),
    "h_floor_ft": (-1e9, 65_000.0),
    "discount": (1e-6, 1.0),
}

#: Allowed range and length (None: scalar) of every reward field, as ``RewardParams`` declares them.
REWARD_RANGES: dict[str, tuple[float, float, int | None]] = {
    f.name: (*f.metadata["range"], len(d) if isinstance(d := f.metadata["default"], tuple) else None)
    for f in reward_fields()
}
#: Allowed range of the randomization ranges (switches are booleans).
RANDOMIZATION_RANGES: dict[str, tuple[float, float]] = {
    "mass_frac": (0.0, 0.5),
    "inertia_frac": (0.0, 0.5),
    "aero_damping_frac": (0.0, 0.9),
    "aero_control_frac": (0.0, 0.9),
    "aero_static_frac": (0.0, 0.9),
    "aero_basic_frac": (0.0, 0.9),
    "gust_std_max_fps": (0.0, 100.0),
    "gust_tau_min_s": (0.01, 100.0),
    "gust_tau_max_s": (0.01, 100.0),
    "delay_max_steps": (0.0, 100.0),
    "lag_max_s": (0.0, BY_NAME["lag"].max_level),
    **{BY_NAME[n].randomization[0]: (0.0, BY_NAME[n].max_level) for n in ADDED_NAMES},
}
#: The ``[randomization]`` key of each disturbance added to the table -> its name.
_ADDED_KEYS = {BY_NAME[n].randomization[0]: n for n in ADDED_NAMES}
#: ``[randomization]`` fields that no table sets directly (``turbulence`` sets them).
_TURBULENCE_FIELDS = ("turbulence_sigma_table_fps", "turbulence_wind_20ft_fps")
#: ``EnvConfig`` fields the settings derive (not ``[env]`` keys): the turbulence switch.
_DERIVED_ENV_FIELDS = ("turbulence",)


@dataclass(frozen=True)
class SpinSettings:
    """The ``[spin]`` table (static: the bank size sets a shape)."""

    reset_prob: float = 0.0  # probability that an episode starts in a developed spin
    bank_size: int = 256  # number of bank states (drawn once per run)
    spin_s_min: float = 15.0  # time flown in the spin, s: U(min, max)
    spin_s_max: float = 30.0
    bank_seed: int = 0  # PRNG seed of the bank (independent of the training seed)
    randomize_aircraft: bool = True  # bank aircraft drawn with the mass/inertia/aero ranges


@dataclass(frozen=True)
class EvalSettings:
    """The ``[eval]`` table: evaluation during training (0 runs or every = 0: off)."""

    every: int = 0  # periods between evaluations (0: never)
    upset_runs: int = 128  # reset-bound states (as ``harv-jax mc``)
    spin_runs: int = 16  # developed spins (the nominal scenario first)
    duration_s: float = 60.0  # length of each run, s


def _number(where: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise UsageError(f"{where} = {v!r} must be a finite number")
    try:
        x = float(v)
    except OverflowError:  # an integer beyond any float
        x = math.inf
    if not math.isfinite(x):
        raise UsageError(f"{where} = {v!r} must be a finite number")
    return x


def _check_range(where: str, v: Any, lo: float, hi: float) -> None:
    _number(where, v)
    if not lo <= v <= hi:
        bounds = ", ".join(str(b) if isinstance(b, int) else f"{b:g}" for b in (lo, hi))
        raise UsageError(f"{where} = {v!r} is outside the allowed range [{bounds}]")


def _dataclass_from_table(cls: type, table: dict[str, Any], name: str) -> Any:
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for k in table:
        if k not in fields:
            raise UsageError(f"unknown [{name}] setting {k!r}; allowed: {', '.join(fields)}")
    out = {}
    for k, v in table.items():
        default = fields[k].default
        where = f"{name}.{k}"
        if isinstance(default, bool):
            if not isinstance(v, bool):
                raise UsageError(f"{where} = {v!r} must be true or false")
        elif isinstance(default, int):
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise UsageError(f"{where} = {v!r} must be a non-negative integer")
        else:
            v = _number(where, v)
        out[k] = v
    return cls(**out)


def spin_settings(table: dict[str, Any] | None) -> SpinSettings:
    """Validated ``[spin]`` table."""
    s = _dataclass_from_table(SpinSettings, table or {}, "spin")
    check_seed(s.bank_seed, "spin.bank_seed")
    _check_range("spin.reset_prob", s.reset_prob, 0.0, 1.0)
    _check_range("spin.bank_size", s.bank_size, 1, 65_536)
    _check_range("spin.spin_s_min", s.spin_s_min, 1.0, 120.0)
    _check_range("spin.spin_s_max", s.spin_s_max, s.spin_s_min, 120.0)
    return s


def eval_settings(table: dict[str, Any] | None) -> EvalSettings:
    """Validated ``[eval]`` table."""
    s = _dataclass_from_table(EvalSettings, table or {}, "eval")
    _check_range("eval.upset_runs", s.upset_runs, 0, 100_000)
    _check_range("eval.spin_runs", s.spin_runs, 0, 10_000)
    _check_range("eval.duration_s", s.duration_s, 11.0, 600.0)
    if s.every and s.upset_runs + s.spin_runs == 0:
        raise UsageError("eval.every > 0 needs eval.upset_runs + eval.spin_runs >= 1")
    return s


def check_reward_table(table: dict[str, Any] | None) -> None:
    """Raise UsageError for an unknown key or a value outside `REWARD_RANGES` in a ``[reward]``
    table."""
    for k, v in (table or {}).items():
        if k not in REWARD_RANGES:
            raise UsageError(f"unknown [reward] setting {k!r}; allowed: {', '.join(REWARD_RANGES)}")
        lo, hi, n = REWARD_RANGES[k]
        if n is None:
            _check_range(f"reward.{k}", v, lo, hi)
        else:
            if not isinstance(v, list | tuple) or len(v) != n:
                raise UsageError(f"reward.{k} = {v!r} must be a list of {n} numbers")
            for i, x in enumerate(v):
                _check_range(f"reward.{k}[{i}]", x, lo, hi)


def reward_params(table: dict[str, Any] | None, base: RewardParams) -> RewardParams:
    """``base`` with the ``[reward]`` table's values (validated)."""
    check_reward_table(table)
    changes = {}
    for k, v in (table or {}).items():
        old = getattr(base, k)
        changes[k] = jnp.asarray(v, dtype=old.dtype).reshape(old.shape)
    return base.replace(**changes)


#: Defaults of the gust correlation times, for the min <= max check of a table that sets one of them.
_GUST_TAU_DEFAULTS = dict(zip(("gust_tau_min_s", "gust_tau_max_s"), DEFAULT_GUST_TAU_S, strict=True))


def check_randomization_table(table: dict[str, Any] | None) -> None:
    """Raise UsageError for an unknown key, a non-bool switch or a range outside
    `RANDOMIZATION_RANGES` of a ``[randomization]`` table."""
    skip = (*_TURBULENCE_FIELDS, "added_max")
    fields = [f.name for f in dataclasses.fields(RandomizationParams) if f.name not in skip]
    fields += ["turbulence", *_ADDED_KEYS]
    n_noise = len(DEFAULT_NOISE_STD_MAX)
    for k, v in (table or {}).items():
        if k not in fields:
            raise UsageError(f"unknown [randomization] setting {k!r}; allowed: {', '.join(fields)}")
        if k == "turbulence":
            turbulence_level(v)
        elif k.endswith("_on"):
            if not isinstance(v, bool):
                raise UsageError(f"randomization.{k} = {v!r} must be true or false")
        elif k == "noise_std_max":
            if not isinstance(v, list | tuple) or len(v) != n_noise:
                raise UsageError(f"randomization.{k} = {v!r} must be a list of {n_noise} numbers")
            for i, x in enumerate(v):
                _check_range(f"randomization.{k}[{i}]", x, 0.0, 10.0)
        else:
            lo, hi = RANDOMIZATION_RANGES[k]
            _check_range(f"randomization.{k}", v, lo, hi)
            if k == "delay_max_steps" and not float(v).is_integer():
                raise UsageError(f"randomization.{k} = {v!r} must be an integer")
    tau = {**_GUST_TAU_DEFAULTS, **{k: v for k, v in (table or {}).items() if k in _GUST_TAU_DEFAULTS}}
    if tau["gust_tau_min_s"] > tau["gust_tau_max_s"]:
        raise UsageError(
            f"randomization.gust_tau_min_s = {tau['gust_tau_min_s']:g} must be <= gust_tau_max_s "
            f"= {tau['gust_tau_max_s']:g}"
        )


def turbulence_level(value: Any) -> str | float | None:
    """A ``[randomization]`` ``turbulence`` value: an intensity name, a sigma in ft/s (a number >= 0), or
    None for ``"none"`` and 0 (still air); UsageError naming it and what is allowed otherwise."""
    top = BY_NAME["turbulence"].max_level
    if value == "none" or (isinstance(value, int | float) and not isinstance(value, bool) and value == 0):
        return None
    if isinstance(value, str) and value in INTENSITIES:
        return value
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        if 0 < value <= top:
            return float(value)
    raise UsageError(
        f"randomization.turbulence = {value!r}: allowed: none, {', '.join(INTENSITIES)}, or a sigma in ft/s "
        f"from 0 to {top:g}"
    )


def env_turbulence(nested: dict[str, dict[str, Any]]) -> bool:
    """Whether the ``[randomization]`` table turns the env's turbulence on."""
    return turbulence_level((nested.get("randomization") or {}).get("turbulence", "none")) is not None


def randomization_params(table: dict[str, Any] | None, base: RandomizationParams) -> RandomizationParams:
    """``base`` with the ``[randomization]`` table's values (validated)."""
    check_randomization_table(table)
    changes = {}
    for k, v in (table or {}).items():
        if k == "turbulence":
            level = turbulence_level(v)
            tp = turbulence_params(0.0 if level is None else level, 1.0)
            changes["turbulence_sigma_table_fps"] = tp.sigma_table_fps.astype(
                base.turbulence_sigma_table_fps.dtype
            )
            changes["turbulence_wind_20ft_fps"] = tp.wind_20ft_fps.astype(base.turbulence_wind_20ft_fps.dtype)
            continue
        if k in _ADDED_KEYS:
            added = {**base.added_max, **changes.get("added_max", {})}
            added[_ADDED_KEYS[k]] = jnp.asarray(v, dtype=base.gust_std_max_fps.dtype)
            changes["added_max"] = {n: added[n] for n in ADDED_NAMES if n in added}  # the table's order
            continue
        old = getattr(base, k)
        changes[k] = jnp.asarray(v, dtype=old.dtype).reshape(old.shape)
    out = base.replace(**changes)
    if float(out.gust_tau_min_s) > float(out.gust_tau_max_s):
        raise UsageError(
            f"randomization.gust_tau_min_s = {float(out.gust_tau_min_s):g} must be <= gust_tau_max_s "
            f"= {float(out.gust_tau_max_s):g}"
        )
    return out


def split_tables(env_table: dict[str, Any]) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
    """(EnvConfig fields, {table name: table}) of an env settings dict."""
    if not isinstance(env_table, dict):
        raise UsageError(f"[env] must be a table of settings, got {env_table!r}")
    flat = {k: v for k, v in env_table.items() if k not in TABLES}
    nested = {}
    for k in TABLES:
        v = env_table.get(k, {})
        if not isinstance(v, dict):
            raise UsageError(f"[{k}] must be a table of settings, got {v!r}")
        nested[k] = v
    return flat, nested


def env_config(flat: dict[str, Any]) -> EnvConfig:
    """Validated EnvConfig from the ``[env]`` table's fields (types and `ENV_RANGES`)."""
    fields = {f.name: f.default for f in dataclasses.fields(EnvConfig) if f.name not in _DERIVED_ENV_FIELDS}
    unknown = sorted(set(flat) - set(fields))
    if unknown:
        raise UsageError(
            f"unknown env setting {unknown[0]!r}; allowed: {', '.join(sorted(set(fields) | set(TABLES)))}"
        )
    for k, v in flat.items():
        if k not in ENV_RANGES:
            continue  # a field without a range here: EnvConfig checks it
        rng, where = ENV_RANGES[k], f"env.{k}"
        if rng is None:
            if not isinstance(v, bool):
                raise UsageError(f"{where} = {v!r} must be true or false")
            continue
        if k == "h_floor_ft" and isinstance(v, float) and v == -math.inf:
            continue  # no ground
        if isinstance(fields[k], int) and (isinstance(v, bool) or not isinstance(v, int)):
            raise UsageError(f"{where} = {v!r} must be a whole number in [{rng[0]}, {rng[1]}]")
        _check_range(where, v, *rng)
    try:
        cfg = EnvConfig(**flat)
    except (TypeError, ValueError) as e:
        raise UsageError(f"bad env setting: {e}") from None
    if not cfg.h_floor_ft < cfg.h0_ft:
        raise UsageError(f"env.h_floor_ft = {cfg.h_floor_ft!r} must be below env.h0_ft = {cfg.h0_ft!r}")
    return cfg


def check_env_settings(env_table: dict[str, Any]) -> None:
    """Validate a whole env settings dict (``[env]`` fields and nested tables) without making jax arrays.

    Raises:
        UsageError: one line naming the first bad key or value and what is allowed.
    """
    flat, nested = split_tables(env_table)
    cfg = env_config(flat)
    check_reward_table(nested["reward"])
    check_randomization_table(nested["randomization"])
    if env_turbulence(nested) and not cfg.domain_randomization:
        raise UsageError(
            f"randomization.turbulence = {nested['randomization']['turbulence']!r} needs "
            "env.domain_randomization = true"
        )
    spin_settings(nested["spin"])
    eval_settings(nested["eval"])


def env_params(config: EnvConfig, nested: dict[str, dict[str, Any]], spin_bank: Any = None) -> EnvParams:
    """EnvParams of a config and its nested tables; ``spin_bank`` (a ``SpinBank``) feeds spin resets."""
    params = default_params(config)
    params = params.replace(
        reward=reward_params(nested.get("reward"), params.reward),
        randomization=randomization_params(nested.get("randomization"), params.randomization),
    )
    spin = spin_settings(nested.get("spin"))
    dtype = params.h0_ft.dtype
    if spin_bank is not None:
        params = params.replace(
            spin_states=jnp.asarray(np.asarray(spin_bank.x_wind), dtype),
            spin_delta_rad=jnp.asarray(np.asarray(spin_bank.delta_rad), dtype),
        )
    elif spin.reset_prob > 0:
        raise ValueError("spin.reset_prob > 0 needs a spin bank")
    params = params.replace(spin_reset_prob=jnp.asarray(spin.reset_prob, dtype))
    return strip_weak_type(params)
