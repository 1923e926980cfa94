"""`harv-jax train`: PPO on the recovery env from a preset, with overrides, checkpoints and resume.

Outputs in ``--out DIR``: ``config.json``, ``metrics.csv`` (one row per period: mean, std and per-seed value
of every metric), TensorBoard event files in ``tb/`` (if tensorboardX is installed), ``checkpoints/``,
``training_curve.png`` (mean episode return +- std over seeds vs env steps) and ``policy/`` (``policy.npz``
and ``policy.stablehlo`` of the best seed by final mean return, ``policy_seed<i>.npz`` for every seed).

``--resume DIR`` continues from the newest intact checkpoint (a damaged newer one is skipped, renamed
``*.corrupt`` and named in a message); a run folder killed before its first checkpoint is restarted from
period 0 with the configuration in its ``config.json``. A watchdog (``--watchdog-s``,
:mod:`harv_jax.ppo.watchdog`) ends a stalled run with a one-line error and exit code 3; its checkpoints stay
intact, so ``--resume`` continues it.
"""

from __future__ import annotations

import csv
import functools
import json
import math
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import typer

from harv_jax.errors import UsageError

#: Metrics shown in the progress bar and summary (name in history -> label).
_SHOWN = {"episode_return": "return", "episode/recovered": "recovered", "episode/final_omega_radps": "|w|end"}


def build_config(
    preset: str,
    overrides: dict[str, Any],
) -> tuple[Any, dict[str, Any]]:
    """Preset + command-line overrides -> (validated PPOConfig, env settings)."""
    from harv_jax.ppo import config as ppo_config

    cfg, env_table = ppo_config.load_preset(preset)
    changes = {k: v for k, v in overrides.items() if v is not None}
    return ppo_config.from_dict(changes, base=cfg, source="command line"), env_table


def make_harv_env(env_table: dict[str, Any], spin_bank: Any = None) -> tuple[Any, Any]:
    """(env, env_params) of the recovery env from a preset's env settings; UsageError if a key is bad.

    ``env_table`` holds the ``[env]`` fields and the nested ``reward``/``randomization``/``spin``/``eval``
    tables (``harv_jax.env.settings``). With spin resets on (``spin.reset_prob`` > 0) the spin bank is
    ``spin_bank`` or, if None, made here from the ``[spin]`` table.
    """
    from harv_jax.env import make_env, settings

    flat, nested = settings.split_tables(env_table)
    env_config = settings.env_config(flat)
    settings.spin_settings(nested["spin"])
    settings.eval_settings(nested["eval"])
    if spin_bank is None:
        spin_bank = settings.build_spin_bank(env_config, nested)
    return make_env(env_config), settings.env_params(env_config, nested, spin_bank)


# ---------------------------------------------------------------------------------------------- outputs


def write_metrics_csv(path: Path, history: list[dict[str, Any]]) -> None:
    """Rewrite ``metrics.csv`` from the whole history (so a resumed run has one row per period)."""
    if not history:
        return
    scalar = ("period", "env_steps", "wall_s", "period_s")
    names = list(dict.fromkeys(k for row in history for k in row if k not in scalar))  # eval rows add keys
    n_seeds = int(np.asarray(history[0][names[0]]).size) if names else 1
    header = list(scalar)
    for k in names:
        header += [k, f"{k}_std"] + [f"{k}/seed{i}" for i in range(n_seeds)]
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        for row in history:
            out = [row[k] for k in scalar]
            for k in names:
                v = np.asarray(row.get(k, np.full(n_seeds, np.nan)), np.float64).reshape(-1)
                finite = v[np.isfinite(v)]
                out += [finite.mean() if finite.size else math.nan, finite.std() if finite.size else math.nan]
                out += list(v)
            w.writerow([f"{x:.6g}" if isinstance(x, float | np.floating) else x for x in out])
    tmp.replace(path)


