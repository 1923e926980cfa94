"""`harv-jax compare`: RL-only vs SMC-only vs hybrid on the spin scenario and a fixed upset state.

For each scenario every controller flies from the same state (``run_fly``); the overlaid time histories
use the paper's four-figure layout and one metrics table (Markdown + CSV) has a row per scenario and
controller.
"""

from __future__ import annotations

import csv
import json
import shlex
import sys
from pathlib import Path

import numpy as np
import typer

from harv_jax.commands.options import policy_option, zeta_option
from harv_jax.errors import UsageError
from harv_jax.numfmt import fmt_num, write_json
from harv_jax.policies import DEFAULT_POLICY_SPEC

#: Fixed upset state of the second scenario (wind axes; ft/s, rad, rad/s, ft): a nose-high (alpha 46 deg),
#: rolling, yawing, banked upset inside the paper's reset bounds.
FIXED_STATE = {"V": 600.0, "alpha": 0.8, "beta": 0.15, "p": 1.0, "q": 0.4, "r": 0.4, "mu": 0.6,
               "gamma": 0.3, "chi": 0.0, "h": 25_000.0}  # fmt: skip
OMEGA_SETTLE_RADPS = 0.17
COLUMNS = (
    "scenario", "controller", "outcome", "recovery_time_s", "alpha_overshoot_deg", "omega_settling_time_s",
    "altitude_loss_ft", "control_tv_rad", "chatter_index_rad2", "constraint_violations",
    "rate_saturation_fraction", "zeta_active_fraction", "supervisor_fallbacks",
)  # fmt: skip


def omega_settling_time_s(
    t_s: np.ndarray, x_wind: np.ndarray, tol: float = OMEGA_SETTLE_RADPS
) -> float | None:
    """First time from which ||(p, q, r)|| < tol holds to the end (None if it never settles)."""
    ok = np.linalg.norm(x_wind[:, 3:6], axis=1) < tol
    if not ok[-1]:
        return None
    bad = np.flatnonzero(~ok)
    return float(t_s[bad[-1] + 1] if bad.size else t_s[0])


