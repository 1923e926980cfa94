"""`harv-jax mc`: Monte Carlo of one or more controllers on common random initial states/aircraft."""

from __future__ import annotations

import csv
import math
import shlex
import sys
from pathlib import Path

import numpy as np
import typer

from harv_jax.commands.options import policy_option, zeta_option
from harv_jax.errors import UsageError
from harv_jax.numfmt import write_json
from harv_jax.policies import DEFAULT_POLICY_SPEC

KNOWN_CONTROLLERS = ("smc", "rl", "hybrid")
MAX_RUNS = 1_000_000


def parse_controllers(text: str) -> list[str]:
    """Comma-separated controller names -> list; UsageError on unknown or duplicate names."""
    names = [c.strip() for c in text.split(",") if c.strip()]
    if not names:
        raise UsageError(
            f"--controller {text!r} names no controller; allowed: {', '.join(KNOWN_CONTROLLERS)}"
        )
    for c in names:
        if c not in KNOWN_CONTROLLERS:
            raise UsageError(f"unknown controller {c!r}; allowed: {', '.join(KNOWN_CONTROLLERS)}")
    if len(set(names)) != len(names):
        raise UsageError(f"--controller {text!r} names a controller twice")
    return names


def build_controller(name: str, policy: str | None, zeta: str = "continuous"):
    """Controller by name: ``smc``; ``rl`` and ``hybrid`` fly the policy at ``policy``.

    ``zeta`` is the hybrid's schedule (``harv_jax.control.hybrid.ZETA_SCHEDULES``).
    """
    if name == "smc":
        from harv_jax.control.smc import make_smc

        return make_smc()
    if name in ("rl", "hybrid"):
        from harv_jax.policy import resolve_policy
        from harv_jax.task.spaces import ACTION_SIZE, OBSERVATION_SIZE

        pol = resolve_policy(policy)
        sizes = (pol.networks.observation_size, pol.networks.action_size)
        if sizes != (OBSERVATION_SIZE, ACTION_SIZE):
            raise UsageError(
                f"--policy {policy!r} maps {sizes[0]} observations to {sizes[1]} actions; this aircraft's "
                f"controller needs {OBSERVATION_SIZE} -> {ACTION_SIZE}"
            )
        act = pol.deterministic
        if name == "rl":
            from harv_jax.control.rl import make_rl_controller

            return make_rl_controller(act)
        from harv_jax.control.hybrid import ZETA_SCHEDULES, HybridConfig, make_hybrid

        if zeta not in ZETA_SCHEDULES:
            raise UsageError(f"--zeta {zeta!r} is unknown; allowed: {', '.join(ZETA_SCHEDULES)}")
        return make_hybrid(act, HybridConfig(schedule=zeta))
    raise UsageError(f"unknown controller {name!r}; allowed: {', '.join(KNOWN_CONTROLLERS)}")


def validate(runs: int, target_alpha: float, duration: float, chunk: int) -> None:
    """One-line UsageErrors for out-of-range numeric flags."""
    if not 1 <= runs <= MAX_RUNS:
        raise UsageError(f"--runs {runs} must be in [1, {MAX_RUNS}]")
    if not (math.isfinite(target_alpha) and -0.244 <= target_alpha <= 1.571):
        raise UsageError(f"--target-alpha {target_alpha} rad is outside the envelope [-0.244, 1.571]")
    if not (math.isfinite(duration) and 1.0 <= duration <= 600.0):
        raise UsageError(f"--duration {duration} s must be in [1, 600]")
    if chunk < 1:
        raise UsageError(f"--chunk {chunk} must be >= 1")


def write_runs_csv(path: Path, x0: np.ndarray, outs: dict) -> None:
    """One row per (controller, run): initial state, outcome, metrics."""
    from harv_jax.dynamics import WIND_STATE_NAMES
    from harv_jax.evaluation.metrics import OUTCOME_NAMES

    header = ["controller", "run"] + [f"{n}0" for n in WIND_STATE_NAMES] + [
        "outcome", "recovered", "t_recover_s", "terminal_alpha_err_deg", "terminal_beta_err_deg",
        "terminal_mu_err_deg", "altitude_loss_ft", "control_tv_rad", "chatter_index_rad2",
        "sat_position_fraction", "left_envelope",
    ]  # fmt: skip
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for name, out in outs.items():
            m = out.metrics
            term = np.degrees(out.terminal_error_rad)
            for i in range(x0.shape[0]):
                w.writerow(
                    [
                        name,
                        i,
                        *[f"{v:.6g}" for v in x0[i]],
                        OUTCOME_NAMES[int(m.outcome[i])],
                        bool(m.recovered[i]),
                        f"{m.t_recover_s[i]:.4g}",
                        *[f"{v:.5g}" for v in term[i]],
                        f"{m.altitude_loss_ft[i]:.5g}",
                        f"{np.sum(m.control_tv_rad[i]):.5g}",
                        f"{np.sum(m.chatter_index_rad2[i]):.4g}",
                        f"{np.mean(m.sat_position_fraction[i]):.4g}",
                        bool(m.left_envelope[i]),
                    ]
                )


