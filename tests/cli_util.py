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


def assert_train_preset_refused(tmp_path, monkeypatch, capsys, env_lines: str, message: str) -> None:
    """``harv-jax train`` on a small preset whose ``[env]`` table holds ``env_lines`` exits 2 with one line
    holding ``message`` and writes nothing."""
    preset = tmp_path / "p.toml"
    preset.write_text(f"[ppo]\ntotal_steps = 4096\nnum_envs = 16\n[env]\n{env_lines}\n")
    code, _, err = cli_run(monkeypatch, capsys, "train", "--preset", preset, "--out", tmp_path / "run")
    assert code == 2 and message in err and err.count("\n") == 1, err
    assert not (tmp_path / "run").exists()
