"""The disturbances a controller meets, declared once: `DISTURBANCES`.

Each row names a disturbance, the Monte Carlo commands' level option and its unit, the level of
``--disturbances default``, the largest level accepted, the training preset's ``[randomization]`` keys
that set the env's per-episode maximum, and what it is. The CLI options and their help, the level checks
of the Monte Carlo commands, the ranges of the new ``[randomization]`` keys and the table in the docs
(``docs/robustness.md``, checked by a test against [`markdown_table`][]) come from here.

The models are ``harv_jax.dynamics.disturbances`` (noise, delay, gust), ``harv_jax.dynamics.turbulence``
(Dryden turbulence), ``harv_jax.aircraft.randomize`` (model error) and ``AircraftParams.act_tau_s`` (lag);
``harv_jax.dynamics.disturbed_step`` flies them, in the env and in the Monte Carlo alike.

A row with a ``model`` (``harv_jax.dynamics.disturbance_model``) adds a disturbance to these: its
``--disturbances`` name and level option, its ``runs.csv`` column, its sweep in ``harv-jax robustness``, its
``[randomization]`` key (the env's per-episode maximum) and its flight in the disturbed step follow from the
row (``docs/robustness.md``, "Adding a disturbance").
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from harv_jax.dynamics.disturbance_model import DisturbanceModel, Models
from harv_jax.dynamics.disturbances import DEFAULT_DELAY_MAX_STEPS, DEFAULT_GUST_STD_MAX_FPS
from harv_jax.task.spec import DT_S


@dataclass(frozen=True)
class Disturbance:
    """One row of the table.

    Attributes:
        name: the name ``--disturbances`` takes.
        option: the level option of the Monte Carlo commands (``mc``, ``compare``, ``robustness``, ...).
        unit: the level's unit.
        default: the level of ``--disturbances default`` (turbulence: an intensity name).
        max_level: the largest level accepted.
        randomization: the ``[randomization]`` keys that set the env's per-episode maximum.
        meaning: what it is, in one sentence.
        in_default: whether ``--disturbances default`` turns it on.
        model: for a disturbance added to the built-in ones, its model (``dynamics.disturbance_model``;
            its one ``randomization`` key is the env's per-episode maximum, drawn U(0, 1) times it).
        sweep: for an added disturbance, the levels ``harv-jax robustness`` sweeps by default.
    """

    name: str
    option: str
    unit: str
    default: float | str
    max_level: float
    randomization: tuple[str, ...]
    meaning: str
    in_default: bool = True
    model: DisturbanceModel | None = None
    sweep: tuple[float, ...] = ()

    @property
    def parameter(self) -> str:
        """The option's Python parameter name (``--delay-ms`` -> ``delay_ms``)."""
        return self.option.lstrip("-").replace("-", "_")


#: The table, in the order the CLI and the reports list them.
DISTURBANCES: tuple[Disturbance, ...] = (
    Disturbance(
        "noise",
        "--noise-scale",
        "x the env's noise std",
        1.0,
        20.0,
        ("noise_on", "noise_std_max"),
        "additive white Gaussian sensor noise on V, alpha, beta, p, q, r, mu, gamma; 1 = the env's maximum "
        "(2 ft/s, 0.005 rad, 0.01 rad/s)",
    ),
    Disturbance(
        "delay",
        "--delay-ms",
        "ms",
        DEFAULT_DELAY_MAX_STEPS * DT_S * 1000.0,
        1000.0,
        ("delay_on", "delay_max_steps"),
        "the plant flies each command this late (whole plant steps)",
    ),
    Disturbance(
        "gust",
        "--gust-fps",
        "ft/s",
        DEFAULT_GUST_STD_MAX_FPS,
        100.0,
        ("gust_on", "gust_std_max_fps", "gust_tau_min_s", "gust_tau_max_s"),
        "the paper's first-order body-axis gust (turns with the aircraft), correlation time per run "
        "U(1, 10) s unless `--gust-tau-s`",
        in_default=False,
    ),
    Disturbance(
        "model",
        "--model-error",
        "x the randomization ranges",
        1.0,
        4.0,
        (
            "mass_frac",
            "inertia_frac",
            "aero_damping_frac",
            "aero_control_frac",
            "aero_static_frac",
            "aero_basic_frac",
        ),
        "the plant aircraft drawn with this multiple of the ranges; the controllers built on the nominal one",
    ),
    Disturbance(
        "lag",
        "--actuator-lag-s",
        "s",
        0.03,
        1.0,
        ("lag_max_s",),
        "a first-order lag of the surfaces (the controllers' model has none)",
    ),
    Disturbance(
        "turbulence",
        "--turbulence",
        "light, moderate, severe or ft/s",
        "moderate",
        100.0,
        ("turbulence",),
        "Dryden turbulence of MIL-F-8785C (u, v, w, p), sigma and scale length by altitude",
    ),
)

#: The rows by name.
BY_NAME: dict[str, Disturbance] = {d.name: d for d in DISTURBANCES}


def _added_names() -> tuple[str, ...]:
    """The rows with a model, in the table's order; ValueError for one without its one
    ``[randomization]`` key or its sweep levels."""
    added = [d for d in DISTURBANCES if d.model is not None]
    for d in added:
        if len(d.randomization) != 1 or not d.sweep:
            raise ValueError(f"disturbance {d.name!r}: a model needs one [randomization] key, sweep levels")
    return tuple(d.name for d in added)


#: The disturbances added to the built-in ones (a row with a model), in the table's order.
ADDED_NAMES: tuple[str, ...] = _added_names()


def added_models(names: Iterable[str]) -> Models:
    """The models of the added disturbances among ``names``, in the table's order."""
    wanted = set(names)
    return tuple((n, BY_NAME[n].model) for n in ADDED_NAMES if n in wanted)


#: The disturbances with a numeric level option (all but the turbulence, which also takes a name).
LEVEL_NAMES: tuple[str, ...] = tuple(d.name for d in DISTURBANCES if d.name != "turbulence")


def markdown_table() -> str:
    """The table as the docs show it (Markdown)."""
    lines = [
        "| disturbance | option | unit | level | max | in `default` | `[randomization]` keys | meaning |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for d in DISTURBANCES:
        default = d.default if isinstance(d.default, str) else f"{d.default:g}"
        keys = ", ".join(f"`{k}`" for k in d.randomization)
        lines.append(
            f"| {d.name} | `{d.option}` | {d.unit} | {default} | {d.max_level:g} | "
            f"{'yes' if d.in_default else 'no'} | {keys} | {d.meaning} |"
        )
    return "\n".join(lines)
