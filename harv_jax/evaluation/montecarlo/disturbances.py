"""Which disturbances a Monte Carlo flies, at which levels (``--disturbances`` and its level options).

The names, options, units, default and largest levels are the declared table
(``harv_jax.task.disturbance_table``):

- ``noise``, ``--noise-scale X`` (default 1): sensor noise, std X times the env's per-channel maximum;
- ``delay``, ``--delay-ms D`` (20): the plant flies each command D ms late (rounded to plant steps);
- ``gust``, ``--gust-fps G`` (10), ``--gust-tau-s``: body-axis Dryden-type gust of std G ft/s,
  correlation time per run U(1, 10) s unless given;
- ``model``, ``--model-error X`` (1): the plant aircraft drawn with X times the randomization ranges,
  the controllers built on the nominal one (``--controller-knows-aircraft``: on the plant's);
- ``lag``, ``--actuator-lag-s T`` (0.03): a first-order surface lag T on the plant (the controllers'
  model has none).

``--turbulence LEVEL``, given by itself: Dryden turbulence (``harv_jax.dynamics.turbulence``) of a named
intensity (light, moderate, severe: MIL-F-8785C's probabilities of exceedance 1e-2, 1e-3, 1e-5) or of a
sigma in ft/s, on top of the others; ``none`` (the default) is off.

``default`` is what a fielded controller meets: noise, delay, model error and lag at these levels (noise and
delay at the training env's maxima) and moderate turbulence (`DEFAULT_TURBULENCE`; ``--turbulence`` sets
another level, ``--turbulence none`` none); the body-axis gust is not part of it (name ``gust`` to fly it).
``none`` (the default) is the undisturbed Monte Carlo, bit for bit. Levels are fixed per run (the env draws
each episode's levels between 0 and its maxima; a robustness figure states one level). The noise and gust
models and their draws are the env's (``harv_jax.dynamics.disturbances``); every controller of one run
meets the same noise sequence, gust and aircraft (common random numbers).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

from harv_jax.dynamics.disturbances import DEFAULT_GUST_TAU_S
from harv_jax.dynamics.turbulence import INTENSITIES
from harv_jax.errors import UsageError
from harv_jax.task.disturbance_table import ADDED_NAMES, BY_NAME, LEVEL_NAMES
from harv_jax.task.spec import DT_S

#: Disturbance names with a numeric level, in the table's order.
DISTURBANCE_NAMES = LEVEL_NAMES
#: The disturbances ``--disturbances default`` turns on (with `DEFAULT_TURBULENCE`).
DEFAULT_DISTURBANCES = tuple(n for n in LEVEL_NAMES if BY_NAME[n].in_default)
#: The turbulence of ``--disturbances default`` when ``--turbulence`` is not given.
DEFAULT_TURBULENCE = str(BY_NAME["turbulence"].default)
#: Default level of each disturbance (the unit of its level option).
DEFAULT_LEVELS: dict[str, float] = {n: float(BY_NAME[n].default) for n in LEVEL_NAMES}
#: Level option of each disturbance (as the CLI spells it) and its unit.
LEVEL_OPTIONS: dict[str, tuple[str, str]] = {n: (BY_NAME[n].option, BY_NAME[n].unit) for n in LEVEL_NAMES}
#: Largest accepted level per disturbance (the delay: the command FIFO's size).
MAX_LEVELS: dict[str, float] = {n: BY_NAME[n].max_level for n in LEVEL_NAMES}
#: Largest turbulence sigma, ft/s (MIL-F-8785C's chart ends at 31 ft/s).
MAX_TURBULENCE_FPS = BY_NAME["turbulence"].max_level


def parse_turbulence(text: str | None) -> str:
    """``--turbulence``: ``none``, an intensity name or a sigma in ft/s (as text, normalized: ``6.5``);
    UsageError naming the value and what is allowed."""
    if text is None or str(text).strip() == "none":
        return "none"
    t = str(text).strip()
    if t in INTENSITIES:
        return t
    try:
        sigma = float(t)
    except ValueError:
        sigma = math.nan
    if not (math.isfinite(sigma) and 0 <= sigma <= MAX_TURBULENCE_FPS):
        raise UsageError(
            f"--turbulence {text!r}: allowed: none, {', '.join(INTENSITIES)}, or a sigma in ft/s from 0 to "
            f"{MAX_TURBULENCE_FPS:g}"
        )
    return "none" if sigma == 0 else f"{sigma:g}"  # sigma 0 is still air: the undisturbed loop, bit for bit


@dataclasses.dataclass(frozen=True)
class DisturbanceSpec:
    """Disturbance levels of a Monte Carlo (all zero: none).

    Attributes:
        noise_scale: sensor-noise std in units of the env's per-channel maximum
            (``dynamics.disturbances.DEFAULT_NOISE_STD_MAX``).
        delay_ms: command delay, ms (flown as ``delay_steps`` plant steps).
        gust_fps: stationary gust std per body axis, ft/s.
        gust_tau_s: gust correlation time, s; None: drawn per run U(1, 10) s as in the env.
        model_error: plant aircraft drawn with this multiple of the randomization ranges.
        actuator_lag_s: first-order actuator lag of the plant, s.
        controller_knows_aircraft: build the model-based controllers on the plant's own (randomized)
            aircraft instead of the nominal one.
        turbulence: Dryden turbulence: ``none``, an intensity name or a sigma in ft/s (``parse_turbulence``).
        added: (name, level) of each disturbance added to the table that is on
            (``dynamics.disturbance_model``).
    """

    noise_scale: float = 0.0
    delay_ms: float = 0.0
    gust_fps: float = 0.0
    gust_tau_s: float | None = None
    model_error: float = 0.0
    actuator_lag_s: float = 0.0
    controller_knows_aircraft: bool = False
    turbulence: str = "none"
    added: tuple[tuple[str, float], ...] = ()

    @property
    def levels(self) -> dict[str, float]:
        """Level of each disturbance by name (0: off)."""
        return {
            "noise": self.noise_scale,
            "delay": self.delay_ms,
            "gust": self.gust_fps,
            "model": self.model_error,
            "lag": self.actuator_lag_s,
            **dict(self.added),
        }

    @property
    def active(self) -> tuple[str, ...]:
        """Names of the disturbances that are on (``turbulence`` last, when on)."""
        on = tuple(n for n, v in self.levels.items() if v > 0)
        return on + (("turbulence",) if self.turbulence != "none" else ())

    @property
    def delay_steps(self) -> int:
        """The delay in plant steps (rounded)."""
        return int(round(self.delay_ms / (1000.0 * DT_S)))

    @property
    def in_loop(self) -> bool:
        """Whether noise, delay, gust, turbulence or an added disturbance act in the loop (model error and lag
        change only the aircraft)."""
        return (
            self.noise_scale > 0
            or self.delay_steps > 0
            or self.gust_fps > 0
            or self.turbulence != "none"
            or any(level > 0 for _, level in self.added)
        )

    def as_dict(self) -> dict[str, Any]:
        """The spec as summary.json records it."""
        return {
            "active": list(self.active),
            **{f"{name}_level": level for name, level in self.levels.items()},
            "delay_steps": self.delay_steps,
            "gust_tau_s": self.gust_tau_s if self.gust_tau_s is not None else list(DEFAULT_GUST_TAU_S),
            "controller_knows_aircraft": self.controller_knows_aircraft,
            "turbulence": self.turbulence,
            "units": {name: unit for name, (_, unit) in LEVEL_OPTIONS.items()},
        }


def _check_level(name: str, value: float) -> float:
    option, unit = LEVEL_OPTIONS[name]
    if not (isinstance(value, int | float) and math.isfinite(value) and 0 <= value <= MAX_LEVELS[name]):
        raise UsageError(f"{option} {value!r}: allowed: a number from 0 to {MAX_LEVELS[name]:g} ({unit})")
    return float(value)


def parse_disturbances(
    names: str = "none",
    levels: dict[str, float | None] | None = None,
    gust_tau_s: float | None = None,
    randomize: bool = False,
    controller_knows_aircraft: bool = False,
    turbulence: str | None = None,
) -> DisturbanceSpec:
    """The spec of a comma list of disturbance names and their level options.

    Args:
        names: comma list of ``DISTURBANCE_NAMES``, or ``default`` (all), or ``none``.
        levels: name -> level given on the command line (None or absent: the default level). A level for
            a disturbance that is off is an error.
        gust_tau_s: fixed gust correlation time, s (None: per run U(1, 10) s); only with ``gust``.
        randomize: the ``--randomize`` flag: ``model`` at its level (1 unless given).
        controller_knows_aircraft: build the controllers on the plant's aircraft (only with a randomized
            aircraft).
        turbulence: ``--turbulence`` (None: none).

    Raises:
        UsageError: an unknown name, ``none``/``default`` mixed with names, a bad or unused level.
    """
    given = {k: v for k, v in (levels or {}).items() if v is not None}
    unknown = [k for k in given if k not in DISTURBANCE_NAMES]
    if unknown:
        raise ValueError(f"levels of unknown disturbances {unknown}; allowed: {', '.join(DISTURBANCE_NAMES)}")
    parts = [p.strip() for p in str(names).split(",") if p.strip()]
    allowed = f"a comma list of {', '.join(DISTURBANCE_NAMES)}, or default, or none"
    if not parts:
        raise UsageError(f"--disturbances {names!r}: allowed: {allowed}")
    bad = [p for p in parts if p not in DISTURBANCE_NAMES + ("default", "none")]
    if bad:
        raise UsageError(f"--disturbances: unknown disturbance {bad[0]!r}; allowed: {allowed}")
    if len(parts) > 1 and ({"default", "none"} & set(parts)):
        raise UsageError(f"--disturbances {names!r}: default and none stand alone; allowed: {allowed}")
    if len(set(parts)) < len(parts):
        raise UsageError(f"--disturbances {names!r}: a disturbance is named twice; allowed: {allowed}")
    on = set(DEFAULT_DISTURBANCES) if parts == ["default"] else set() if parts == ["none"] else set(parts)
    if parts == ["default"] and turbulence is None:
        turbulence = DEFAULT_TURBULENCE
    if randomize:
        on.add("model")
    for name, value in given.items():
        if name not in on:
            option = LEVEL_OPTIONS[name][0]
            raise UsageError(f"{option} {value!r} given but {name} is off; name it in --disturbances")
    if gust_tau_s is not None:
        if "gust" not in on:
            raise UsageError(f"--gust-tau-s {gust_tau_s!r} given but gust is off; name it in --disturbances")
        if not (
            isinstance(gust_tau_s, int | float) and math.isfinite(gust_tau_s) and 0.01 <= gust_tau_s <= 1000
        ):
            raise UsageError(f"--gust-tau-s {gust_tau_s!r}: allowed: a number from 0.01 to 1000 (s)")
    if controller_knows_aircraft and "model" not in on:
        raise UsageError(
            "--controller-knows-aircraft needs a randomized aircraft: --randomize or model in --disturbances"
        )
    lv = {n: _check_level(n, given.get(n, DEFAULT_LEVELS[n])) if n in on else 0.0 for n in DISTURBANCE_NAMES}
    return DisturbanceSpec(
        noise_scale=lv["noise"],
        delay_ms=lv["delay"],
        gust_fps=lv["gust"],
        gust_tau_s=float(gust_tau_s) if gust_tau_s is not None else None,
        model_error=lv["model"],
        actuator_lag_s=lv["lag"],
        controller_knows_aircraft=controller_knows_aircraft,
        turbulence=parse_turbulence(turbulence),
        added=tuple((n, lv[n]) for n in ADDED_NAMES if n in on),
    )


def describe_disturbances(spec: DisturbanceSpec) -> str:
    """One line: each active disturbance with its level and unit ("none" if none)."""
    if not spec.active:
        return "none"
    parts = [f"{name} {level:g} {LEVEL_OPTIONS[name][1]}" for name, level in spec.levels.items() if level > 0]
    if spec.turbulence != "none":
        parts.append(f"turbulence {spec.turbulence}")
    if spec.model_error > 0:
        parts.append(
            "controllers on the "
            + ("plant's aircraft" if spec.controller_knows_aircraft else "nominal aircraft")
        )
    return ", ".join(parts)
