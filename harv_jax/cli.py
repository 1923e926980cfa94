"""`harv-jax` command line. Sub-commands live in ``harv_jax.commands.*``; errors are one line."""

from __future__ import annotations

import importlib
import os
import sys

import typer

from harv_jax import interrupt, outdir, runlock
from harv_jax.errors import UsageError

app = typer.Typer(
    name="harv-jax",
    help="F-18/HARV upset and spin recovery: flight model, controllers, RL training, Monte Carlo.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _print_version(value: bool) -> None:
    if value:
        from harv_jax import __version__

        typer.echo(f"harv-jax {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False, "--version", callback=_print_version, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """F-18/HARV upset and spin recovery: flight model, controllers, RL training, Monte Carlo."""


#: Sub-command modules under ``harv_jax.commands``, in help order.
COMMAND_MODULES = (
    "simulate",
    "fly",
    "train",
    "evaluate",
    "mc",
    "compare",
    "envelope",
    "robustness",
    "optimal",
    "report",
    "quickstart",
)

for _name in COMMAND_MODULES:
    importlib.import_module(f"harv_jax.commands.{_name}").register(app)


def use_all_cpu_cores() -> None:
    """One XLA host device per CPU core (unless XLA_FLAGS already sets a count), so that runs sharded
    over ``jax.local_devices()`` use every core of a CPU machine; no effect on GPU runs.
    Must run before jax initializes its backends."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_force_host_platform_device_count" not in flags:
        n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
        os.environ["XLA_FLAGS"] = f"{flags} --xla_force_host_platform_device_count={n}".strip()


def main() -> None:
    """Console entry point: run the app; turn UsageError/ValueError into a one-line error, exit 2."""
    # one XLA host device per core: the Monte Carlo and the envelope map shard their runs over them
    use_all_cpu_cores()
    try:
        try:
            with interrupt.handled(outdir.interrupted_message):
                app(standalone_mode=False)
            outdir.finish_all()
        except typer.Exit as e:
            outdir.finish_all() if not e.exit_code else outdir.forget_all()
            sys.exit(e.exit_code)
        except (UsageError, ValueError, FileExistsError, FileNotFoundError) as e:
            outdir.forget_all()
            print(f"harv-jax: error: {e}", file=sys.stderr)
            sys.exit(2)
        except Exception as e:  # click/typer usage errors (typer vendors its own click)
            outdir.forget_all()
            if hasattr(e, "format_message") and hasattr(e, "exit_code"):
                if e.format_message():
                    print(f"harv-jax: error: {e.format_message()}", file=sys.stderr)
                sys.exit(e.exit_code)
            if type(e).__name__ == "Abort":
                sys.exit(1)
            raise
    finally:  # the process ends here: its folders' locks go with it (also when main is called in-process)
        runlock.release_all()


if __name__ == "__main__":
    main()
