"""Run a training from parsed ``harv-jax train`` options: validate, build, train, write the outputs.

[`run_train`][] is the whole run behind the command (`harv_jax.commands.train` parses the command
line and calls it): a fresh run or ``--resume``, the progress bar, the watchdog and the run folder's outputs.
"""

from __future__ import annotations

import math
import shlex
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from harv_jax.errors import UsageError

if TYPE_CHECKING:
    from harv_jax.training.spec import TrainSpec


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
    spec: TrainSpec | None,
    out: Path | None = None,
    force: bool = False,
    watchdog_s: float | None = None,
    resume: Path | None = None,
) -> dict[str, Any]:
    """Build, train and write the outputs of a run; returns its summary dict. UsageError on bad input.

    A fresh run trains ``spec`` into ``out`` (``force``: replace a folder harv-jax wrote). ``resume``
    continues the run in that folder from its stored spec (``spec`` and ``out`` are then None or that
    folder). ``watchdog_s``: wall seconds without a finished period after which the run stops with exit
    code 3 (None: automatic, see `harv_jax.ppo.watchdog`; 0: no watchdog).
    """
    from harv_jax import runlock
    from harv_jax.outdir import adopt, check_out_dir, read_paths
    from harv_jax.ppo import checkpoint
    from harv_jax.ppo import config as ppo_config
    from harv_jax.training.resume import resume_plan

    check_run_flags(None, None, watchdog_s)
    plan = None
    if resume is not None:
        if spec is not None:
            raise UsageError("--resume continues the stored configuration; give no other settings")
        if out is not None and Path(out).resolve() != Path(resume).resolve():
            raise UsageError(f"--resume writes into its own folder; drop --out {str(out)!r}")
        if not Path(resume).is_dir():
            raise UsageError(f"--resume {str(resume)!r} is not a directory")
        runlock.check_free(resume, "--resume")
        plan = resume_plan(Path(resume))
        spec = plan.spec
        out_dir = Path(resume)
        runlock.acquire(out_dir, "--resume")  # refused while another harv-jax process writes there
        checkpoint.remove_stale_tmp(out_dir / "checkpoints")  # left by a save that was killed
        adopt(out_dir, resume_command(out_dir))
    else:
        if spec is None:
            raise ValueError("run_train needs a spec or a folder to resume")
        if out is None:
            raise UsageError("--out DIR is required (or --resume DIR)")
        preset_file = spec.preset if spec.preset.endswith(".toml") else None
        reads = read_paths(preset_file, spec.init_policy, spec.ppo.demos)
        check_out_dir(out, force, reads)  # a bad --out fails before the env is built
    cfg = spec.ppo

    import jax
    from rich.console import Console

    from harv_jax.outdir import prepare_out_dir
    from harv_jax.plots.training import plot_training_curve
    from harv_jax.ppo import sharding
    from harv_jax.ppo.runner import run_training
    from harv_jax.task.measurement_path import path_record
    from harv_jax.training import outputs
    from harv_jax.training.eval_hook import make_eval_hook
    from harv_jax.training.stall import make_watchdog
    from harv_jax.training.start import build_training, write_run_record
    from harv_jax.training.tensorboard import TensorBoardWriter

    ppo_config.check_devices(cfg, len(sharding.default_devices()))
    setup = build_training(spec)  # before --out is touched
    env_params, trainer = setup.env_params, setup.trainer
    if resume is None:
        out_dir = prepare_out_dir(out, force, reads, resume_command=resume_command(out))
        write_run_record(out_dir, spec, env_params, setup.demos)
    hook, eval_desc = make_eval_hook(trainer, spec, env_params, out_dir)
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
                env_config=spec.env_settings(),
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
    path = None if spec.path is None else path_record(spec.path)
    best = outputs.export_policies(
        out_dir, result.state, result.trainer, cfg, history, spec.loop, demos, path
    )
    summary = outputs.run_summary(out_dir, history, best, spec.target_recovery)
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
