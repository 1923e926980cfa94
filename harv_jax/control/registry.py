"""The one table of controllers: name -> builder and the options it reads.

Every command that flies a controller by name (``fly``, ``mc``, ``compare``, ``envelope``, ``quickstart``)
looks it up here. Adding a controller is one module with a ``make_*(…) -> Controller`` factory plus one
line in `CONTROLLERS` (or one [`register`][] call from outside the package, as the tests do)::

    register("toy", lambda opts: make_toy(), options=(), help="constant deflection")

Any name takes a measurement path as a suffix: ``smc+lp2`` is the SMC fed its measured states through a
second-order Butterworth low-pass at 2 Hz (``harv_jax.control.filters``); ``smc+obs0.5`` the SMC fed the
estimate of a model-based observer of 0.5 Hz bandwidth (``harv_jax.control.observer``), ``smc+eso0.1``
that of the extended-state observer (the observer that also estimates the rate bias the model misses);
``rl+lp1.5``, ``hybrid+obs1`` alike.

A builder takes the [`ControllerOptions`][] of the command line and returns a
``Controller(init, apply)`` (``harv_jax.control.base``); ``options`` names the fields it reads, so the
commands know whether a run needs a policy (``"policy"``) or a zeta schedule (``"zeta"``) and record them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

from harv_jax.control.hybrid.settings import DEFAULT_ZETA, ZETA_SCHEDULES
from harv_jax.errors import UsageError
from harv_jax.task.measurement_path import (
    ESO_SUFFIX,
    FILTER_CUTOFF_RANGE_HZ,
    FILTER_ORDER,
    FILTER_SUFFIX,
    OBSERVER_SUFFIX,
    MeasurementPath,
    path_from_record,
    path_record,
)

if TYPE_CHECKING:  # the table stays importable without jax (the CLI checks its arguments first)
    from harv_jax.control.base import Controller

#: Option names a builder may read (fields of ControllerOptions).
OPTION_NAMES = ("policy", "zeta", "switching")


@dataclasses.dataclass(frozen=True)
class ControllerOptions:
    """The command-line options a controller builder may read (hashable: builders may be cached on it).

    Attributes:
        policy: rl/hybrid policy spec (``harv_jax.policy.resolve_policy``; None: the shipped default).
        zeta: the hybrid's zeta schedule (``harv_jax.control.hybrid.law.ZETA_SCHEDULES``).
        switching: the SMC's switching law, ``"sat"`` (boundary layer) or ``"sign"`` (the paper's).
    """

    policy: str | None = None
    zeta: str = DEFAULT_ZETA
    switching: str = "sat"


@dataclasses.dataclass(frozen=True)
class ControllerEntry:
    """One row of the table.

    Attributes:
        build: ControllerOptions -> Controller; raises UsageError for a bad option value.
        options: the ControllerOptions fields ``build`` reads (subset of OPTION_NAMES).
        help: one line for the command-line help.
        loop: for a controller that flies a policy, the loop it flies it in (``none``: alone,
            ``hybrid:<schedule>``), compared with the loop the policy was trained in
            (``harv_jax.training.in_loop``); None: no policy.
        build_behind: (ControllerOptions, MeasurementPath) -> the controller built behind the path a name's
            suffix gives (``policy_controller``: the hybrid then takes its path gains); None: ``build``'s
            controller, wrapped in the path.
    """

    build: Callable[[ControllerOptions], Controller]
    options: tuple[str, ...] = ()
    help: str = ""
    loop: Callable[[ControllerOptions], str] | None = None
    build_behind: Callable[[ControllerOptions, MeasurementPath], Controller] | None = None


def _build_smc(opts: ControllerOptions) -> Controller:
    from harv_jax.control.smc import SMCConfig, make_smc

    return make_smc(SMCConfig(switching=opts.switching))


def _build_smc_brake(opts: ControllerOptions) -> Controller:
    from harv_jax.control.smc import SMCConfig
    from harv_jax.control.smc_brake import make_smc_brake

    return make_smc_brake(SMCConfig(switching=opts.switching))


def _build_smc_brake_zoom(opts: ControllerOptions) -> Controller:
    from harv_jax.control import smc_brake as sb
    from harv_jax.control.smc import SMCConfig

    return sb.make_smc_brake(SMCConfig(switching=opts.switching), schedule=sb.zoom_schedule())


def _policy(policy: str | None) -> Any:
    """The policy at ``policy``; UsageError if its sizes do not fit."""
    from harv_jax.policy import resolve_policy
    from harv_jax.task.spaces import check_policy_sizes

    pol = resolve_policy(policy)
    try:
        check_policy_sizes(pol.networks.observation_size, pol.networks.action_size)
    except ValueError as e:
        raise UsageError(f"--policy {policy!r}: {e}") from None
    return pol


def policy_controller(
    kind: str, act: Callable[[Any], Any], zeta: str, path: MeasurementPath | None
) -> Controller:
    """The policy ``act`` (``obs -> action``) flown as ``kind`` (``rl``, or ``hybrid`` with the ζ schedule
    ``zeta``) behind ``path``, the measurement path it was trained behind (None: none), as ``--controller
    rl``/``hybrid`` fly it. Behind a path the hybrid takes ``control.hybrid.law.path_hybrid_gains``."""
    from harv_jax.control.hybrid.law import HybridConfig, default_hybrid_gains, make_hybrid, path_hybrid_gains
    from harv_jax.control.rl import make_rl_controller

    if kind == "rl":
        ctrl = make_rl_controller(act)
    else:
        gains = default_hybrid_gains() if path is None else path_hybrid_gains()
        ctrl = make_hybrid(act, HybridConfig(schedule=zeta), gains)
    return ctrl if path is None else with_measurement_path(ctrl, path)


def _build_rl(opts: ControllerOptions, path: MeasurementPath | None = None) -> Controller:
    pol = _policy(opts.policy)
    path = path if path is not None else policy_path(pol)
    return policy_controller("rl", pol.deterministic, opts.zeta, path)


def _hybrid_zeta(opts: ControllerOptions) -> str:
    """``opts.zeta``; UsageError if it names no ζ schedule."""
    if opts.zeta not in ZETA_SCHEDULES:
        raise UsageError(f"--zeta {opts.zeta!r} is unknown; allowed: {', '.join(ZETA_SCHEDULES)}")
    return opts.zeta


def _build_hybrid(opts: ControllerOptions, path: MeasurementPath | None = None) -> Controller:
    pol = _policy(opts.policy)
    path = path if path is not None else policy_path(pol)
    return policy_controller("hybrid", pol.deterministic, _hybrid_zeta(opts), path)


#: The controllers, in help order.
CONTROLLERS: dict[str, ControllerEntry] = {
    "smc": ControllerEntry(_build_smc, ("switching",), "sliding-mode control (harv_jax.control.smc)"),
    "rl": ControllerEntry(
        _build_rl,
        ("policy",),
        "the learned policy alone (harv_jax.control.rl)",
        lambda opts: "none",
        _build_rl,
    ),
    "hybrid": ControllerEntry(
        _build_hybrid,
        ("policy", "zeta"),
        "policy + SMC feedback, scheduled by zeta (harv_jax.control.hybrid.law)",
        lambda opts: f"hybrid:{opts.zeta}",
        _build_hybrid,
    ),
    "smc-brake": ControllerEntry(
        _build_smc_brake,
        ("switching",),
        "the SMC flying alpha_d = 1.0 rad while V > 500 ft/s: brakes by drag (harv_jax.control.smc_brake)",
    ),
    "smc-brake-zoom": ControllerEntry(
        _build_smc_brake_zoom,
        ("switching",),
        "smc-brake while 600 < V < 1200 - 600 max(gamma, 0) ft/s: not in a zoom climb (control.smc_brake)",
    ),
}


def register(
    name: str,
    build: Callable[[ControllerOptions], Controller],
    options: Iterable[str] = (),
    help: str = "",
) -> None:
    """Add a controller to `CONTROLLERS` (ValueError if the name is taken or an option unknown)."""
    if name in CONTROLLERS:
        raise ValueError(f"controller {name!r} is already registered")
    options = tuple(options)
    unknown = [o for o in options if o not in OPTION_NAMES]
    if unknown or not name or "," in name or "+" in name:
        raise ValueError(
            f"controller {name!r}: bad name or unknown options {unknown}; allowed {OPTION_NAMES}"
        )
    CONTROLLERS[name] = ControllerEntry(build, options, help)


def controller_names() -> tuple[str, ...]:
    """The registered names, in table order."""
    return tuple(CONTROLLERS)


def _unknown(name: str) -> UsageError:
    return UsageError(
        f"unknown controller {name!r}; allowed: {', '.join(CONTROLLERS)} "
        "(each may end in +lpHZ, +obsHZ or +esoHZ)"
    )


def base_name(name: str) -> str:
    """``name`` without its measurement-path suffix (not validated)."""
    return name.partition("+")[0]


def split_filter(name: str) -> tuple[str, MeasurementPath | None]:
    """(registered name, measurement path or None) of a controller name; UsageError for a bad suffix."""
    base, plus, rest = name.partition("+")
    if not plus:
        return name, None
    suffixes = (OBSERVER_SUFFIX, ESO_SUFFIX, FILTER_SUFFIX)
    suffix = next((s for s in suffixes if ("+" + rest).startswith(s)), None)
    text = rest[len(suffix) - 1 :] if suffix else rest
    lo, hi = FILTER_CUTOFF_RANGE_HZ
    try:
        hz = float(text)
    except ValueError:
        hz = float("nan")
    if suffix is None or not (lo <= hz <= hi):  # also false for nan
        raise UsageError(
            f"controller {name!r}: the suffix +{rest} needs to be +lpHZ (low-pass), +obsHZ (observer) or "
            f"+esoHZ (extended-state observer) with HZ from {lo:g} to {hi:g} (e.g. {base}{FILTER_SUFFIX}2, "
            f"{base}{OBSERVER_SUFFIX}0.5)"
        )
    return base, MeasurementPath(suffix, hz)


def with_measurement_path(ctrl: Controller, path: MeasurementPath) -> Controller:
    """``ctrl`` fed through the measurement path ``path`` (low-pass, observer or extended-state observer)."""
    if path.suffix in (OBSERVER_SUFFIX, ESO_SUFFIX):
        from harv_jax.control.observer import with_state_observer

        return with_state_observer(ctrl, path.bandwidth_hz, estimate_bias=path.suffix == ESO_SUFFIX)
    from harv_jax.control.filters import with_measurement_filter

    return with_measurement_filter(ctrl, path.bandwidth_hz, FILTER_ORDER)


def parse_measurement_path(text: str, where: str = "measurement_path") -> MeasurementPath | None:
    """``none`` or a path as a suffix names it without its ``+`` (``lp2``, ``obs0.3``, ``eso0.075``);
    UsageError naming the value and what is allowed."""
    t = str(text).strip()
    if t == "none":
        return None
    try:
        return split_filter(f"x+{t}")[1]
    except UsageError:
        lo, hi = FILTER_CUTOFF_RANGE_HZ
        raise UsageError(
            f"{where} {text!r}: allowed: none, lpHZ (low-pass), obsHZ (observer) or esoHZ (extended-state "
            f"observer) with HZ from {lo:g} to {hi:g} (e.g. lp2, obs0.3)"
        ) from None


def policy_path(policy: Any) -> MeasurementPath | None:
    """The measurement path a loaded policy carries (its metadata's, validated on load), or None."""
    rec = policy.meta.get("measurement_path")
    return None if rec is None else path_from_record(rec, "policy")


def build_controller(name: str, options: ControllerOptions | None = None) -> Controller:
    """The controller ``name`` built with ``options``; UsageError for an unknown name or bad option. A
    policy that carries its measurement path flies behind it (``rl``, ``hybrid``); a suffix on such a
    policy's controller is refused. Behind a path, carried or by suffix, the policy-flown controllers are
    ``policy_controller``'s (``ControllerEntry.build_behind``)."""
    base, path = split_filter(name)
    if base not in CONTROLLERS:
        raise _unknown(name)
    options = options or ControllerOptions()
    if path is not None and "policy" in CONTROLLERS[base].options:
        from harv_jax.policy import resolve_policy

        carried = policy_path(resolve_policy(options.policy))
        if carried is not None:
            rec = path_record(carried)
            raise UsageError(
                f"controller {name!r}: the policy {options.policy or 'shipped'!r} carries its measurement "
                f"path ({rec['kind']} {rec['bandwidth_hz']:g} Hz) and flies behind it; drop the suffix"
            )
    entry = CONTROLLERS[base]
    if path is not None and entry.build_behind is not None:
        return entry.build_behind(options, path)
    ctrl = entry.build(options)
    return ctrl if path is None else with_measurement_path(ctrl, path)


def uses_option(names: Iterable[str], option: str) -> bool:
    """Whether any of the controllers ``names`` reads ``option`` (e.g. ``"policy"``)."""
    bases = [base_name(n) for n in names]
    return any(option in CONTROLLERS[n].options for n in bases if n in CONTROLLERS)


def check_options_apply(names: Iterable[str], given: dict[str, str]) -> None:
    """UsageError if an option the user gave (``given``: option name -> its value) is read by none of the
    controllers ``names``: ``--policy`` without rl or hybrid, ``--zeta`` without hybrid, ``--switching``
    without an SMC."""
    names = list(names)
    for option, value in given.items():
        if uses_option(names, option):
            continue
        readers = [n for n, e in CONTROLLERS.items() if option in e.options]
        raise UsageError(
            f"--{option} {value!r} applies only to {', '.join(readers)}; --controller {','.join(names)} "
            f"flies none of them: drop --{option} or add one of them"
        )


def parse_controllers(text: str) -> list[str]:
    """Comma-separated controller names -> list; UsageError on unknown or duplicate names."""
    names = [c.strip() for c in text.split(",") if c.strip()]
    if not names:
        raise UsageError(f"--controller {text!r} names no controller; allowed: {', '.join(CONTROLLERS)}")
    for c in names:
        if split_filter(c)[0] not in CONTROLLERS:
            raise _unknown(c)
    if len(set(names)) != len(names):
        raise UsageError(f"--controller {text!r} names a controller twice")
    return names


def loop_mismatches(names: Iterable[str], options: ControllerOptions) -> list[str]:
    """One line per controller in ``names`` that flies a policy trained in a loop in another loop.

    The policy file's ``meta["loop"]`` (absent: ``none``, trained alone) is compared with the entry's
    ``loop``; e.g. a policy trained with ``train --in-loop hybrid:gated`` flown as ``rl`` or with
    ``--zeta continuous``. A policy trained alone flown in a hybrid is the paper's design: no line.
    """
    bases = {n: base_name(n) for n in names}
    entries = {
        n: CONTROLLERS[b] for n, b in bases.items() if b in CONTROLLERS and CONTROLLERS[b].loop is not None
    }
    if not entries:
        return []
    from harv_jax.policies import DEFAULT_POLICY_SPEC
    from harv_jax.policy import resolve_policy

    trained = str(resolve_policy(options.policy).meta.get("loop", "none"))  # one load for all controllers
    lines = []
    for name, entry in entries.items():
        flown = entry.loop(options)
        if trained not in ("none", flown):
            spec = options.policy or DEFAULT_POLICY_SPEC
            lines.append(
                f"the policy {spec!r} was trained in the loop {trained!r} and flies here as {name!r} "
                f"(loop {flown!r})"
            )
    return lines