def row_of(scenario: str, controller: str, res: dict) -> dict:
    """The metrics-table row of one flight (times from engagement)."""
    m = res["metrics"]
    n_pre = int(round(res["t_engage_s"] / (res["t_s"][1] - res["t_s"][0]))) if len(res["t_s"]) > 1 else 0
    t = res["t_s"][n_pre:] - res["t_engage_s"]
    hy = res.get("hybrid")
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
        "omega_settling_time_s": omega_settling_time_s(t, res["x_wind"][n_pre:]),
        "altitude_loss_ft": m["altitude_loss_ft"],
        "control_tv_rad": float(np.nansum(m["control_tv_rad"])),
        "chatter_index_rad2": float(np.nansum(m["chatter_index_rad2"])),
        "constraint_violations": int(bool(m["left_envelope"])) + int(bool(m["hit_ground"])),
        "rate_saturation_fraction": float(np.mean(m["sat_rate_fraction"])),
        "zeta_active_fraction": zeta_frac,
        "supervisor_fallbacks": fallbacks,
    }


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def write_tables(out_dir: Path, rows: list[dict], setting: str = "") -> None:
    """compare_metrics.csv and compare_metrics.md (``setting``: a sentence naming the policy, references
    and h0, printed above the table)."""
    with (out_dir / "compare_metrics.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows([{k: ("" if r[k] is None else r[k]) for k in COLUMNS} for r in rows])
    lines = ([setting, ""] if setting else []) + [
        "| " + " | ".join(COLUMNS) + " |",
        "|" + "---|" * len(COLUMNS),
    ]
    lines += ["| " + " | ".join(_fmt(r[k]) for k in COLUMNS) + " |" for r in rows]
    notes = (
        "\nTimes are from controller engagement. constraint_violations counts leaving the flight envelope "
        "and hitting the ground (0-2); omega settling: ||(p, q, r)|| < 0.17 rad/s to the end; TV and chatter "
        "are summed over the three surfaces; supervisor_fallbacks counts entries into SMC-only mode.\n"
    )
    (out_dir / "compare_metrics.md").write_text("\n".join(lines) + "\n" + notes)


def run_compare(
    controllers: list[str],
    policy: str | None,
    zeta: str,
    target_alpha: float,
    duration: float,
    spin_s: float,
    state_file: Path | None,
    seed: int,
    out_dir: Path,
) -> list[dict]:
    """Fly every controller on both scenarios; write figures, tables and compare.json."""
    from harv_jax.commands.fly import DT_S, load_state_file, plot_hybrid, run_fly
    from harv_jax.dynamics import CONTROL_NAMES, WIND_STATE_NAMES
    from harv_jax.plotting import plot_time_histories

    state = load_state_file(state_file) if state_file else FIXED_STATE
    scen_file = out_dir / "fixed_state.json"
    scen_file.write_text(json.dumps(state, indent=2) + "\n")
    scenarios = {"spin": "spin", "fixed": str(scen_file)}
    rows: list[dict] = []
    certificates: dict[str, dict] = {}
    h0_ft: dict[str, float] = {}
    learned = bool({"rl", "hybrid"} & set(controllers))
    policy_name = (policy or DEFAULT_POLICY_SPEC) if learned else None
    for scen, arg in scenarios.items():
        runs = {}
        t_engage = None
        for name in controllers:
            typer.echo(f"[compare] {scen}: {name} ...")
            res = run_fly(arg, target_alpha, duration, seed, "sat", spin_s, name, policy, zeta)
            rows.append(row_of(scen, name, res))
            if res.get("certificate") is not None:
                certificates[f"{scen}/{name}"] = res["certificate"]
            cols = {n: res["x_wind"][:, i] for i, n in enumerate(WIND_STATE_NAMES)}
            cols.update({n: res["delta_rad"][:, i] for i, n in enumerate(CONTROL_NAMES)})
            runs[name] = cols
            t_engage = res["t_engage_s"]
            h0_ft[scen] = float(res["x_wind"][0, 9])
            if res.get("hybrid") is not None:
                plot_hybrid(
                    res["t_s"], res["hybrid"], out_dir / f"{scen}_hybrid.png", t_engage, res["u_cmd_rad"]
                )
            typer.echo(
                f"[compare]     outcome {rows[-1]['outcome']}, recovery time "
                f"{fmt_num(rows[-1]['recovery_time_s'], unit='s', missing='- (not recovered)')}"
            )
        plot_time_histories(
            res["t_s"], runs, out_dir / f"{scen}_trajectories.png",
            title=f"{scen}: {' vs '.join(controllers)} (alpha_d = {np.degrees(target_alpha):.1f} deg"
            + (f", policy {policy_name}" if learned else "") + ")",
            references={"alpha": target_alpha, "beta": 0.0, "mu": 0.0},
            t_marker_s=t_engage if t_engage else None,
        )  # fmt: skip
    setting = (
        (f"Policy of rl and hybrid: {policy_name}; hybrid zeta schedule: {zeta}. " if learned else "")
        + f"alpha_d = {np.degrees(target_alpha):.1f} deg ({target_alpha:g} rad), beta_d = mu_d = 0; initial "
        + "altitude h0: "
        + ", ".join(f"{s} {h:,.0f} ft" for s, h in h0_ft.items())
        + (f" (the spin starts at h0 and is held {spin_s:g} s before engagement)" if "spin" in h0_ft else "")
        + "."
    )
    write_tables(out_dir, rows, setting)
    doc = {
        "command": "harv-jax " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
        "controllers": controllers, "policy": policy_name, "zeta_schedule": zeta, "h0_ft": h0_ft,
        "target_alpha_rad": target_alpha, "duration_s": duration, "spin_s": spin_s, "seed": seed,
        "dt_s": DT_S, "fixed_state": state, "rows": rows, "certificates": certificates,
    }  # fmt: skip
    write_json(out_dir / "compare.json", doc)
    return rows


def register(app: typer.Typer) -> None:
    @app.command()
    def compare(
        controller: str = typer.Option(
            "rl,smc,hybrid", help="Controllers, comma-separated: smc, rl, hybrid."
        ),
        policy: str = policy_option(),
        zeta: str = zeta_option(),
        target_alpha: float = typer.Option(0.349, help="Target angle of attack, rad."),
        duration: float = typer.Option(60.0, help="Closed-loop time after engagement, s."),
        spin_s: float = typer.Option(30.0, help="Seconds held in the spin before engagement."),
        state: Path = typer.Option(
            None, help="Fixed-state scenario file (.json/.csv; default: a built-in upset)."
        ),
        seed: int = typer.Option(0, help="Seed of the controller keys."),
        out: Path = typer.Option(Path("runs/compare"), help="Output directory."),
        force: bool = typer.Option(False, help="Replace an existing non-empty output directory."),
    ) -> None:
        """RL vs SMC vs hybrid on the spin and a fixed state: overlaid histories, metrics table (md, csv)."""
        from harv_jax.commands.fly import load_state_file, validate_options
        from harv_jax.commands.mc import build_controller, parse_controllers
        from harv_jax.guards import check_seed
        from harv_jax.outdir import prepare_out_dir

        names = parse_controllers(controller)
        check_seed(seed)
        for name in names:
            validate_options(name, "sat", target_alpha, duration, spin_s)
            build_controller(name, policy, zeta)
        if state is not None:
            if not state.is_file():
                raise UsageError(f"--state {str(state)!r} does not exist")
            load_state_file(state)
        out_dir = prepare_out_dir(out, force)
        run_compare(names, policy, zeta, target_alpha, duration, spin_s, state, seed, out_dir)
        typer.echo(
            f"wrote {out_dir}/compare_metrics.md, compare_metrics.csv, *_trajectories.png, compare.json"
        )
