"""Run ``harv-jax`` in-process through its console entry point (one-line errors, exit codes)."""

from __future__ import annotations

import os
import sys

from harv_jax import cli


def cli_run(monkeypatch, capsys, command: str, *args) -> tuple[int, str, str]:
    """``harv-jax COMMAND ARGS`` via ``cli.main()``; returns (exit code, stdout, stderr)."""
    monkeypatch.setenv("XLA_FLAGS", os.environ.get("XLA_FLAGS", ""))  # main() edits it; restored after
    monkeypatch.setattr(sys, "argv", ["harv-jax", command, *map(str, args)])
    code = 0
    try:
        cli.main()
    except SystemExit as e:
        code = e.code
    out = capsys.readouterr()
    return code, out.out, out.err
