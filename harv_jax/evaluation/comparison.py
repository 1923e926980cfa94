"""Controllers compared on the spin scenario and a fixed upset state (``harv-jax compare``).

For each scenario every controller flies from the same state ([`harv_jax.evaluation.flight.fly`][]);
[`compare`][] returns a [`Comparison`][] with one metrics row per scenario and controller
(``summary.COMPARE_COLUMNS``) and, when ``smc`` is among the controllers, every other controller against it
on the same scenarios (``montecarlo.paired.paired_vs_smc``); [`write_comparison`][] writes the overlaid time
histories in the paper's four-figure layout, the metrics table (Markdown + CSV) and ``compare.json``.
"""

from __future__ import annotations

import csv
import dataclasses
import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from harv_jax import atomic
from harv_jax.aircraft.registry import resolve_aircraft
from harv_jax.dynamics import CONTROL_NAMES, WIND_STATE_NAMES
from harv_jax.evaluation.flight import FlightResult, fly
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.evaluation.montecarlo.paired import REFERENCE_CONTROLLER, paired_vs_smc, times_nr_at_run_s
from harv_jax.evaluation.summary import COMPARE_COLUMNS, controllers_setting
from harv_jax.numfmt import fmt_num, write_json
from harv_jax.task.spec import DT_S, H0_FT
from harv_jax.task.turbulent_criterion import criterion_record

if TYPE_CHECKING:
    from harv_jax.aircraft.params import AircraftParams

#: Fixed upset state of the second scenario (wind axes; ft/s, rad, rad/s, ft): a nose-high (alpha 46 deg),
#: rolling, yawing, banked upset inside the paper's reset bounds.
FIXED_STATE = {
    "V": 600.0,
    "alpha": 0.8,
    "beta": 0.15,
    "p": 1.0,
    "q": 0.4,
    "r": 0.4,
    "mu": 0.6,
    "gamma": 0.3,
    "chi": 0.0,
    "h": H0_FT,
}
OMEGA_SETTLE_RADPS = 0.17


def omega_settling_time_s(
    t_s: np.ndarray, x_wind: np.ndarray, tol: float = OMEGA_SETTLE_RADPS
) -> float | None:
    """First time from which ||(p, q, r)|| < tol holds to the end (None if it never settles)."""
    ok = np.linalg.norm(x_wind[:, 3:6], axis=1) < tol
    if not ok[-1]:
        return None
    bad = np.flatnonzero(~ok)
    return float(t_s[bad[-1] + 1] if bad.size else t_s[0])


def row_of(scenario: str, controller: str, res: FlightResult) -> dict[str, Any]:
    """The metrics-table row of one flight (times from engagement; ``recovery_time_vs_smc`` is None until
    [`add_vs_smc`][] fills it in)."""
    m = res.metrics
    n_pre = int(round(res.t_engage_s / (res.t_s[1] - res.t_s[0]))) if len(res.t_s) > 1 else 0
    t_rec = np.nan if m["t_recover_s"] is None else m["t_recover_s"]
    t_nr = times_nr_at_run_s([t_rec], [m["recovered"]], (len(res.t_s) - n_pre) * DT_S)  # run length
    t = res.t_s[n_pre:] - res.t_engage_s
    hy = res.hybrid
    zeta_frac = fallbacks = None
    if hy is not None:
        z = hy["zeta"][n_pre:]
        fb = hy["fallback"][n_pre:].astype(bool)
        zeta_frac = float(np.mean(z))
        fallbacks = int(np.sum(fb[1:] & ~fb[:-1]) + fb[0])
    return {
        "scenario": scenario,
        "controller": controller,
        "outcome": m["outcome_name"],
        "recovery_time_s": m["t_recover_s"],
        "alpha_overshoot_deg": None
        if m["overshoot_rad"][0] is None
        else float(np.degrees(m["overshoot_rad"][0])),
        "omega_settling_time_s": omega_settling_time_s(t, res.x_wind[n_pre:]),
        "altitude_loss_ft": m["altitude_loss_ft"],
        "control_tv_rad": float(np.nansum(m["control_tv_rad"])),
        "chatter_index_rad2": float(np.nansum(m["chatter_index_rad2"])),
        "constraint_violations": int(bool(m["left_envelope"])) + int(bool(m["hit_ground"])),
        "rate_saturation_fraction": float(np.mean(m["sat_rate_fraction"])),
        "zeta_active_fraction": zeta_frac,
        "supervisor_fallbacks": fallbacks,
        "recovery_time_nr_at_run_s": float(t_nr[0]),
        "recovery_time_vs_smc": None,
    }


