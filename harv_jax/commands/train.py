"""`harv-jax train`: PPO on the recovery env from a preset, with overrides, checkpoints and resume.

Outputs in ``--out DIR``: ``config.json``, ``metrics.csv`` (one row per period: mean, std and per-seed value
of every metric), TensorBoard event files in ``tb/`` (if tensorboardX is installed), ``checkpoints/``,
``training_curve.png`` (mean episode return +- std over seeds vs env steps) and ``policy/`` (``policy.npz``
and ``policy.stablehlo`` of the best seed by final mean return, ``policy_seed<i>.npz`` for every seed).

``--resume DIR`` continues from the newest intact checkpoint (a damaged newer one is skipped, renamed
``*.corrupt`` and named in a message); a run folder killed before its first checkpoint is restarted from
period 0 with the configuration in its ``config.json``. A watchdog (``--watchdog-s``,
:mod:`harv_jax.ppo.watchdog`) ends a stalled run with a one-line error and exit code 3; its checkpoints stay
intact, so ``--resume`` continues it. ``--demos FILE`` (or ``[ppo] demos``) adds behaviour cloning on
demonstrations written by ``harv-jax optimal --save-demos`` (:mod:`harv_jax.training.demos`). The work is
done by the recipe in :mod:`harv_jax.training`.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

import numpy as np
import typer

from harv_jax.cli_options import aircraft_option, real_number, whole_number
from harv_jax.errors import UsageError


def _fmt(row: dict[str, Any], key: str) -> str:
    if key not in row:
        return "-"
    v = np.asarray(row[key], np.float64).reshape(-1)
    v = v[np.isfinite(v)]
    return f"{v.mean():.4g}" if v.size else "nan"


def _per_seed(row: dict[str, Any], key: str, spec: str = ".2f") -> str:
    """Each seed's value of ``key``, slash-separated (``1.00/0.98/1.00``)."""
    if key not in row:
        return "-"
    return "/".join(format(x, spec) for x in np.asarray(row[key], np.float64).reshape(-1))


def check_run_flags(periods: int | None, checkpoint_every: int | None, watchdog_s: float | None) -> None:
    """One-line UsageErrors for --periods, --checkpoint-every and --watchdog-s (before anything is built)."""
    for flag, v in (("--periods", periods), ("--checkpoint-every", checkpoint_every)):
        if v is not None and v <= 0:
            raise UsageError(f"{flag} {v} must be a positive integer")
    if watchdog_s is not None and (not math.isfinite(watchdog_s) or watchdog_s < 0):
        raise UsageError(f"--watchdog-s {watchdog_s} must be a finite number of seconds >= 0 (0: off)")


def check_periods(cfg: Any, periods: int | None) -> None:
    """``--periods N`` cannot exceed the number of PPO updates (a period is at least one update)."""
    from harv_jax.ppo import config as ppo_config

    updates = math.ceil(cfg.total_steps / ppo_config.batch_size(cfg))
    if periods is not None and periods > updates:
        raise UsageError(
            f"--periods {periods} exceeds the {updates} PPO updates of this run "
            f"(--steps {cfg.total_steps} / (num_envs {cfg.num_envs} x unroll {cfg.unroll})); "
            f"at most {updates}"
        )


@functools.cache
def _shown_presets() -> tuple[tuple[str, Any], ...]:
    """(name, PPOConfig) of every shipped preset, the default first (those that load)."""
    from harv_jax.training.presets import DEFAULT_PRESET, available_presets, load_preset

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


# ---------------------------------------------------------------------------------------------- command


