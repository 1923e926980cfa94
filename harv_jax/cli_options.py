"""Command-line options and validators shared by several commands (one definition, one help text).

Validators raise `UsageError` with one line naming the value and what is allowed;
resource guards (memory, seeds) are in ``harv_jax.guards``.
"""

from __future__ import annotations

import functools
import inspect
import math
import shlex
import sys
from collections.abc import Callable, Sequence
from typing import Any

import typer

from harv_jax.aircraft.registry import aircraft_names
from harv_jax.control.hybrid.settings import DEFAULT_ZETA
from harv_jax.control.registry import (
    ControllerOptions,
    check_options_apply,
    controller_names,
    loop_mismatches,
    split_filter,
)
from harv_jax.errors import UsageError
from harv_jax.evaluation.montecarlo.disturbances import parse_disturbances
from harv_jax.task.disturbance_table import BY_NAME, LEVEL_NAMES

POLICY_HELP = (
    "rl/hybrid policy: run folder, .npz, checkpoint\\[@seed], shipped:robust (default), shipped:teacher, "
    "shipped:fast, shipped:recovery, shipped:paper-full, shipped:paper-partial."
)
ZETA_HELP = (
    "Hybrid zeta schedule: simplex (the policy alone until a monitor hands over to the SMC for good), "
    "continuous, hysteresis (the paper's), gated (per channel, from the reaching condition), always, never."
)
MAX_DURATION_S = 600.0
SWITCHING = ("sat", "sign")


def whole_number(text: str) -> int:
    """``parser=`` of an int option: the text as an int; BadParameter naming the text if it is none (the
    CLI prints ``Invalid value for '--runs': 'nan' is not a whole number``)."""
    try:
        return int(text)
    except (TypeError, ValueError):
        raise typer.BadParameter(f"{text!r} is not a whole number") from None


def real_number(text: str) -> float:
    """``parser=`` of a float option: the text as a float (``nan``/``inf`` pass, for the range checks to name
    them); BadParameter naming the text if it is no number."""
    try:
        return float(text)
    except (TypeError, ValueError):
        raise typer.BadParameter(f"{text!r} is not a number") from None


def policy_option():
    """``--policy`` (default None = the default shipped policy, ``shipped:robust``)."""
    return typer.Option(None, help=POLICY_HELP)


def zeta_option():
    """``--zeta`` (default None: ``registry.DEFAULT_ZETA``, see [`controller_options`][])."""
    return typer.Option(None, help=ZETA_HELP + f" Default {DEFAULT_ZETA}.", show_default=False)


def controller_options(
    names: Sequence[str], policy: str | None, zeta: str | None, switching: str | None = None
) -> ControllerOptions:
    """The controller options of a command; UsageError if one was given that none of the controllers
    ``names`` reads (``registry.check_options_apply``). Options not given take their defaults."""
    given = {"policy": policy, "zeta": zeta, "switching": switching}
    check_options_apply(names, {k: v for k, v in given.items() if v is not None})
    return ControllerOptions(policy=policy, zeta=zeta or DEFAULT_ZETA, switching=switching or "sat")


def force_option(what: str = "non-empty output directory"):
    """``--force``: replace an existing ``what`` (default False)."""
    return typer.Option(False, help=f"Replace an existing {what}.")


def chunk_option():
    """``--chunk`` of a batched closed-loop command (default None: sized from the CPU count and memory)."""
    return typer.Option(
        None,
        parser=whole_number,
        help="Runs per compiled call (bounds memory). Default: 512 per CPU core, all runs on a GPU, "
        "within 1/8 of memory. Results depend on it at float rounding.",
    )


def controllers_help() -> str:
    """``--controller`` help (fixed text; the error for an unknown name lists the registered ones)."""
    return (
        "Controllers, comma-separated: smc, smc-brake, smc-brake-zoom, rl, hybrid"
        " or another name in harv_jax.control.registry; NAME+lpHZ feeds NAME its measurements "
        "through a 2nd-order low-pass at HZ (e.g. smc+lp2), NAME+obsHZ the estimate of a model-based "
        "observer of HZ bandwidth (e.g. smc+obs0.1), NAME+esoHZ that of the extended-state observer, which "
        "also estimates the rate bias the model misses (e.g. rl+eso0.075)."
    )