def add_vs_smc(rows: list[dict[str, Any]], run_length_s: float) -> dict[str, dict[str, Any]]:
    """Fill in ``recovery_time_vs_smc`` (this row's ``recovery_time_nr_at_run_s`` over smc's on the same
    scenario) and return every other controller against smc over the scenarios
    (``montecarlo.paired.paired_vs_smc``); nothing when smc is not among the rows."""
    by = {(r["scenario"], r["controller"]): r["recovery_time_nr_at_run_s"] for r in rows}
    scenarios = list(dict.fromkeys(r["scenario"] for r in rows))
    if not any(c == REFERENCE_CONTROLLER for _, c in by):
        return {}
    for r in rows:
        ref = by[(r["scenario"], REFERENCE_CONTROLLER)]
        r["recovery_time_vs_smc"] = r["recovery_time_nr_at_run_s"] / ref if ref > 0 else None
    times = {
        c: (np.array([by[(sc, c)] for sc in scenarios]), np.ones(len(scenarios), bool))
        for c in dict.fromkeys(r["controller"] for r in rows)
    }
    return paired_vs_smc(times, run_length_s)


@dataclasses.dataclass(frozen=True)
class Comparison:
    """The flights of a comparison and their metrics.

    Attributes:
        flights: scenario -> controller -> FlightResult.
        rows: one metrics row (COMPARE_COLUMNS) per scenario and controller.
        vs_smc: controller -> ``montecarlo.paired.paired_vs_reference`` against smc over the scenarios
            (not-recovered flights at the run length); empty when smc was not flown.
        certificates: ``"<scenario>/<controller>"`` -> the flight's certificate (controllers that have one).
        h0_ft: scenario -> initial altitude, ft.
        settings: the run's settings (the top of compare.json).
    """

    flights: dict[str, dict[str, FlightResult]]
    rows: list[dict[str, Any]]
    certificates: dict[str, dict]
    h0_ft: dict[str, float]
    settings: dict[str, Any]
    vs_smc: dict[str, dict[str, Any]] = dataclasses.field(default_factory=dict)


