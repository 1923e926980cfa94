"""`harv-jax train`: PPO on the recovery env from a preset, with overrides, checkpoints and resume.

Outputs in ``--out DIR``: ``config.json``, ``metrics.csv`` (one row per period: mean, std and per-seed value
of every metric), TensorBoard event files in ``tb/`` (if tensorboardX is installed), ``checkpoints/``,
``training_curve.png`` (mean episode return +- std over seeds vs env steps) and ``policy/`` (``policy.npz``
and ``policy.stablehlo`` of the best seed by final mean return, ``policy_seed<i>.npz`` for every seed).

``--resume DIR`` continues from the newest intact checkpoint (a damaged newer one is skipped, renamed
``*.corrupt`` and named in a message); a run folder killed before its first checkpoint is restarted from
period 0 with the configuration in its ``config.json``. A watchdog (``--watchdog-s``,
`harv_jax.ppo.watchdog`) ends a stalled run with a one-line error and exit code 3; its checkpoints stay
intact, so ``--resume`` continues it. ``--demos FILE`` (or ``[ppo] demos``) adds behaviour cloning on
demonstrations written by ``harv-jax optimal --save-demos`` ([`harv_jax.training.demos`][]). The run is
[`harv_jax.training.run.run_train`][].
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

import typer

from harv_jax.cli_options import aircraft_option, force_option, real_number, whole_number
from harv_jax.errors import UsageError
from harv_jax.training.demos import resolve_demos_path
from harv_jax.training.presets import DEFAULT_PRESET, available_presets, load_preset, load_spec
from harv_jax.training.run import check_periods, check_run_flags, run_train

__all__ = ["preset_defaults", "register", "train"]


@functools.cache
def _shown_presets() -> tuple[tuple[str, Any], ...]:
    """(name, PPOConfig) of every shipped preset, the default first (those that load)."""
    out = []
    for name in sorted(available_presets(), key=lambda n: n != DEFAULT_PRESET):
        try:
            out.append((name, load_preset(name, check_env=False)[0]))
        except UsageError:
            continue
    return tuple(out)


def preset_defaults(field: str) -> str:
    """'Default from --preset: smoke 600,000, paper-partial ...' for a PPO field (help text)."""
    parts = []
    for name, cfg in _shown_presets():
        v = getattr(cfg, field)
        parts.append(f"{name} {v:,}" if isinstance(v, int) and not isinstance(v, bool) else f"{name} {v:g}")
    return ("Default from --preset: " + ", ".join(parts) + ".") if parts else "Default from --preset."


@aircraft_option
def train(
    preset: str = typer.Option(
        None,
        help=f"Preset shipped with the package ({', '.join(name for name, _ in _shown_presets())}) or "
        "a path to a .toml; the first is the default.",
    ),
    steps: int = typer.Option(
        None, parser=whole_number, help="Env steps per seed (> 0). " + preset_defaults("total_steps")
    ),
    num_envs: int = typer.Option(
        None,
        parser=whole_number,
        help="Parallel envs per seed; divisible by the device count. " + preset_defaults("num_envs"),
    ),
    unroll: int = typer.Option(
        None, parser=whole_number, help="Rollout length per update (> 0). " + preset_defaults("unroll")
    ),
    epochs: int = typer.Option(
        None, parser=whole_number, help="PPO epochs per update (> 0). " + preset_defaults("epochs")
    ),
    minibatches: int = typer.Option(
        None,
        parser=whole_number,
        help="Minibatches per epoch; divides num_envs * unroll. " + preset_defaults("minibatches"),
    ),
    lr: float = typer.Option(
        None, parser=real_number, help="Adam learning rate (> 0). " + preset_defaults("lr")
    ),
    seeds: int = typer.Option(
        None,
        parser=whole_number,
        help="Independent policies trained together (vmap). " + preset_defaults("num_seeds"),
    ),
    seed: int = typer.Option(None, parser=whole_number, help="Base seed (>= 0). " + preset_defaults("seed")),
    periods: int = typer.Option(
        None,
        parser=whole_number,
        help="Host periods (progress line, metrics row, checkpoint chance) over the run; at most the "
        "number of PPO updates. " + preset_defaults("num_periods"),
    ),
    checkpoint_every: int = typer.Option(
        None,
        parser=whole_number,
        help="Write a checkpoint every K periods (and after the last). "
        + preset_defaults("checkpoint_every"),
    ),
    watchdog_s: float = typer.Option(
        None,
        parser=real_number,
        help="Stop a stalled run (exit code 3, checkpoints intact) when no period finishes for this many "
        "seconds, or when the process uses no CPU for min(this, 300) s. Default automatic: 3600 s for "
        "the first period (it includes compilation), then max(600 s, 20 x the first period), and 300 s "
        "without CPU use. 0: off.",
    ),
    out: Path = typer.Option(None, help="Output directory (new, or empty, or with --force)."),
    resume: Path = typer.Option(
        None,
        help="Continue the run in this directory from its newest intact checkpoint (a damaged newer one "
        "is skipped and kept as *.corrupt); a run stopped before its first checkpoint restarts from "
        "period 0 with its config.json.",
    ),
    force: bool = force_option("non-empty --out directory"),
    init_policy: str = typer.Option(
        None,
        help="Start every seed from this policy (shipped:NAME, or a path\\[@seed]): fine-tuning.",
    ),
    target_recovery: float = typer.Option(
        None,
        parser=real_number,
        help="Stop once every seed's recovery fraction in the [eval] batch reaches this (0-1].",
    ),
    in_loop: str = typer.Option(
        None,
        help="Train with a controller in the loop: hybrid[:SCHEDULE] (default schedule gated) applies "
        "u = u_RL + zeta u_SMC inside the env step, the policy's action being u_RL. Default none.",
    ),
    demos: str = typer.Option(
        None,
        help="Also clone these demonstrations (a .npz of harv-jax optimal --save-demos; its recovered "
        "runs) with the preset's bc_coef schedule; overrides [ppo] demos. Default the preset's (none).",
    ),
    aircraft_name: str | None = None,
) -> None:
    """Train PPO policies (several seeds at once) on the spin/upset recovery env."""
    check_run_flags(periods, checkpoint_every, watchdog_s)
    if resume is not None:  # the stored spec: a setting given here would be ignored
        settings = {
            "--preset": preset,
            "--steps": steps,
            "--num-envs": num_envs,
            "--unroll": unroll,
            "--epochs": epochs,
            "--minibatches": minibatches,
            "--lr": lr,
            "--seeds": seeds,
            "--seed": seed,
            "--periods": periods,
            "--checkpoint-every": checkpoint_every,
            "--demos": demos,
            "--init-policy": init_policy,
            "--in-loop": in_loop,
            "--aircraft": aircraft_name,
            "--target-recovery": target_recovery,
        }
        given = [flag for flag, v in settings.items() if v is not None]
        if given:
            raise UsageError(f"--resume continues the stored configuration; drop {given[0]}")
        summary = run_train(None, out, force, watchdog_s, resume=resume)
    else:
        overrides = {
            "total_steps": steps,
            "num_envs": num_envs,
            "unroll": unroll,
            "epochs": epochs,
            "minibatches": minibatches,
            "lr": lr,
            "num_seeds": seeds,
            "seed": seed,
            "num_periods": periods,
            "checkpoint_every": checkpoint_every,
            # from the current directory, recorded absolute
            "demos": resolve_demos_path(demos) if (demos or "").strip() else demos,
        }
        spec = load_spec(preset, overrides, in_loop, aircraft_name, init_policy, target_recovery)
        check_periods(spec.ppo, periods)
        summary = run_train(spec, out, force, watchdog_s)
    ret = summary.get("episode_return", {})
    rec = summary.get("episode/recovered", {})
    typer.echo(
        f"wrote {summary['out']} ({summary['periods']} periods, "
        f"{summary['env_steps_per_seed']:,} steps/seed); "
        f"mean return {ret.get('first_mean', math.nan):.4g} -> {ret.get('last_mean', math.nan):.4g} "
        f"(+- {ret.get('last_std', math.nan):.3g} over seeds), recovered at episode end "
        f"{rec.get('last_mean', math.nan):.3f}; best seed {summary['best_seed']}"
    )


def register(app: typer.Typer) -> None:
    """Add the command(s) of this module to ``app``."""
    app.command()(train)