def command_line() -> str:
    """The ``harv-jax …`` command being run (recorded in the JSON outputs)."""
    return "harv-jax " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def check_fly_options(controller: str, switching: str | None, spin_s: float) -> None:
    """UsageError (one line naming the value and what is allowed) for a bad ``fly``/``compare`` option
    (their shared study options are checked by ``harv_jax.study_options.StudyOptions``)."""
    names = controller_names()
    if split_filter(controller)[0] not in names:
        raise UsageError(f"--controller {controller!r} is unknown; allowed: {', '.join(names)}")
    if switching is not None and switching not in SWITCHING:
        raise UsageError(f"--switching {switching!r} is unknown; allowed: {', '.join(SWITCHING)}")
    if not (math.isfinite(spin_s) and 0 <= spin_s <= MAX_DURATION_S):
        raise UsageError(f"--spin-s {spin_s} must be in [0, {MAX_DURATION_S:g}] s")


def warn_loop_mismatch(names: Sequence[str], policy: str | None, zeta: str) -> None:
    """Print one warning line to stderr per controller that flies the policy in another loop than it was
    trained in (``harv_jax.control.registry.loop_mismatches``)."""
    for line in loop_mismatches(names, ControllerOptions(policy=policy, zeta=zeta)):
        typer.echo(f"harv-jax: warning: {line}", err=True)


DISTURBANCES_HELP = (
    f"Disturbances between the controllers and the aircraft, a comma list of: {', '.join(LEVEL_NAMES)}; "
    f"or default ({', '.join(n for n in LEVEL_NAMES if BY_NAME[n].in_default)} at their default levels, "
    f"and {BY_NAME['turbulence'].default} turbulence unless --turbulence says otherwise), or none (the "
    "undisturbed runs). Every controller of one run meets the same noise, gust, turbulence and aircraft."
)


TURBULENCE_HELP = (
    "Dryden turbulence of MIL-F-8785C: none, light, moderate, severe (probability of exceedance 1e-2, "
    "1e-3, 1e-5 at the current altitude) or a sigma in ft/s; every controller of a run meets the same "
    "white noise, drawn apart from the other disturbances. Default none (moderate with --disturbances "
    "default)."
)


def disturbances_option():
    """``--disturbances`` (default ``none``)."""
    return typer.Option("none", help=DISTURBANCES_HELP)


#: The level options every command with ``@disturbance_options`` takes: parameter name -> help. Each is
#: a number, None (not given: the disturbance's default level) unless set.
LEVEL_OPTION_HELP = {
    **{
        BY_NAME[n].parameter: f"{BY_NAME[n].meaning[0].upper()}{BY_NAME[n].meaning[1:]}; {BY_NAME[n].unit} "
        f"(with {n}; default {BY_NAME[n].default:g})."
        for n in LEVEL_NAMES
    },
    "gust_tau_s": "Gust correlation time, s (with gust; default: per run U(1, 10) s).",
}


def knows_aircraft_option():
    """``--controller-knows-aircraft``."""
    return typer.Option(
        False,
        help="With a randomized aircraft, build the model-based controllers on the plant's own aircraft "
        "instead of the nominal one (no model error).",
    )