def compare(
    controllers: list[str],
    policy: str | None,
    zeta: str,
    target_alpha_rad: float,
    duration_s: float,
    spin_s: float,
    fixed_state: dict[str, float],
    seed: int,
    progress: Callable[[str], None] | None = None,
    disturbances: DisturbanceSpec | None = None,
    aircraft: str | AircraftParams | None = None,
) -> Comparison:
    """Fly every controller on the spin and from ``fixed_state`` (a wind state by name); no files.
    ``disturbances``: after engagement, the same for every controller (``flight.fly``); ``aircraft``: the
    nominal aircraft (a registry name or ``AircraftParams``; None: the default), recorded by name."""

    aircraft_name, nominal = resolve_aircraft(aircraft)
    say = progress or (lambda _msg: None)
    flights: dict[str, dict[str, FlightResult]] = {}
    rows: list[dict[str, Any]] = []
    certificates: dict[str, dict] = {}
    h0_ft: dict[str, float] = {}
    for scen, arg in (("spin", "spin"), ("fixed", fixed_state)):
        flights[scen] = {}
        for name in controllers:
            say(f"[compare] {scen}: {name} ...")
            res = fly(
                arg,
                target_alpha_rad,
                duration_s,
                seed,
                "sat",
                spin_s,
                name,
                policy,
                zeta,
                disturbances,
                aircraft=nominal,
            )
            flights[scen][name] = res
            rows.append(row_of(scen, name, res))
            if res.certificate is not None:
                certificates[f"{scen}/{name}"] = res.certificate
            h0_ft[scen] = float(res.x_wind[0, 9])
            say(
                f"[compare]     outcome {rows[-1]['outcome']}, recovery time "
                f"{fmt_num(rows[-1]['recovery_time_s'], unit='s', missing='- (not recovered)')}"
            )
    settings = {
        "controllers": controllers,
        "policy": controllers_setting(controllers, policy, zeta)["policy"],
        "zeta_schedule": zeta,
        "h0_ft": h0_ft,
        "target_alpha_rad": target_alpha_rad,
        "duration_s": duration_s,
        "spin_s": spin_s,
        "seed": seed,
        "dt_s": DT_S,
        "fixed_state": fixed_state,
        "disturbances": (disturbances or DisturbanceSpec()).as_dict(),
        "recovery_criterion": criterion_record((disturbances or DisturbanceSpec()).turbulence != "none"),
        "aircraft": aircraft_name,
    }
    vs_smc = add_vs_smc(rows, duration_s)
    return Comparison(flights, rows, certificates, h0_ft, settings, vs_smc)


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def write_tables(
    out_dir: Path, rows: list[dict], setting: str = "", vs_smc: dict[str, dict] | None = None
) -> None:
    """compare_metrics.csv and compare_metrics.md (``setting``: a sentence naming the policy, references
    and h0, printed above the table; ``vs_smc``: [`Comparison.vs_smc`][], a second table in the .md)."""
    with atomic.open_atomic(out_dir / "compare_metrics.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COMPARE_COLUMNS)
        w.writeheader()
        w.writerows([{k: ("" if r[k] is None else r[k]) for k in COMPARE_COLUMNS} for r in rows])
    lines = ([setting, ""] if setting else []) + [
        "| " + " | ".join(COMPARE_COLUMNS) + " |",
        "|" + "---|" * len(COMPARE_COLUMNS),
    ]
    lines += ["| " + " | ".join(_fmt(r[k]) for k in COMPARE_COLUMNS) + " |" for r in rows]
    notes = (
        "\nTimes are from controller engagement. constraint_violations counts leaving the flight envelope "
        "and hitting the ground (0-2); omega settling: ||(p, q, r)|| < 0.17 rad/s to the end; TV and chatter "
        "are summed over the three surfaces; supervisor_fallbacks counts entries into SMC-only mode; "
        "recovery_time_nr_at_run_s is the recovery time with a flight that does not recover counted at the "
        "run length, recovery_time_vs_smc that time over smc's on the same scenario.\n"
    )
    if vs_smc:
        cols = ("faster_fraction", "slower_fraction", "mean_ratio")
        first = next(iter(vs_smc.values()))
        notes += (
            f"\nAgainst smc over the {first['runs']} scenarios (recovery times with a flight that does "
            f"not recover at the run length, {first['run_length_s']:g} s): the share of scenarios recovered "
            f"faster / slower than smc by more than {first['margin_s']:g} s and the mean time over smc's.\n\n"
            "| controller | "
            + " | ".join(cols)
            + " |\n|"
            + "---|" * (len(cols) + 1)
            + "\n"
            + "".join(f"| {c} | " + " | ".join(_fmt(v[k]) for k in cols) + " |\n" for c, v in vs_smc.items())
        )
    atomic.write_text(out_dir / "compare_metrics.md", "\n".join(lines) + "\n" + notes)


def write_comparison(out_dir: Path, comp: Comparison, command: str) -> None:
    """fixed_state.json, <scenario>_trajectories.png (and <scenario>_hybrid.png), compare_metrics.md/.csv
    and compare.json (``command``: the command line recorded in it)."""
    from harv_jax.plots.flight import plot_hybrid
    from harv_jax.plots.time_histories import plot_time_histories

    s = comp.settings
    atomic.write_text(out_dir / "fixed_state.json", json.dumps(s["fixed_state"], indent=2) + "\n")
    target_alpha, policy_name = s["target_alpha_rad"], s["policy"]
    learned = policy_name is not None
    for scen, flights in comp.flights.items():
        runs = {}
        res = t_engage = None
        for name, res in flights.items():
            cols = {n: res.x_wind[:, i] for i, n in enumerate(WIND_STATE_NAMES)}
            cols.update({n: res.delta_rad[:, i] for i, n in enumerate(CONTROL_NAMES)})
            runs[name] = cols
            t_engage = res.t_engage_s
            if res.hybrid is not None:
                plot_hybrid(res.t_s, res.hybrid, out_dir / f"{scen}_hybrid.png", t_engage, res.u_cmd_rad)
        plot_time_histories(
            res.t_s,
            runs,
            out_dir / f"{scen}_trajectories.png",
            title=f"{scen}: {' vs '.join(flights)} (alpha_d = {np.degrees(target_alpha):.1f} deg"
            + (f", policy {policy_name}" if learned else "")
            + ")",
            references={"alpha": target_alpha, "beta": 0.0, "mu": 0.0},
            t_marker_s=t_engage if t_engage else None,
        )
    h0_ft = comp.h0_ft
    zeta, spin_s = s["zeta_schedule"], s["spin_s"]
    setting = (
        (f"Policy of rl and hybrid: {policy_name}; hybrid zeta schedule: {zeta}. " if learned else "")
        + f"alpha_d = {np.degrees(target_alpha):.1f} deg ({target_alpha:g} rad), beta_d = mu_d = 0; initial "
        + "altitude h0: "
        + ", ".join(f"{sc} {h:,.0f} ft" for sc, h in h0_ft.items())
        + (f" (the spin starts at h0 and is held {spin_s:g} s before engagement)" if "spin" in h0_ft else "")
        + "."
    )
    write_tables(out_dir, comp.rows, setting, comp.vs_smc)
    doc = {
        "command": command,
        **s,
        "rows": comp.rows,
        "vs_smc": comp.vs_smc,
        "certificates": comp.certificates,
    }
    write_json(out_dir / "compare.json", doc)
