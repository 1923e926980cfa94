"""The spin bank a preset's ``[spin]`` table asks for, and what it was made from."""

from __future__ import annotations

import dataclasses
from typing import Any

import jax

from harv_jax.env.config import EnvConfig, default_params, default_randomization_params
from harv_jax.env.settings import randomization_params, spin_settings
from harv_jax.task.spin_bank import SpinBank, make_spin_bank


def build_spin_bank(config: EnvConfig, nested: dict[str, dict[str, Any]]) -> SpinBank | None:
    """The spin bank of the ``[spin]`` table, or None when spin resets are off."""
    spin = spin_settings(nested.get("spin"))
    if spin.reset_prob <= 0:
        return None
    base = default_params(config)
    rand = randomization_params(nested.get("randomization"), default_randomization_params(True))
    if not spin.randomize_aircraft:
        rand = default_randomization_params(False)
    return make_spin_bank(
        jax.random.key(spin.bank_seed),
        spin.bank_size,
        base.aircraft,
        rand,
        spin.spin_s_min,
        spin.spin_s_max,
        config.dt_s,
        config.h0_ft,
    )


def bank_provenance(config: EnvConfig, nested: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """What a stored spin bank was made from (for its npz): the ``[spin]`` settings, the nominal aircraft's
    name (``harv_jax.aircraft.registry``), the step, the start altitude and the ``[randomization]`` table."""
    spin = spin_settings(nested.get("spin"))
    return {
        "spin": dataclasses.asdict(spin),
        "aircraft": config.aircraft,
        "dt_s": config.dt_s,
        "h0_ft": config.h0_ft,
        "randomization": nested.get("randomization", {}),
        "made_by": "harv_jax.task.spin_bank.make_spin_bank",
    }
