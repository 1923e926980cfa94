"""Robustness margins (``harv-jax robustness``): every controller over levels of each disturbance.

For each disturbance of ``harv_jax.evaluation.montecarlo.disturbances`` and each of its levels, one Monte
Carlo of the same sampled runs (same seed: the same initial states; the same noise sequence, gust and aircraft
for every controller of a run), the others off. All levels of all disturbances fly one closed loop per
controller (zero levels act as none), so each controller's rollout compiles once.

The margin of a controller for a disturbance is the largest level of the sweep at which it, and every
smaller level of the sweep, recovers at least ``MARGIN_RECOVERY`` of the runs (None: not even the
lowest level; the levels are the sweep's, so the margin is a lower bound resolved to the sweep's step).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from harv_jax.aircraft.registry import resolve_aircraft
from harv_jax.control.base import Controller
from harv_jax.errors import UsageError
from harv_jax.evaluation.montecarlo.disturbances import (
    DISTURBANCE_NAMES,
    LEVEL_OPTIONS,
    MAX_LEVELS,
    MAX_TURBULENCE_FPS,
    DisturbanceSpec,
    parse_turbulence,
)
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs, with_full_structure
from harv_jax.evaluation.summary import summarize_controller
from harv_jax.task.disturbance_table import ADDED_NAMES, BY_NAME
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S

if TYPE_CHECKING:
    from harv_jax.aircraft.params import AircraftParams

#: Default sweep: levels per disturbance (units of its level option).
SWEEP_LEVELS: dict[str, tuple[float, ...]] = {
    "noise": (0.0, 1.0, 2.0, 3.0, 5.0),
    "delay": (0.0, 50.0, 100.0, 150.0, 200.0),
    "gust": (0.0, 2.5, 5.0, 10.0, 20.0, 30.0),
    "model": (0.0, 0.5, 1.0, 1.5, 2.0),
    "lag": (0.0, 0.03, 0.06, 0.1, 0.2),
    "turbulence": (0.0, 2.5, 5.0, 7.5, 10.0, 15.0, 20.0),
    **{name: BY_NAME[name].sweep for name in ADDED_NAMES},
}
#: What a sweep can vary: the disturbances and the Dryden turbulence's sigma (ft/s at every altitude above
#: 2000 ft; 0: still air, scored by the still-air criterion, any other level by the criterion in turbulence).
SWEEP_NAMES = (*DISTURBANCE_NAMES, "turbulence")
#: Option and unit of each swept name.
SWEEP_OPTIONS: dict[str, tuple[str, str]] = {**LEVEL_OPTIONS, "turbulence": ("--turbulence", "ft/s")}
_MAX_SWEEP = {**MAX_LEVELS, "turbulence": MAX_TURBULENCE_FPS}
#: Recovered fraction a level must reach to count inside the margin.
MARGIN_RECOVERY = 0.99
_FIELD = {
    "noise": "noise_scale",
    "delay": "delay_ms",
    "gust": "gust_fps",
    "model": "model_error",
    "lag": "actuator_lag_s",
}


def parse_levels(name: str, text: str) -> tuple[float, ...]:
    """Levels of one disturbance from a comma list (UsageError naming a bad one)."""
    unit = SWEEP_OPTIONS[name][1]
    out = []
    for part in str(text).split(","):
        try:
            v = float(part)
        except ValueError:
            raise UsageError(f"--{name}-levels: {part.strip()!r} is not a number ({unit})") from None
        if not (np.isfinite(v) and 0 <= v <= _MAX_SWEEP[name]):
            raise UsageError(
                f"--{name}-levels: {part.strip()!r}; allowed: numbers from 0 to {_MAX_SWEEP[name]:g} ({unit})"
            )
        out.append(v)
    if len(set(out)) < len(out):
        raise UsageError(f"--{name}-levels {text!r}: a level is named twice")
    return tuple(sorted(out))


def margin(levels: Sequence[float], recovery: Sequence[float], bar: float = MARGIN_RECOVERY) -> float | None:
    """The largest level up to which every level of the sweep recovers >= ``bar`` (None: not the first)."""
    best = None
    for level, rate in sorted(zip(levels, recovery, strict=True)):
        if rate is None or rate < bar:
            break
        best = level
    return best


def _row(s: dict[str, Any]) -> dict[str, Any]:
    return {
        "recovery_rate": s["recovery_rate"],
        "t_recover_mean_nr_at_run_s": s["t_recover_mean_nr_at_run_s"],
        "recovery_time_p50_s": s["recovery_time_s"]["p50"],
        "control_tv_mean_rad": s["control_tv"]["mean"],
        "chatter_index_mean_rad2": s["chatter_index"]["mean"],
        "outcomes": s["outcomes"],
    }


def robustness_sweep(
    controllers: Mapping[str, Controller],
    runs: int,
    seed: int,
    levels: Mapping[str, Sequence[float]] | None = None,
    target_alpha_rad: float = ALPHA_TARGET_RAD,
    duration_s: float = 60.0,
    chunk: int | None = None,
    progress: Callable[[str], None] | None = None,
    aircraft: str | AircraftParams | None = None,
    turbulence: str = "none",
) -> dict[str, Any]:
    """Fly every controller at every level of every disturbance of ``levels`` (default ``SWEEP_LEVELS``).

    Args:
        controllers: name -> Controller (built once; each compiles once for the whole sweep).
        runs: Monte Carlo runs per level.
        seed: Monte Carlo seed (the same runs at every level).
        levels: disturbance name -> levels (units of its level option).
        target_alpha_rad: alpha_d, rad.
        duration_s: run length, s.
        chunk: runs per compiled call (``run_mc``).
        progress: called with one line per level.
        aircraft: the nominal aircraft, a name of ``harv_jax.aircraft.registry`` or ``AircraftParams``
            (None: the registry's default); recorded by name.
        turbulence: Dryden turbulence every level of the other disturbances flies in (``--turbulence``;
            ``none``: still air).

    Returns:
        The robustness.json document: per disturbance its levels, per controller a row per level
        (recovery rate, mean recovery time with not-recovered runs at the run length, median, TV, chatter
        index, outcomes) and its margin.
    """
    import jax
    import jax.numpy as jnp

    say = progress or (lambda _msg: None)
    levels = dict(SWEEP_LEVELS if levels is None else levels)
    unknown = [n for n in levels if n not in SWEEP_NAMES]
    if unknown:
        raise ValueError(f"unknown disturbances {unknown}; allowed: {', '.join(SWEEP_NAMES)}")
    turbulence = parse_turbulence(turbulence)
    record_every = 100
    n_steps = int(round(duration_s / DT_S))
    n_steps -= n_steps % record_every
    run_s = n_steps * DT_S
    max_delay = max([DisturbanceSpec(delay_ms=v).delay_steps for v in levels.get("delay", (0.0,))] + [0])
    aircraft_name, nominal = resolve_aircraft(aircraft)
    reference = jnp.array([target_alpha_rad, 0.0, 0.0])
    cache: dict = {}
    doc: dict[str, Any] = {
        "runs": runs,
        "seed": seed,
        "duration_s": run_s,
        "target_alpha_rad": target_alpha_rad,
        "margin_recovery": MARGIN_RECOVERY,
        "controllers": list(controllers),
        "disturbances": {},
        "turbulence": turbulence,
        "devices": [str(d) for d in jax.local_devices()],
        "aircraft": aircraft_name,
    }
    for name, lv in levels.items():
        rows: dict[str, list[dict[str, Any]]] = {c: [] for c in controllers}
        for level in lv:
            if name == "turbulence":
                spec = DisturbanceSpec(turbulence=parse_turbulence(f"{float(level):g}"))
            elif name in ADDED_NAMES:
                spec = DisturbanceSpec(added=((name, float(level)),), turbulence=turbulence)
            else:
                spec = DisturbanceSpec(**{_FIELD[name]: float(level)}, turbulence=turbulence)
            inputs = sample_mc_inputs(jax.random.key(seed), runs, nominal, disturbances=spec)
            inputs = with_full_structure(inputs, max_delay)
            line = []
            for cname, ctrl in controllers.items():
                out, wall = run_mc(ctrl, inputs, reference, n_steps, DT_S, record_every, chunk, cache)
                row = _row(summarize_controller(out, wall, n_steps, run_s))
                rows[cname].append({"level": float(level), **row})
                line.append(f"{cname} {100 * row['recovery_rate']:.1f}% TV {row['control_tv_mean_rad']:.1f}")
            say(f"[robustness] {name} {level:g} {SWEEP_OPTIONS[name][1]}: " + ", ".join(line))
        doc["disturbances"][name] = {
            "option": SWEEP_OPTIONS[name][0],
            "unit": SWEEP_OPTIONS[name][1],
            "levels": [float(v) for v in lv],
            "controllers": {
                c: {"rows": r, "margin": margin([x["level"] for x in r], [x["recovery_rate"] for x in r])}
                for c, r in rows.items()
            },
        }
    return doc


def margins_table(doc: dict[str, Any]) -> list[str]:
    """Markdown lines: each controller's margin per disturbance."""
    names = list(doc["disturbances"])
    head = (
        "| controller | " + " | ".join(f"{n} margin ({doc['disturbances'][n]['unit']})" for n in names) + " |"
    )
    lines = [head, "|---" * (len(names) + 1) + "|"]
    for c in doc["controllers"]:
        cells = []
        for n in names:
            m = doc["disturbances"][n]["controllers"][c]["margin"]
            cells.append("< lowest" if m is None else f"{m:g}")
        lines.append(f"| {c} | " + " | ".join(cells) + " |")
    return lines


def levels_from_options(
    options: Mapping[str, str | None], only: Sequence[str] | None = None
) -> dict[str, tuple[float, ...]]:
    """The sweep's levels: the default ones, replaced where a ``--<name>-levels`` list is given, limited to
    ``only`` (default: every disturbance)."""
    names = list(only) if only else list(SWEEP_NAMES)
    return {n: parse_levels(n, options[n]) if options.get(n) else SWEEP_LEVELS[n] for n in names}