def _progress(console: Any) -> Any:
    """The progress bar of a run: steps, speed, ETA, return, recovered, |w|end and the last evaluation."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    return Progress(
        TextColumn("[bold]train"),
        BarColumn(),
        TextColumn("{task.completed:,.0f}/{task.total:,.0f} steps"),
        TextColumn("{task.fields[sps]} steps/s"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        TextColumn(
            "return {task.fields[ret]}  recovered {task.fields[rec]}  |w|end {task.fields[omega]}"
            "  eval {task.fields[ev]}"
        ),
        console=console,
        transient=False,
    )


def run_train(
    preset: str | None,
    overrides: dict[str, Any],
    out: Path | None,
    resume: Path | None,
    force: bool,
    init_policy: str | None = None,
    target_recovery: float | None = None,
    watchdog_s: float | None = None,
    in_loop: str | None = None,
    aircraft: str | None = None,
) -> dict[str, Any]:
    """Validate, build, train, write outputs; returns a summary dict. Raises UsageError on bad input.

    ``init_policy``: a policy spec (``shipped:partial``, a ``.npz`` or checkpoint path[@seed]) every seed
    starts from instead of a random initialization (fine-tuning; recorded in ``config.json``).
    ``target_recovery``: stop at the first evaluation (``[eval]``) where every seed's RL-only recovery
    fraction is at least this (evaluation then runs every period unless ``[eval] every`` says otherwise).
    ``watchdog_s``: wall seconds without a finished period after which the run stops with exit code 3
    (None: automatic, see :mod:`harv_jax.ppo.watchdog`; 0: no watchdog).
    ``in_loop``: ``hybrid[:schedule]`` trains with the hybrid law inside the env step
    (:mod:`harv_jax.training.in_loop`); recorded in ``config.json`` and in the policy files.
    ``aircraft``: the env's nominal aircraft, a name of ``harv_jax.aircraft.registry`` (None: the preset's
    ``[env] aircraft``, else the registry's default); recorded as ``aircraft`` in the env settings.
    """
    if target_recovery is not None and not (math.isfinite(target_recovery) and 0 < target_recovery <= 1):
        raise UsageError(f"--target-recovery {target_recovery} must be in (0, 1]")
    from harv_jax import runlock
    from harv_jax.aircraft.registry import DEFAULT_AIRCRAFT
    from harv_jax.outdir import check_out_dir
    from harv_jax.ppo import checkpoint
    from harv_jax.ppo import config as ppo_config
    from harv_jax.training.in_loop import LOOP_KEY, parse_loop, split_loop
    from harv_jax.training.presets import DEFAULT_PRESET, build_config
    from harv_jax.training.resume import resume_plan

    check_run_flags(overrides.get("num_periods"), overrides.get("checkpoint_every"), watchdog_s)
    plan = None
    if (overrides.get("demos") or "").strip():  # from the current directory, recorded absolute
        from harv_jax.training.demos import resolve_demos_path

        overrides = {**overrides, "demos": resolve_demos_path(overrides["demos"])}
    if resume is not None:
        given = ["--preset"] if preset is not None else []
        given += [ppo_config.flag_name(k) for k, v in sorted(overrides.items()) if v is not None]
        given += ["--init-policy"] if init_policy is not None else []
        given += ["--in-loop"] if in_loop is not None else []
        given += ["--aircraft"] if aircraft is not None else []
        if given:
            raise UsageError(f"--resume continues the stored configuration; drop {given[0]}")
        if out is not None and Path(out).resolve() != Path(resume).resolve():
            raise UsageError(f"--resume writes into its own folder; drop --out {str(out)!r}")
        if not Path(resume).is_dir():
            raise UsageError(f"--resume {str(resume)!r} is not a directory")
        runlock.check_free(resume, "--resume")
        plan = resume_plan(Path(resume))
        cfg, env_table, init_policy = plan.cfg, plan.env_table, plan.init_policy
        out_dir = Path(resume)
        runlock.acquire(out_dir, "--resume")  # refused while another harv-jax process writes there
        checkpoint.remove_stale_tmp(out_dir / "checkpoints")  # left by a save that was killed
    else:
        if out is None:
            raise UsageError("--out DIR is required (or --resume DIR)")
        cfg, env_table = build_config(preset or DEFAULT_PRESET, overrides)
        check_periods(cfg, overrides.get("num_periods"))
        if in_loop is not None:
            env_table = {**env_table, LOOP_KEY: parse_loop(in_loop)}
        env_table = {**env_table, "aircraft": aircraft or env_table.get("aircraft", DEFAULT_AIRCRAFT)}
        check_out_dir(out, force)  # a bad --out fails before the env is built
    loop = split_loop(env_table)[0]

    import jax
    from rich.console import Console

    from harv_jax.outdir import prepare_out_dir
    from harv_jax.plots.training import plot_training_curve
    from harv_jax.ppo import sharding
    from harv_jax.ppo.runner import run_training
    from harv_jax.training import outputs
    from harv_jax.training.eval_hook import make_eval_hook
    from harv_jax.training.stall import make_watchdog
    from harv_jax.training.start import build_training, write_run_record
    from harv_jax.training.tensorboard import TensorBoardWriter

    ppo_config.check_devices(cfg, len(sharding.default_devices()))
    fresh_init = init_policy if plan is None or not plan.from_checkpoint else None  # before --out is touched
    setup = build_training(cfg, env_table, fresh_init, plan.demos_sha256 if plan is not None else None)
    env_params, trainer = setup.env_params, setup.trainer
    if resume is None:
        out_dir = prepare_out_dir(out, force)
        write_run_record(out_dir, preset or DEFAULT_PRESET, cfg, env_table, env_params, init_policy,
                         target_recovery, setup.demos)  # fmt: skip
    hook, eval_desc = make_eval_hook(trainer, cfg, env_params, env_table, target_recovery, out_dir)
    n_periods = ppo_config.num_periods(cfg)
    total = n_periods * ppo_config.steps_per_period(cfg)
    start_steps = plan.env_steps if plan is not None else 0
    tb = TensorBoardWriter(out_dir / "tb", purge_step=start_steps if resume is not None else None)

    console = Console(stderr=True)
    for line in plan.messages if plan is not None else ():
        console.print(f"harv-jax: {line}", soft_wrap=True, markup=False, highlight=False)
    dog = make_watchdog(watchdog_s, out_dir, console)
    progress = _progress(console)
    task = progress.add_task(
        "train", total=total, completed=start_steps, sps="-", ret="-", rec="-", omega="-", ev="-"
    )
    if eval_desc:
        console.print(eval_desc)
    last_eval = ["-"]

    def on_period(p: int, row: dict[str, Any]) -> None:
        if dog is not None:
            dog.beat()
        sps = cfg.num_seeds * ppo_config.steps_per_period(cfg) / max(row["period_s"], 1e-9)
        fields = {
            "sps": f"{sps:,.0f}",
            "ret": _fmt(row, "episode_return"),
            "rec": _fmt(row, "episode/recovered"),
            "omega": _fmt(row, "episode/final_omega_radps"),
        }
        if "eval/recovered" in row:
            last_eval[0] = (f"recovered {_per_seed(row, 'eval/recovered')} "
                            f"(spin {_per_seed(row, 'eval/recovered_spin')}), "
                            f"t_rec mean {_per_seed(row, 'eval/t_recover_mean_s', '.3g')} s")  # fmt: skip
        fields["ev"] = last_eval[0]
        progress.update(task, completed=row["env_steps"], **fields)
        if not console.is_terminal:
            console.print(
                f"period {row['period']}/{n_periods} steps {row['env_steps']:,} ({fields['sps']} steps/s) "
                f"return {fields['ret']} recovered {fields['rec']} |w|end {fields['omega']} "
                f"eval {fields['ev']}",
                soft_wrap=True,
            )
        tb.write(row)

    key = jax.random.key(cfg.seed)
    if dog is not None:
        dog.start()
    try:
        with progress:
            result = run_training(
                key, setup.env, env_params, cfg, run_dir=out_dir,
                resume=plan is not None and plan.from_checkpoint, env_config=env_table, progress_fn=on_period,
                trainer=trainer, init_policy=setup.init_policy, period_hook=hook,
            )  # fmt: skip
    finally:
        if dog is not None:
            dog.stop()
    tb.close()
    history = result.history
    outputs.write_metrics_csv(out_dir / "metrics.csv", history)
    if history:
        plot_training_curve(out_dir / "training_curve.png", history,
                            f"harv-jax train: {cfg.num_seeds} seed(s), {cfg.num_envs} envs")  # fmt: skip
    demos = None if setup.demos is None else setup.demos.record()
    best = outputs.export_policies(out_dir, result.state, result.trainer, cfg, history, loop, demos)
    summary = outputs.run_summary(out_dir, history, best, target_recovery)
    if demos is not None:
        summary["demos"] = demos
    outputs.write_summary(out_dir / "summary.json", summary)
    if "seeds" in summary:
        console.print(f"harv-jax: {outputs.seed_verdict(summary['seeds'])}", soft_wrap=True, markup=False,
                      highlight=False)  # fmt: skip
    return summary


def register(app: typer.Typer) -> None:
    @app.command()
    @aircraft_option
    def train(
        preset: str = typer.Option(
            None,
            help=f"Preset shipped with the package ({', '.join(name for name, _ in _shown_presets())}) or "
            "a path to a .toml; the first is the default.",
        ),  # fmt: skip
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
        seed: int = typer.Option(
            None, parser=whole_number, help="Base seed (>= 0). " + preset_defaults("seed")
        ),
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
        force: bool = typer.Option(False, help="Replace an existing non-empty --out directory."),
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
        overrides = {"total_steps": steps, "num_envs": num_envs, "unroll": unroll, "epochs": epochs,
                     "minibatches": minibatches, "lr": lr, "num_seeds": seeds, "seed": seed,
                     "num_periods": periods, "checkpoint_every": checkpoint_every}  # fmt: skip
        overrides["demos"] = demos
        summary = run_train(
            preset,
            overrides,
            out,
            resume,
            force,
            init_policy,
            target_recovery=target_recovery,
            watchdog_s=watchdog_s,
            in_loop=in_loop,
            aircraft=aircraft_name,
        )
        ret = summary.get("episode_return", {})
        rec = summary.get("episode/recovered", {})
        typer.echo(
            f"wrote {summary['out']} ({summary['periods']} periods, "
            f"{summary['env_steps_per_seed']:,} steps/seed); "
            f"mean return {ret.get('first_mean', math.nan):.4g} -> {ret.get('last_mean', math.nan):.4g} "
            f"(+- {ret.get('last_std', math.nan):.3g} over seeds), recovered at episode end "
            f"{rec.get('last_mean', math.nan):.3f}; best seed {summary['best_seed']}"
        )