def plot_training_curve(path: Path, history: list[dict[str, Any]], title: str) -> Path:
    """Mean episode return +- std over seeds vs env steps (the paper's reward-vs-steps figure)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = np.array([row["env_steps"] for row in history], np.float64)
    ret = np.stack([np.asarray(row["episode_return"], np.float64).reshape(-1) for row in history])
    mean, std = np.nanmean(ret, axis=1), np.nanstd(ret, axis=1)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    ax = axes[0]
    ax.plot(steps, mean, color="C0", label=f"mean over {ret.shape[1]} seed(s)")
    ax.fill_between(steps, mean - std, mean + std, color="C0", alpha=0.25, label="+- 1 std")
    for s in range(ret.shape[1]):
        ax.plot(steps, ret[:, s], color="C0", lw=0.6, alpha=0.4)
    ax.set_xlabel("env steps per seed")
    ax.set_ylabel("mean episode return")
    ax.grid(alpha=0.3)
    ax.legend()
    ax = axes[1]
    for k, label, c in (("episode/recovered", "recovered at episode end", "C2"),
                        ("episode/terminated", "terminated (left envelope)", "C3")):  # fmt: skip
        if k in history[0]:
            v = np.stack([np.asarray(row[k], np.float64).reshape(-1) for row in history])
            m, s = np.nanmean(v, axis=1), np.nanstd(v, axis=1)
            ax.plot(steps, m, color=c, label=label)
            ax.fill_between(steps, m - s, m + s, color=c, alpha=0.2)
    ax.set_xlabel("env steps per seed")
    ax.set_ylabel("fraction of episodes")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


class _TensorBoard:
    """Scalars per period to TensorBoard event files (no-op without tensorboardX)."""

    def __init__(self, log_dir: Path, purge_step: int | None) -> None:
        try:
            from tensorboardX import SummaryWriter
        except ImportError:
            self.writer = None
            return
        self.writer = SummaryWriter(str(log_dir), purge_step=purge_step)

    def write(self, row: dict[str, Any]) -> None:
        if self.writer is None:
            return
        step = int(row["env_steps"])
        for k, v in row.items():
            if k in ("period", "env_steps"):
                continue
            a = np.asarray(v, np.float64).reshape(-1)
            if np.any(np.isfinite(a)):
                self.writer.add_scalar(f"train/{k}", float(np.nanmean(a)), step)
        self.writer.flush()

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


def _fmt(row: dict[str, Any], key: str) -> str:
    if key not in row:
        return "-"
    v = np.asarray(row[key], np.float64).reshape(-1)
    v = v[np.isfinite(v)]
    return f"{v.mean():.4g}" if v.size else "nan"


def _nanstat(fn: Any, v: np.ndarray) -> float:
    """``fn`` over the finite entries of ``v``; NaN (without a warning) if there are none."""
    v = v[np.isfinite(v)]
    return float(fn(v)) if v.size else math.nan


def export_seed_policies(pdir: Path, state: Any, trainer: Any, cfg: Any, env_steps: int) -> list[Any]:
    """Write ``pdir/policy_seed<i>.npz`` for every seed; returns the policies."""
    import jax

    from harv_jax import policy as policy_api
    from harv_jax.policy import make_policy, select_seed
    from harv_jax.ppo import config as ppo_config

    params, normalizer = jax.device_get((state.params, state.normalizer))
    pols = []
    for s in range(cfg.num_seeds):
        meta = {"seed": s, "config": ppo_config.to_dict(cfg), "env_steps": env_steps,
                "normalize_observations": cfg.normalize_observations}  # fmt: skip
        pol = make_policy(select_seed(params, s), select_seed(normalizer, s), trainer.networks,
                          cfg.normalize_observations, meta)  # fmt: skip
        policy_api.export_npz(pdir / f"policy_seed{s}.npz", pol)
        pols.append(pol)
    return pols


def export_policies(out_dir: Path, state: Any, trainer: Any, cfg: Any, history: list[dict[str, Any]]) -> int:
    """Write ``policy/policy_seed<i>.npz`` per seed and ``policy.npz``/``policy.stablehlo`` of the best."""
    from harv_jax import policy as policy_api

    last = np.asarray(history[-1]["episode_return"], np.float64).reshape(-1) if history else np.zeros(1)
    best = int(np.nanargmax(np.where(np.isfinite(last), last, -np.inf))) if np.any(np.isfinite(last)) else 0
    pdir = out_dir / "policy"
    pols = export_seed_policies(pdir, state, trainer, cfg, history[-1]["env_steps"] if history else 0)
    policy_api.export_npz(pdir / "policy.npz", pols[best])
    if policy_api.export_available():  # jax.export serialization needs flatbuffers
        policy_api.export_stablehlo(pdir / "policy.stablehlo", pols[best])
    return best


def make_eval_hook(
    trainer: Any,
    cfg: Any,
    env_params: Any,
    env_table: dict[str, Any],
    target_recovery: float | None,
    out_dir: Path | None = None,
) -> tuple[Any, str]:
    """The period hook of evaluation during training (``[eval]`` table), or (None, "") when it is off.

    Every ``eval.every`` periods (and at the last) every seed's deterministic policy flies the fixed batch of
    ``harv_jax.evaluation.policy_eval`` RL-only; its recovery fractions and median recovery time go into the
    period's row. With ``target_recovery`` training stops at the first evaluation where every seed recovers
    at least that fraction (that period's checkpoint is written). With ``out_dir`` every evaluated period's
    policies are kept as ``policy/period_<N>/policy_seed<s>.npz`` (a few kB each).
    """
    import dataclasses

    import jax

    from harv_jax.env import settings
    from harv_jax.evaluation.policy_eval import make_eval_batch, make_policy_eval, summarize_eval
    from harv_jax.ppo import config as ppo_config
    from harv_jax.ppo import normalize as obs_norm
    from harv_jax.ppo.networks import postprocess

    ev = settings.eval_settings(settings.split_tables(env_table)[1]["eval"])
    if target_recovery is not None and not ev.every:
        ev = dataclasses.replace(ev, every=1)
    if not ev.every:
        return None, ""
    batch = make_eval_batch(ev.upset_runs, ev.spin_runs, env_params.aircraft)

    def act(params: Any, normalizer: Any, obs: jax.Array) -> jax.Array:
        obs_in = obs_norm.normalize(normalizer, obs) if cfg.normalize_observations else obs
        mean, _ = trainer.networks.policy(params, obs_in)
        return postprocess(mean)

    evaluate = jax.jit(jax.vmap(make_policy_eval(act, batch, ev.duration_s)))
    n_periods = ppo_config.num_periods(cfg)
    is_spin = jax.device_get(batch.is_spin)

    def hook(p: int, state: Any) -> tuple[dict[str, Any], bool]:
        if (p + 1) % ev.every and p + 1 != n_periods:
            return {}, False
        out = summarize_eval(jax.device_get(evaluate(state.params, state.normalizer)), is_spin)
        stop = target_recovery is not None and bool(np.all(out["eval/recovered"] >= target_recovery))
        if out_dir is not None:
            steps = (p + 1) * ppo_config.steps_per_period(cfg)
            export_seed_policies(out_dir / "policy" / f"period_{p + 1:04d}", state, trainer, cfg, steps)
        return out, stop

    desc = f"evaluation every {ev.every} period(s): {ev.upset_runs} upsets + {ev.spin_runs} spins, RL-only"
    return hook, desc


def save_spin_bank(out_dir: Path, env_table: dict[str, Any], env_params: Any) -> None:
    """``spin_bank.npz`` in the run folder: the bank's states, deflections and provenance (if spin resets)."""
    from harv_jax.env import settings

    flat, nested = settings.split_tables(env_table)
    if settings.spin_settings(nested["spin"]).reset_prob <= 0:
        return
    prov = settings.bank_provenance(settings.env_config(flat), nested)
    np.savez(
        out_dir / "spin_bank.npz",
        x_wind=np.asarray(env_params.spin_states),
        delta_rad=np.asarray(env_params.spin_delta_rad),
        provenance=np.asarray(json.dumps(prov)),
    )


# ---------------------------------------------------------------------------------------------- resume


#: Exit code of a run that the watchdog stopped.
STALL_EXIT_CODE = 3


class ResumePlan(NamedTuple):
    """How ``--resume DIR`` continues: from a checkpoint (``from_checkpoint``) or from period 0."""

    cfg: Any
    env_table: dict[str, Any]
    from_checkpoint: bool
    period: int
    env_steps: int
    init_policy: str | None
    messages: tuple[str, ...]


def resume_plan(run_dir: Path) -> ResumePlan:
    """Decide how to continue the run in ``run_dir``: its newest intact checkpoint, or, if it was stopped
    before writing one, a restart from period 0 with its ``config.json``. UsageError if neither exists."""
    from harv_jax.ppo import checkpoint
    from harv_jax.ppo import config as ppo_config

    ckpt_dir = run_dir / "checkpoints"
    choice = checkpoint.latest_intact(ckpt_dir)
    if choice is not None:
        messages = [
            f"skipping checkpoint {p.name}: {reason.removeprefix(f'checkpoint {str(p)!r} ')}; "
            f"it is kept as {p.name}.corrupt"
            for p, reason in choice.skipped
        ]
        period, steps = int(choice.payload["period"]), int(choice.payload["env_steps"])
        messages.append(f"resuming from period {period} (env steps {steps:,}) of {choice.path}")
        cfg = ppo_config.from_dict(json.loads(choice.payload["config"]), source=choice.path.name)
        env_table = json.loads(choice.payload["env_config"])
        return ResumePlan(cfg, env_table, True, period, steps, None, tuple(messages))
    record_path = run_dir / "config.json"
    if not record_path.is_file():
        raise UsageError(
            f"no checkpoint found in {str(ckpt_dir)!r} and no config.json in {str(run_dir)!r}: "
            "not a harv-jax train run folder; start a new run with --out"
        )
    try:
        record = json.loads(record_path.read_text())
        cfg = ppo_config.from_dict(record["ppo"], source=str(record_path))
        env_table = dict(record.get("env", {}))
        init_policy = record.get("init_policy")
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise UsageError(
            f"no checkpoint found in {str(ckpt_dir)!r} and {str(record_path)!r} is unreadable "
            f"({type(e).__name__}); start the run again with --out {str(run_dir)!r} --force"
        ) from None
    msg = (f"no checkpoint in {ckpt_dir} (the run stopped before its first one): restarting it from "
           "period 0 with the configuration in its config.json")  # fmt: skip
    return ResumePlan(cfg, env_table, False, 0, 0, init_policy, (msg,))


def _stall_handler(out_dir: Path, console: Any) -> Any:
    """``on_stall`` for the CLI: all threads' Python stacks to ``stall_traceback.txt``, one line, exit 3.

    The process ends with ``os._exit`` (a deadlocked XLA runtime cannot be unwound); a checkpoint is written
    atomically, so the newest complete one stays loadable whenever this fires.
    """
    import faulthandler
    import os
    import sys

    def on_stall(reason: str) -> None:
        try:
            with open(out_dir / "stall_traceback.txt", "w") as f:
                faulthandler.dump_traceback(f, all_threads=True)
        except OSError:
            pass
        try:
            console.file.flush()
        except Exception:  # noqa: BLE001 - the progress display must not stop the exit
            pass
        from harv_jax.ppo import checkpoint

        files = checkpoint.checkpoint_paths(out_dir / "checkpoints")
        kept = f"its newest checkpoint {files[-1].name} is intact" if files else "no checkpoint written yet"
        line = (f"harv-jax: error: training stalled: {reason}; {kept}: continue with "
                f"harv-jax train --resume {out_dir}")  # fmt: skip
        print(line, file=sys.stderr, flush=True)
        os._exit(STALL_EXIT_CODE)

    return on_stall


def make_watchdog(watchdog_s: float | None, out_dir: Path, console: Any) -> Any:
    """The CLI's :class:`~harv_jax.ppo.watchdog.Watchdog` (not started); ``watchdog_s`` 0 turns it off."""
    from harv_jax.ppo.watchdog import Watchdog

    if watchdog_s == 0:
        return None
    # an explicit limit also shortens the no-CPU-use limit (so a short --watchdog-s acts quickly)
    idle_s = None if watchdog_s is None else watchdog_s
    kw = {} if idle_s is None else {"idle_s": min(idle_s, 300.0), "poll_s": min(5.0, max(0.2, idle_s / 5))}
    return Watchdog(_stall_handler(out_dir, console), limit_s=watchdog_s, **kw)


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


#: Preset fields shown in the help of the flag that overrides them.
_PRESETS_SHOWN = ("smoke", "paper-partial", "paper-full")


@functools.cache
def _shown_presets() -> tuple[tuple[str, Any], ...]:
    """(name, PPOConfig) of the presets named in the help (those that load)."""
    from harv_jax.ppo import config as ppo_config

    out = []
    for name in _PRESETS_SHOWN:
        try:
            out.append((name, ppo_config.load_preset(name)[0]))
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


def run_train(
    preset: str | None,
    overrides: dict[str, Any],
    out: Path | None,
    resume: Path | None,
    force: bool,
    init_policy: str | None = None,
    target_recovery: float | None = None,
    watchdog_s: float | None = None,
) -> dict[str, Any]:
    """Validate, build, train, write outputs; returns a summary dict. Raises UsageError on bad input.

    ``init_policy``: a policy spec (``shipped:partial``, a ``.npz`` or checkpoint path[@seed]) every seed
    starts from instead of a random initialization (fine-tuning; recorded in ``config.json``).
    ``target_recovery``: stop at the first evaluation (``[eval]``) where every seed's RL-only recovery
    fraction is at least this (evaluation then runs every period unless ``[eval] every`` says otherwise).
    ``watchdog_s``: wall seconds without a finished period after which the run stops with exit code 3
    (None: automatic, see :mod:`harv_jax.ppo.watchdog`; 0: no watchdog).
    """
    if target_recovery is not None and not (math.isfinite(target_recovery) and 0 < target_recovery <= 1):
        raise UsageError(f"--target-recovery {target_recovery} must be in (0, 1]")
    from harv_jax.ppo import checkpoint
    from harv_jax.ppo import config as ppo_config

    check_run_flags(overrides.get("num_periods"), overrides.get("checkpoint_every"), watchdog_s)
    plan = None
    if resume is not None:
        given = ["--preset"] if preset is not None else []
        given += [ppo_config.flag_name(k) for k, v in sorted(overrides.items()) if v is not None]
        given += ["--init-policy"] if init_policy is not None else []
        if given:
            raise UsageError(f"--resume continues the stored configuration; drop {given[0]}")
        if out is not None and Path(out).resolve() != Path(resume).resolve():
            raise UsageError(f"--resume writes into its own folder; drop --out {str(out)!r}")
        if not Path(resume).is_dir():
            raise UsageError(f"--resume {str(resume)!r} is not a directory")
        plan = resume_plan(Path(resume))
        cfg, env_table, init_policy = plan.cfg, plan.env_table, plan.init_policy
        out_dir = Path(resume)
        checkpoint.remove_stale_tmp(out_dir / "checkpoints")  # left by a save that was killed
    else:
        if out is None:
            raise UsageError("--out DIR is required (or --resume DIR)")
        cfg, env_table = build_config(preset or "smoke", overrides)
        check_periods(cfg, overrides.get("num_periods"))

    import jax

    from harv_jax.outdir import prepare_out_dir
    from harv_jax.ppo.train import default_devices, harv_episode_metrics, make_train, run_training

    ppo_config.check_devices(cfg, len(default_devices()))
    env, env_params = make_harv_env(env_table)
    trainer = make_train(env, cfg, env_params, episode_metrics_fn=harv_episode_metrics)
    init = None
    if init_policy is not None and (plan is None or not plan.from_checkpoint):  # before --out is touched
        from harv_jax.policy import resolve_policy
        from harv_jax.ppo.train import check_init_policy

        pol = resolve_policy(init_policy)
        init = (pol.params, pol.normalizer)
        keys = jax.random.split(jax.random.key(0), cfg.num_seeds)
        try:  # against the run's abstract state: nothing is allocated
            check_init_policy(jax.eval_shape(trainer.init, keys, env_params), *init)
        except ValueError as e:
            raise UsageError(f"--init-policy {init_policy!r}: {e}") from None
    if resume is None:
        out_dir = prepare_out_dir(out, force)
        record = {"preset": preset or "smoke", "ppo": ppo_config.to_dict(cfg), "env": env_table}
        if init_policy is not None:
            record["init_policy"] = init_policy
        if target_recovery is not None:
            record["target_recovery"] = target_recovery
        (out_dir / "config.json").write_text(json.dumps(record, indent=2))
        save_spin_bank(out_dir, env_table, env_params)
    hook, eval_desc = make_eval_hook(trainer, cfg, env_params, env_table, target_recovery, out_dir)
    n_periods = ppo_config.num_periods(cfg)
    total = n_periods * ppo_config.steps_per_period(cfg)
    start_steps = plan.env_steps if plan is not None else 0
    tb = _TensorBoard(out_dir / "tb", purge_step=start_steps if resume is not None else None)
    history_box: list[list[dict[str, Any]]] = [[]]

    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    console = Console(stderr=True)
    for line in plan.messages if plan is not None else ():
        console.print(f"harv-jax: {line}", soft_wrap=True, markup=False, highlight=False)
    dog = make_watchdog(watchdog_s, out_dir, console)
    progress = Progress(
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
    task = progress.add_task(
        "train", total=total, completed=start_steps, sps="-", ret="-", rec="-", omega="-", ev="-"
    )
    if eval_desc:
        console.print(eval_desc)
    last_eval = ["-"]

    def on_period(p: int, row: dict[str, Any]) -> None:
        if dog is not None:
            dog.beat()
        history_box[0].append(row)
        sps = cfg.num_seeds * ppo_config.steps_per_period(cfg) / max(row["period_s"], 1e-9)
        fields = {
            "sps": f"{sps:,.0f}",
            "ret": _fmt(row, "episode_return"),
            "rec": _fmt(row, "episode/recovered"),
            "omega": _fmt(row, "episode/final_omega_radps"),
        }
        if "eval/recovered" in row:
            last_eval[0] = (f"recovered {_fmt(row, 'eval/recovered')} "
                            f"(spin {_fmt(row, 'eval/recovered_spin')}), "
                            f"t_rec {_fmt(row, 'eval/t_recover_median_s')} s")  # fmt: skip
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
                key, env, env_params, cfg, run_dir=out_dir, resume=plan is not None and plan.from_checkpoint,
                env_config=env_table, progress_fn=on_period, trainer=trainer, init_policy=init,
                period_hook=hook,
            )  # fmt: skip
    finally:
        if dog is not None:
            dog.stop()
    tb.close()
    history = result.history
    write_metrics_csv(out_dir / "metrics.csv", history)
    if history:
        plot_training_curve(out_dir / "training_curve.png", history,
                            f"harv-jax train: {cfg.num_seeds} seed(s), {cfg.num_envs} envs")  # fmt: skip
    best = export_policies(out_dir, result.state, result.trainer, cfg, history)
    summary = {"out": str(out_dir), "periods": len(history), "best_seed": best,
               "env_steps_per_seed": history[-1]["env_steps"] if history else 0}  # fmt: skip
    evals = [row for row in history if "eval/recovered" in row]
    if evals:
        summary["eval"] = {k: np.asarray(v, np.float64).reshape(-1).tolist() for k, v in evals[-1].items()
                           if k.startswith("eval/")}  # fmt: skip
        summary["eval"]["env_steps"] = evals[-1]["env_steps"]
        summary["eval"]["wall_s"] = evals[-1]["wall_s"]
        if target_recovery is not None:
            reached = [r for r in evals if np.all(np.asarray(r["eval/recovered"]) >= target_recovery)]
            summary["target_reached_at_env_steps"] = reached[0]["env_steps"] if reached else None
    for k in ("episode_return", "episode/recovered", "episode/final_omega_radps", "episode/terminated"):
        if history and k in history[-1]:
            first = np.asarray(history[0][k], np.float64).reshape(-1)
            last = np.asarray(history[-1][k], np.float64).reshape(-1)
            summary[k] = {"first_mean": _nanstat(np.nanmean, first), "last_mean": _nanstat(np.nanmean, last),
                          "last_std": _nanstat(np.nanstd, last)}  # fmt: skip
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def register(app: typer.Typer) -> None:
    @app.command()
    def train(
        preset: str = typer.Option(
            None,
            help="Preset (experiments/presets, shipped with the package): smoke, paper-partial, "
            "paper-full (or a path to a .toml). Default smoke.",
        ),  # fmt: skip
        steps: int = typer.Option(None, help="Env steps per seed (> 0). " + preset_defaults("total_steps")),
        num_envs: int = typer.Option(
            None, help="Parallel envs per seed; divisible by the device count. " + preset_defaults("num_envs")
        ),
        unroll: int = typer.Option(
            None, help="Rollout length per update (> 0). " + preset_defaults("unroll")
        ),
        epochs: int = typer.Option(None, help="PPO epochs per update (> 0). " + preset_defaults("epochs")),
        minibatches: int = typer.Option(
            None, help="Minibatches per epoch; divides num_envs * unroll. " + preset_defaults("minibatches")
        ),
        lr: float = typer.Option(None, help="Adam learning rate (> 0). " + preset_defaults("lr")),
        seeds: int = typer.Option(
            None, help="Independent policies trained together (vmap). " + preset_defaults("num_seeds")
        ),
        seed: int = typer.Option(None, help="Base seed (>= 0). " + preset_defaults("seed")),
        periods: int = typer.Option(
            None,
            help="Host periods (progress line, metrics row, checkpoint chance) over the run; at most the "
            "number of PPO updates. " + preset_defaults("num_periods"),
        ),
        checkpoint_every: int = typer.Option(
            None,
            help="Write a checkpoint every K periods (and after the last). "
            + preset_defaults("checkpoint_every"),
        ),
        watchdog_s: float = typer.Option(
            None,
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
            help="Stop once every seed's RL-only recovery fraction in the [eval] batch reaches this (0-1].",
        ),
    ) -> None:
        """Train PPO policies (several seeds at once) on the spin/upset recovery env."""
        overrides = {"total_steps": steps, "num_envs": num_envs, "unroll": unroll, "epochs": epochs,
                     "minibatches": minibatches, "lr": lr, "num_seeds": seeds, "seed": seed,
                     "num_periods": periods, "checkpoint_every": checkpoint_every}  # fmt: skip
        summary = run_train(
            preset,
            overrides,
            out,
            resume,
            force,
            init_policy,
            target_recovery=target_recovery,
            watchdog_s=watchdog_s,
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
