"""`harv-jax evaluate RUN_DIR`: every seed of a training run judged on the acceptance criteria.

The work is ``harv_jax.evaluation.seeds.conditions`` (the cells) and ``harv_jax.evaluation.seeds.report``
(numbers, criteria, outputs); the criteria are ``harv_jax.evaluation.seeds.acceptance``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import typer

from harv_jax import atomic, outdir, runlock
from harv_jax.aircraft.registry import DEFAULT_AIRCRAFT, check_aircraft_name
from harv_jax.cli_options import command_line, force_option
from harv_jax.errors import UsageError
from harv_jax.evaluation.seeds.conditions import CONDITIONS, EvalSettings, file_sha256
from harv_jax.study_options import StudyOptions, study_options

#: The file that records an evaluation's settings (read back by ``--resume``).
SETTINGS_FILE = "evaluate_settings.json"
_SEED_FILE = re.compile(r"policy_seed(\d+)\.npz")


def policy_files(run_dir: Path) -> list[Path]:
    """The per-seed policies of a training run folder, by seed; UsageError naming what is missing."""
    if not run_dir.is_dir():
        raise UsageError(f"RUN_DIR {str(run_dir)!r} is not a folder; give a training run folder")
    if not (run_dir / "config.json").is_file():
        raise UsageError(
            f"RUN_DIR {str(run_dir)!r} is not a training run (no config.json); give a folder that "
            "`harv-jax train` wrote"
        )
    found = sorted(
        (
            (int(m.group(1)), p)
            for p in (run_dir / "policy").glob("policy_seed*.npz")
            if (m := _SEED_FILE.fullmatch(p.name))
        ),
    )
    if not found:
        raise UsageError(
            f"RUN_DIR {str(run_dir)!r} has no policies (policy/policy_seed<i>.npz); wait for its first period"
        )
    seeds = [s for s, _ in found]
    if seeds != list(range(len(seeds))):
        raise UsageError(
            f"RUN_DIR {str(run_dir)!r}: policies of seeds {seeds}; allowed: seeds 0..N-1, each once"
        )
    return [p for _, p in found]


def run_aircraft(run_dir: Path) -> str:
    """The registered aircraft a training run flew (its ``config.json``'s ``env.aircraft``; default harv);
    UsageError for a record that is not JSON or names an unknown aircraft."""
    try:
        record = json.loads((run_dir / "config.json").read_text())
    except (OSError, ValueError):
        raise UsageError(f"RUN_DIR {str(run_dir)!r}: config.json is not a run record (JSON)") from None
    env = record.get("env") if isinstance(record, dict) else None
    name = env.get("aircraft", DEFAULT_AIRCRAFT) if isinstance(env, dict) else DEFAULT_AIRCRAFT
    try:
        check_aircraft_name(name)
    except ValueError as e:
        raise UsageError(f"RUN_DIR {str(run_dir)!r}: {e}") from None
    return name


def parse_conditions(text: str) -> tuple[str, ...]:
    """``--conditions``: ``all`` or a comma list of condition names; UsageError otherwise."""
    parts = [p.strip() for p in str(text).split(",") if p.strip()]
    if parts == ["all"]:
        return tuple(CONDITIONS)
    bad = [p for p in parts if p not in CONDITIONS]
    if not parts or bad or len(set(parts)) < len(parts):
        what = f"unknown condition {bad[0]!r}" if bad else f"{text!r}"
        raise UsageError(f"--conditions: {what}; allowed: all, or a comma list of {', '.join(CONDITIONS)}")
    return tuple(c for c in CONDITIONS if c in parts)


#: Largest ``--runs`` of an evaluation (per condition; every seed and baseline flies them).
MAX_EVAL_RUNS = 100_000


@study_options(
    runs=1000,
    target_alpha=False,
    help={"runs": "Monte Carlo runs per condition.", "seed": "Seed of the Monte Carlo's runs."},
)
def evaluate(
    run_dir: Path = typer.Argument(..., help="A training run folder (policy/policy_seed<i>.npz)."),
    conditions: str = typer.Option(
        "all",
        help="Conditions: all, or a comma list of clean, randomized, disturbed (--disturbances default), "
        "noise3 (noise x3), model2 (model error x2), spin (the 30 s spin).",
    ),
    out: Path = typer.Option(Path("runs/evaluate"), help="Output directory."),
    resume: bool = typer.Option(
        False, help="Continue an interrupted evaluation in --out: cells already written are kept."
    ),
    force: bool = force_option(),
    study: StudyOptions = StudyOptions(),
) -> None:
    """Every seed of a training run: RL-only and the hybrid against the SMC and smc-brake-zoom on the same
    runs, clean and disturbed; per-seed table, IQM with 95% CI, pass/fail per criterion (JSON, md, png)."""
    if study.runs > MAX_EVAL_RUNS:
        raise UsageError(f"--runs {study.runs}: allowed: 1 to {MAX_EVAL_RUNS}")
    conds = parse_conditions(conditions)
    files = policy_files(run_dir)
    if resume and force:
        raise UsageError("--resume keeps what --out holds and --force replaces it; give one of them")
    settings = EvalSettings(
        runs=study.runs, mc_seed=study.seed, duration_s=float(study.duration_s), conditions=conds
    )
    record = {
        **settings.record(),
        "run_dir": str(run_dir),
        "aircraft": run_aircraft(run_dir),
        "policies": [{"seed": i, "policy": str(p), "sha256": file_sha256(p)} for i, p in enumerate(files)],
    }
    out_dir = _open_out(out, resume, force, record, [run_dir])
    # the evaluation pulls optax: imported here, not by every command (tools/results/house/cli_startup.json)
    from harv_jax.evaluation.seeds.flow import run_evaluation

    run_evaluation(out_dir, settings, record, files, command_line(), typer.echo)


def _open_out(out: Path, resume: bool, force: bool, record: dict, reads: list[Path]) -> Path:
    """The output folder: new (``--force`` may replace it), or with ``--resume`` the folder of an
    interrupted evaluation of the same settings and policies."""
    if not resume:
        out_dir = outdir.prepare_out_dir(out, force, outdir.read_paths(*reads))
        atomic.write_text(out_dir / SETTINGS_FILE, json.dumps(record, indent=1) + "\n")
        return out_dir
    stored = out / SETTINGS_FILE
    if not stored.is_file() or not outdir.is_run_dir(out):
        raise UsageError(f"--resume: {str(out)!r} holds no evaluation to continue; run without --resume")
    try:
        before = json.loads(stored.read_text())
    except (OSError, ValueError):
        raise UsageError(f"--resume: {str(stored)!r} cannot be read; run without --resume") from None
    diff = sorted(k for k in set(before) | set(record) if before.get(k) != record.get(k))
    if diff:
        raise UsageError(
            f"--resume: {str(out)!r} evaluated other settings ({', '.join(diff)} differ); give the same "
            "settings or a new --out"
        )
    runlock.acquire(out, "--out")  # refused while another harv-jax process writes there
    outdir.adopt(out)
    return out


def register(app: typer.Typer) -> None:
    """Add ``evaluate`` to the CLI."""
    app.command()(evaluate)