def disturbance_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """Give a typer command ``--disturbances`` and the level options (one definition for every command).

    The command declares a keyword ``disturbance_spec`` instead and receives the parsed ``DisturbanceSpec``
    (``evaluation.montecarlo.disturbances``); a bad value fails with the one-line UsageError before the
    command runs. Parameters ``randomize`` and ``controller_knows_aircraft`` of the command, if it has them,
    take part in the parsing (``--randomize`` turns ``model`` on).
    """
    keyword = inspect.Parameter.KEYWORD_ONLY
    added = [inspect.Parameter("disturbances", keyword, default=disturbances_option(), annotation=str)]
    turbulence_option = typer.Option(None, help=TURBULENCE_HELP, show_default=False)
    added.append(inspect.Parameter("turbulence", keyword, default=turbulence_option, annotation=str | None))
    for name, text in LEVEL_OPTION_HELP.items():
        option = typer.Option(None, parser=real_number, help=text)
        added.append(inspect.Parameter(name, keyword, default=option, annotation=float | None))

    @functools.wraps(command)
    def wrapper(**kwargs: Any) -> Any:
        names = kwargs.pop("disturbances")
        turbulence = kwargs.pop("turbulence")
        levels = {name: kwargs.pop(name) for name in LEVEL_OPTION_HELP}
        randomize = kwargs.get("randomize", False)
        knows = kwargs.get("controller_knows_aircraft", False)
        spec = disturbance_spec_from_cli(
            names, **levels, randomize=randomize, controller_knows_aircraft=knows, turbulence=turbulence
        )
        return command(**kwargs, disturbance_spec=spec)

    return with_options(command, wrapper, "disturbance_spec", added)


def with_options(
    command: Callable[..., Any], wrapper: Callable[..., Any], replaced: str, added: list[inspect.Parameter]
) -> Callable[..., Any]:
    """``wrapper`` with the signature typer reads: ``command``'s parameters but ``replaced`` (the keyword the
    wrapper fills in), all keyword-only, then the ``added`` options."""
    sig = inspect.signature(command, eval_str=True)
    keyword = inspect.Parameter.KEYWORD_ONLY
    kept = [p.replace(kind=keyword) for p in sig.parameters.values() if p.name != replaced]
    params = kept + added
    wrapper.__signature__ = sig.replace(parameters=params)  # type: ignore[attr-defined]
    wrapper.__annotations__ = {p.name: p.annotation for p in params} | {"return": sig.return_annotation}
    return wrapper


AIRCRAFT_HELP = (
    "Nominal aircraft: harv (the F-18/HARV, default) or a name registered with "
    "harv_jax.aircraft.register_aircraft; the controllers are built on it."
)


def check_aircraft(name: str | None) -> str | None:
    """``name`` if it is None (not given) or a registered aircraft; UsageError naming ``--aircraft`` and the
    allowed names otherwise."""
    if name is None:
        return None
    if name not in aircraft_names():
        raise UsageError(f"--aircraft {name!r} is unknown; allowed: {', '.join(aircraft_names())}")
    return name


def aircraft_option(command: Callable[..., Any]) -> Callable[..., Any]:
    """Give a typer command ``--aircraft NAME`` (one definition, help text and check for every command).

    The command declares a keyword ``aircraft_name`` instead and receives the checked name (a name of
    ``harv_jax.aircraft.registry``), or None when the option is not given (the studies then fly the
    registry's default); an unknown name fails with the one-line UsageError before the command runs.
    """
    keyword = inspect.Parameter.KEYWORD_ONLY
    option = typer.Option(None, help=AIRCRAFT_HELP, show_default=False)
    added = [inspect.Parameter("aircraft", keyword, default=option, annotation=str | None)]

    @functools.wraps(command)
    def wrapper(**kwargs: Any) -> Any:
        name = check_aircraft(kwargs.pop("aircraft"))
        return command(**kwargs, aircraft_name=name)

    return with_options(command, wrapper, "aircraft_name", added)


def disturbance_spec_from_cli(
    disturbances: str,
    randomize: bool = False,
    controller_knows_aircraft: bool = False,
    turbulence: str | None = None,
    gust_tau_s: float | None = None,
    **levels: float | None,
):
    """The ``DisturbanceSpec`` of the disturbance options (UsageError naming a bad one); ``levels`` by
    option parameter (``noise_scale``, ``delay_ms``, ...: ``harv_jax.task.disturbance_table``)."""
    unknown = sorted(set(levels) - {BY_NAME[n].parameter for n in LEVEL_NAMES})
    if unknown:
        raise ValueError(f"unknown level options {unknown}")
    levels = {n: levels.get(BY_NAME[n].parameter) for n in LEVEL_NAMES}
    return parse_disturbances(
        disturbances, levels, gust_tau_s, randomize, controller_knows_aircraft, turbulence
    )