def run_monte_carlo(
    controllers: list[str],
    policy: str | None,
    runs: int,
    target_alpha: float,
    duration: float,
    seed: int,
    randomize: bool,
    out_dir: Path,
    chunk: int = 250,
    record_every: int = 10,
    progress: bool = True,
    zeta: str = "continuous",
    save_trajectories: bool = False,
) -> dict:
    """Run the Monte Carlo and write summary.json, bands_*.png/.csv (bands_all.png: every controller on
    one figure; all band plots share one y-scale per variable), terminal_errors.png, runs.csv (and
    trajectories_*.npz: t_s [T], alpha_beta_mu_rad [N, T, 3] every ``record_every`` steps, if asked)."""
    import jax
    import jax.numpy as jnp

    from harv_jax.aircraft import harv
    from harv_jax.evaluation.monte_carlo import run_mc, sample_mc_inputs, summarize_controller
    from harv_jax.plotting import (
        band_limits_deg,
        plot_mc_bands,
        plot_mc_bands_overlay,
        plot_terminal_errors,
        write_bands_csv,
    )
    from harv_jax.task.spec import H0_FT  # every run starts at h0

    ctrls = {name: build_controller(name, policy, zeta) for name in controllers}
    dt_s = 0.01
    n_steps = int(round(duration / dt_s))
    n_steps -= n_steps % record_every
    reference = jnp.array([target_alpha, 0.0, 0.0])
    inputs = sample_mc_inputs(jax.random.key(seed), runs, harv(), randomize=randomize, h0_ft=H0_FT)
    summary: dict = {
        "runs": runs, "target_alpha_rad": target_alpha, "duration_s": n_steps * dt_s, "seed": seed,
        "randomize": randomize, "dt_s": dt_s, "h0_ft": H0_FT,
        "policy": (policy or DEFAULT_POLICY_SPEC) if {"rl", "hybrid"} & set(controllers) else None,
        "zeta_schedule": zeta if "hybrid" in controllers else None,
        "devices": [str(d) for d in jax.local_devices()],
        "command": "harv-jax " + " ".join(shlex.quote(a) for a in sys.argv[1:]),
        "controllers": {},
    }  # fmt: skip
    outs = {}
    for name, ctrl in ctrls.items():
        if progress:
            typer.echo(f"[mc] {name}: {runs} runs x {n_steps} steps ...")
        out, wall = run_mc(ctrl, inputs, reference, n_steps, dt_s, record_every, chunk)
        outs[name] = out
        summary["controllers"][name] = summarize_controller(out, wall, n_steps)
        if progress:
            s = summary["controllers"][name]
            typer.echo(
                f"[mc] {name}: recovery {s['recovery_rate']:.3f}, outcomes {s['outcomes']}, "
                f"compile {wall['compile']:.1f} s, run {wall['run']:.1f} s"
            )
        t_rec = np.arange(out.history.shape[1]) * record_every * dt_s
        write_bands_csv(t_rec, out.history, out_dir / f"bands_{name}.csv")
        if save_trajectories:
            np.savez_compressed(
                out_dir / f"trajectories_{name}.npz", t_s=t_rec, alpha_beta_mu_rad=out.history
            )
    histories = {n: o.history for n, o in outs.items()}
    ref = np.asarray(reference)
    lims = band_limits_deg(histories, ref)  # one y-scale per variable across controllers
    setting = f"N = {runs}, alpha_d = {np.degrees(target_alpha):.1f} deg, h0 = {H0_FT:,.0f} ft"
    for name, h in histories.items():
        plot_mc_bands(t_rec, h, ref, out_dir / f"bands_{name}.png",
                      title=f"{name}: Monte Carlo bands ({setting})", ylims_deg=lims)  # fmt: skip
    if len(histories) > 1:
        plot_mc_bands_overlay(t_rec, histories, ref, out_dir / "bands_all.png",
                              title=f"{', '.join(histories)}: Monte Carlo bands ({setting})")  # fmt: skip
    plot_terminal_errors(
        {n: np.degrees(o.terminal_error_rad) for n, o in outs.items()}, out_dir / "terminal_errors.png"
    )
    write_runs_csv(out_dir / "runs.csv", np.asarray(inputs.x0_wind), outs)
    write_json(out_dir / "summary.json", summary)
    return summary


def register(app: typer.Typer) -> None:
    @app.command()
    def mc(
        controller: str = typer.Option("smc", help="Controllers, comma-separated: smc, rl, hybrid."),
        policy: str = policy_option(),
        zeta: str = zeta_option(),
        runs: int = typer.Option(1000, help="Number of Monte Carlo runs."),
        target_alpha: float = typer.Option(0.349, help="Target angle of attack, rad."),
        duration: float = typer.Option(60.0, help="Run length, s."),
        seed: int = typer.Option(0, help="Seed of initial states, aircraft and controller keys."),
        randomize: bool = typer.Option(False, help="Randomize mass, inertia and aero per run."),
        chunk: int = typer.Option(250, help="Runs per compiled call (bounds memory)."),
        out: Path = typer.Option(Path("runs/mc"), help="Output directory."),
        force: bool = typer.Option(False, help="Replace an existing non-empty output directory."),
        save_trajectories: bool = typer.Option(
            False, help="Also write trajectories_<controller>.npz (alpha, beta, mu of every run every 0.1 s)."
        ),
    ) -> None:
        """Monte Carlo: same sampled aircraft/initial states for every controller; summary + figures."""
        from harv_jax.guards import check_closed_loop_batch, check_seed
        from harv_jax.outdir import prepare_out_dir

        names = parse_controllers(controller)
        validate(runs, target_alpha, duration, chunk)
        check_seed(seed)
        check_closed_loop_batch(runs, round(duration / 0.01), 10, chunk, len(names))
        for name in names:
            build_controller(name, policy, zeta)  # fail fast, before creating the output directory
        out_dir = prepare_out_dir(out, force)
        run_monte_carlo(
            names, policy, runs, target_alpha, duration, seed, randomize, out_dir, chunk, zeta=zeta,
            save_trajectories=save_trajectories,
        )  # fmt: skip
        typer.echo(f"wrote {out_dir}/summary.json, bands_*.png/.csv, terminal_errors.png, runs.csv")
