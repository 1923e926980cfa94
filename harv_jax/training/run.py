"""Run a training from parsed ``harv-jax train`` options: validate, build, train, write the outputs.

[`run_train`][] is the whole run behind the command (`harv_jax.commands.train` parses the command
line and calls it): a fresh run or ``--resume``, the progress bar, the watchdog and the run folder's outputs.
"""

from __future__ import annotations

import math
import shlex
from pathlib import Path
from typing import Any

import numpy as np

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


def resume_command(out: str | Path) -> str:
    """The command that continues the training run in ``out``."""
    return f"harv-jax train --resume {shlex.quote(str(out))}"


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
    (None: automatic, see `harv_jax.ppo.watchdog`; 0: no watchdog).
    ``in_loop``: ``hybrid[:schedule]`` trains with the hybrid law inside the env step
    ([`harv_jax.training.in_loop`][]); recorded in ``config.json`` and in the policy files.
    ``aircraft``: the env's nominal aircraft, a name of ``harv_jax.aircraft.registry`` (None: the preset's
    ``[env] aircraft``, else the registry's default); recorded as ``aircraft`` in the env settings.
    """
    if target_recovery is not None and not (math.isfinite(target_recovery) and 0 < target_recovery <= 1):
        raise UsageError(f"--target-recovery {target_recovery} must be in (0, 1]")
    from harv_jax import runlock
    from harv_jax.aircraft.registry import DEFAULT_AIRCRAFT
    from harv_jax.outdir import adopt, check_out_dir, read_paths
    from harv_jax.ppo import checkpoint
    from harv_jax.ppo import config as ppo_config
    from harv_jax.training import time_to_go
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
        adopt(out_dir, resume_command(out_dir))
    else:
        if out is None:
            raise UsageError("--out DIR is required (or --resume DIR)")
        cfg, env_table = build_config(preset or DEFAULT_PRESET, overrides)
        check_periods(cfg, overrides.get("num_periods"))
        if in_loop is not None:
            env_table = {**env_table, LOOP_KEY: parse_loop(in_loop)}
        env_table = {**env_table, "aircraft": aircraft or env_table.get("aircraft", DEFAULT_AIRCRAFT)}
        env_table = time_to_go.pin_file_digest(env_table)  # --resume refuses the file if it changes
        reads = read_paths(preset, init_policy, overrides.get("demos"), env_table.get(time_to_go.FILE_KEY))
        check_out_dir(out, force, reads)  # a bad --out fails before the env is built
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
        out_dir = prepare_out_dir(out, force, reads, resume_command=resume_command(out))
        write_run_record(
            out_dir,
            preset or DEFAULT_PRESET,
            cfg,
            env_table,
            env_params,
            init_policy,
            target_recovery,
            setup.demos,
        )
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
            last_eval[0] = (
                f"recovered {_per_seed(row, 'eval/recovered')} "
                f"(spin {_per_seed(row, 'eval/recovered_spin')}), "
                f"t_rec mean {_per_seed(row, 'eval/t_recover_mean_s', '.3g')} s"
            )
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
                key,
                setup.env,
                env_params,
                cfg,
                run_dir=out_dir,
                resume=plan is not None and plan.from_checkpoint,
                env_config=env_table,
                progress_fn=on_period,
                trainer=trainer,
                init_policy=setup.init_policy,
                period_hook=hook,
            )
    finally:
        if dog is not None:
            dog.stop()
    tb.close()
    history = result.history
    outputs.write_metrics_csv(out_dir / "metrics.csv", history)
    if history:
        plot_training_curve(
            out_dir / "training_curve.png",
            history,
            f"harv-jax train: {cfg.num_seeds} seed(s), {cfg.num_envs} envs",
        )
    demos = None if setup.demos is None else setup.demos.record()
    best = outputs.export_policies(out_dir, result.state, result.trainer, cfg, history, loop, demos)
    summary = outputs.run_summary(out_dir, history, best, target_recovery)
    if demos is not None:
        summary["demos"] = demos
    outputs.write_summary(out_dir / "summary.json", summary)
    if "seeds" in summary:
        console.print(
            f"harv-jax: {outputs.seed_verdict(summary['seeds'])}",
            soft_wrap=True,
            markup=False,
            highlight=False,
        )
    return summary
