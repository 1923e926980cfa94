"""A run's environment settings as one validated, frozen object: [`EnvSettings`][].

The tables and their checks are [`harv_jax.env.settings`][]; this is what a training run's spec holds.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from harv_jax.env.config import EnvConfig, EnvParams
from harv_jax.env.settings import (
    TABLES,
    EvalSettings,
    SpinSettings,
    check_env_settings,
    env_config,
    env_params,
    env_turbulence,
    eval_settings,
    spin_settings,
    split_tables,
)
from harv_jax.env.spin_table import bank_provenance, build_spin_bank


def _frozen(v: Any) -> Any:
    """Lists (also nested) as tuples, so that a settings value cannot change after it was checked."""
    return tuple(_frozen(x) for x in v) if isinstance(v, list | tuple) else v


def _thawed(v: Any) -> Any:
    """Tuples as lists (the TOML/JSON form)."""
    return [_thawed(x) for x in v] if isinstance(v, tuple) else v


Pairs = tuple[tuple[str, Any], ...]


@dataclass(frozen=True)
class EnvSettings:
    """A run's environment settings, validated once: the ``[env]`` fields and the ``[reward]``,
    ``[randomization]``, ``[spin]`` and ``[eval]`` tables, each as the (key, value) pairs that were set, in
    their order (so that [`table`][harv_jax.env.env_settings.EnvSettings.table] gives back what was read).
    Build it with [`from_table`][harv_jax.env.env_settings.EnvSettings.from_table]."""

    fields: Pairs = ()
    reward: Pairs = ()
    randomization: Pairs = ()
    spin_table: Pairs = ()
    eval_table: Pairs = ()

    @classmethod
    def from_table(cls, table: dict[str, Any]) -> EnvSettings:
        """Validated settings of an env settings dict (``[env]`` fields with the nested tables inside).

        Raises:
            UsageError: one line naming the first bad key or value and what is allowed.
        """
        check_env_settings(table)
        flat, nested = split_tables(table)

        def pairs(d: dict[str, Any]) -> Pairs:
            return tuple((k, _frozen(v)) for k, v in d.items())

        return cls(
            pairs(flat),
            pairs(nested["reward"]),
            pairs(nested["randomization"]),
            pairs(nested["spin"]),
            pairs(nested["eval"]),
        )

    def table(self) -> dict[str, Any]:
        """The settings as a dict: the ``[env]`` fields, then each nested table that has a setting."""
        out: dict[str, Any] = {k: _thawed(v) for k, v in self.fields}
        for name, pairs in zip(
            TABLES, (self.reward, self.randomization, self.spin_table, self.eval_table), strict=True
        ):
            if pairs:
                out[name] = {k: _thawed(v) for k, v in pairs}
        return out

    def _nested(self) -> dict[str, dict[str, Any]]:
        return split_tables(self.table())[1]

    @property
    def config(self) -> EnvConfig:
        """The static [`EnvConfig`][harv_jax.env.config.EnvConfig] (its turbulence switch from the
        ``[randomization]`` table)."""
        return dataclasses.replace(env_config(dict(self.fields)), turbulence=env_turbulence(self._nested()))

    @property
    def spin(self) -> SpinSettings:
        """The ``[spin]`` settings."""
        return spin_settings(dict(self.spin_table))

    @property
    def eval(self) -> EvalSettings:
        """The ``[eval]`` settings."""
        return eval_settings(dict(self.eval_table))

    def spin_bank(self) -> Any:
        """The spin bank of the ``[spin]`` table, or None when spin resets are off."""
        return build_spin_bank(self.config, self._nested())

    def params(self, spin_bank: Any = None) -> EnvParams:
        """The traced EnvParams; ``spin_bank`` feeds spin resets."""
        return env_params(self.config, self._nested(), spin_bank)

    def provenance(self) -> dict[str, Any]:
        """What the spin bank was made from (``bank_provenance``)."""
        return bank_provenance(self.config, self._nested())
