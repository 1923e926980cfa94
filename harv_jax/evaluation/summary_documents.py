"""The top level of each summary document the commands write: its settings, and the compare table's columns.

``mc_summary`` (``summary.json`` of ``harv-jax mc``), ``envelope_summary`` (``envelope.json`` of ``harv-jax
envelope``), ``flight_settings`` and ``flight_summary`` (``metrics.json`` of ``harv-jax fly``, whose settings
the report shows in the order of ``FLY_SETTING_KEYS``), ``COMPARE_COLUMNS`` (``harv-jax compare``). The
per-controller blocks and the report's tables are in ``harv_jax.evaluation.summary``, which re-exports these.
"""

from __future__ import annotations

from typing import Any

from harv_jax.control.registry import uses_option
from harv_jax.policies import DEFAULT_POLICY_SPEC


def controllers_setting(names: list[str], policy: str | None, zeta: str) -> dict[str, Any]:
    """``policy`` and ``zeta_schedule`` of a summary: recorded only when a controller reads them."""

    return {
        "policy": (policy or DEFAULT_POLICY_SPEC) if uses_option(names, "policy") else None,
        "zeta_schedule": zeta if uses_option(names, "zeta") else None,
    }


def mc_summary(
    names: list[str],
    policy: str | None,
    zeta: str,
    runs: int,
    target_alpha_rad: float,
    duration_s: float,
    seed: int,
    randomize: bool,
    dt_s: float,
    h0_ft: float,
    devices: list[str],
    command: str,
) -> dict[str, Any]:
    """The settings of a ``summary.json`` (``"controllers"``: empty, one block per controller to add)."""
    return {
        "runs": runs,
        "target_alpha_rad": target_alpha_rad,
        "duration_s": duration_s,
        "seed": seed,
        "randomize": randomize,
        "dt_s": dt_s,
        "h0_ft": h0_ft,
        **controllers_setting(names, policy, zeta),
        "devices": devices,
        "command": command,
        "controllers": {},
    }


def envelope_summary(
    names: list[str],
    policy: str | None,
    zeta: str,
    grid: dict[str, Any],
    runs_per_controller: int,
    target_alpha_rad: float,
    duration_s: float,
    dt_s: float,
    seed: int,
    devices: list[str],
    command: str,
) -> dict[str, Any]:
    """The settings of an ``envelope.json`` (``"controllers"``: empty, one block per controller to add)."""
    setting = controllers_setting(names, policy, zeta)
    return {
        "grid": grid,
        "runs_per_controller": runs_per_controller,
        "target_alpha_rad": target_alpha_rad,
        "reference_rad": [target_alpha_rad, 0.0, 0.0],
        "duration_s": duration_s,
        "dt_s": dt_s,
        "seed": seed,
        "aircraft": "nominal",
        "devices": devices,
        "policy": setting["policy"],
        "zeta_schedule": setting["zeta_schedule"],
        "command": command,
        "controllers": {},
    }


def flight_settings(
    controller: str,
    policy: str | None,
    zeta: str,
    switching: str,
    scenario: str,
    seed: int,
    duration_s: float,
    dt_s: float,
    target_alpha_rad: float,
    spin_s: float,
) -> dict[str, Any]:
    """The settings block of a fly ``metrics.json``."""
    setting = controllers_setting([controller], policy, zeta)
    return {
        "controller": controller,
        "policy": setting["policy"],
        "zeta_schedule": setting["zeta_schedule"],
        "switching": switching,
        "scenario": scenario,
        "seed": seed,
        "duration_s": duration_s,
        "dt_s": dt_s,
        "reference_rad": [target_alpha_rad, 0.0, 0.0],
        "spin_s": spin_s if scenario == "spin" else None,
    }


def flight_summary(
    settings: dict[str, Any],
    t_engage_s: float,
    initial_state: dict[str, float],
    spin_check: dict | None,
    metrics: dict[str, Any],
    certificate: dict | None,
) -> dict[str, Any]:
    """A fly ``metrics.json``: the settings, then the run's engagement time, state, spin check and metrics."""
    return {
        **settings,
        "t_engage_s": t_engage_s,
        "initial_state": initial_state,
        "spin_check": spin_check,
        "metrics": metrics,
        "certificate": certificate,
    }


#: Settings of a fly metrics.json shown by the report (in this order).
FLY_SETTING_KEYS = (
    "controller",
    "aircraft",
    "scenario",
    "switching",
    "seed",
    "duration_s",
    "dt_s",
    "reference_rad",
    "spin_s",
    "t_engage_s",
)

#: Columns of the compare metrics table (compare_metrics.csv/.md and compare.json's rows).
COMPARE_COLUMNS = (
    "scenario",
    "controller",
    "outcome",
    "recovery_time_s",
    "alpha_overshoot_deg",
    "omega_settling_time_s",
    "altitude_loss_ft",
    "control_tv_rad",
    "chatter_index_rad2",
    "constraint_violations",
    "rate_saturation_fraction",
    "zeta_active_fraction",
    "supervisor_fallbacks",
    "recovery_time_nr_at_run_s",
    "recovery_time_vs_smc",
)
