"""`harv-jax simulate`: CSV + PNG on good input; one-line error and exit code 2 on bad input."""

from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

from harv_jax import cli

HEADER = "t,V,alpha,beta,p,q,r,mu,gamma,chi,h,de,da,dr"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def run_main(monkeypatch, capsys, *args: str) -> tuple[int, str, str]:
    """Run the console entry point ``harv_jax.cli.main`` in-process; returns (exit code, stdout, stderr)."""
    monkeypatch.setattr(sys, "argv", ["harv-jax", *args])
    code = 0
    try:
        cli.main()
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else 1
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """One successful run (2 s at dt 0.01 s from a non-default state and controls) via typer's CliRunner."""
    out = tmp_path_factory.mktemp("sim") / "run"
    args = ["simulate", "--state", "V=500,alpha=0.12,q=0.05,mu=0.2,h=20000",
            "--controls", "de=-0.05,da=0.02,dr=-0.03", "--duration", "2", "--out", str(out)]  # fmt: skip
    result = CliRunner().invoke(cli.app, args)
    return result, out


def test_simulate_writes_csv_and_png(simulated):
    result, out = simulated
    assert result.exit_code == 0, result.output
    assert "trajectory.csv" in result.output and "NON-FINITE" not in result.output
    csv = out / "trajectory.csv"
    assert csv.read_text().splitlines()[0] == HEADER
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    assert data.shape == (201, 14)  # 2 s / 0.01 s + the initial row
    assert np.all(np.isfinite(data))
    np.testing.assert_allclose(data[:, 0], np.arange(201) * 0.01, atol=1e-9)
    # the first row is the requested initial state (unspecified entries keep their defaults)
    np.testing.assert_allclose(data[0, 1:11], [500, 0.12, 0, 0, 0.05, 0, 0.2, 0, 0, 20000], atol=1e-6)
    np.testing.assert_allclose(data[:, 11:], np.tile([-0.05, 0.02, -0.03], (201, 1)), atol=1e-7)
    assert np.ptp(data[:, 1]) > 1.0 and np.ptp(data[:, 10]) > 1.0  # it actually flew
    png = (out / "trajectory.png").read_bytes()
    assert png.startswith(PNG_MAGIC) and len(png) > 10_000


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--state", "foo=1"], "foo"),  # unknown state name
        (["--state", "V=nan"], "V"),  # NaN
        (["--state", "alpha=inf"], "alpha"),
        (["--state", "V=0"], "V"),  # V <= 0
        (["--state", "V=-100"], "V"),
        (["--state", "alpha=3.2"], "alpha"),  # |alpha| > pi
        (["--state", "alpha=-3.5"], "alpha"),
        (["--state", "beta=4"], "beta"),  # |beta| > pi
        (["--state", "V=abc"], "V"),  # not a number
        (["--state", "V"], "V"),  # not NAME=VALUE
        (["--duration", "-1"], "duration"),  # negative duration
        (["--duration", "0"], "duration"),
        (["--controls", "de=0.2"], "de"),  # above the stabilator limit 0.175
        (["--controls", "de=-0.5"], "de"),  # below -0.436
        (["--controls", "da=0.44"], "da"),
        (["--controls", "dr=-0.6"], "dr"),
        (["--controls", "dx=0.1"], "dx"),  # unknown control name
        (["--dt", "0"], "dt"),
        (["--throttle", "1.5"], "throttle"),
    ],
)
def test_bad_values_give_one_line_error_and_exit_2(monkeypatch, capsys, tmp_path, args, needle):
    out = tmp_path / "never"
    code, stdout, stderr = run_main(monkeypatch, capsys, "simulate", *args, "--out", str(out))
    assert code == 2, (stdout, stderr)
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert lines[0].startswith("harv-jax: error:") and needle in lines[0], lines[0]
    assert not out.exists()  # nothing was written


def test_existing_out_dir_is_not_overwritten(monkeypatch, capsys, simulated):
    _, out = simulated
    before = (out / "trajectory.csv").read_bytes()
    code, _, stderr = run_main(monkeypatch, capsys, "simulate", "--duration", "2", "--out", str(out))
    assert code == 2
    assert len(stderr.strip().splitlines()) == 1 and "--force" in stderr
    assert (out / "trajectory.csv").read_bytes() == before


@pytest.mark.skipif(shutil.which("harv-jax") is None, reason="console script not installed")
def test_console_script_error_is_one_line():
    """The installed console script itself: exit code 2 and a single stderr line, no traceback."""
    proc = subprocess.run(
        ["harv-jax", "simulate", "--state", "V=-1", "--out", "/nonexistent/never"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert "V=-1" in proc.stderr and "Traceback" not in proc.stderr
