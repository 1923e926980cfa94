"""``harv-jax`` with one more teacher: the braking SMC behind the policy's 2 Hz low-pass (variant v8).

The `robust` recipe's teacher labels the true state, which the policy behind its low-pass sees only late;
in the spin's fast rates those labels are not what any function of the policy's observation can match.
This script registers ``smc-brake-lp2`` (``smc-brake`` fed its states through the same 2 Hz low-pass) and
runs the command line with it; ``train`` without ``--preset`` trains v8, the shipped `robust` preset with
``[env] teacher = "smc-brake-lp2"`` (written beside copies of the shipped presets in a temporary folder):

    python experiments/robust_policy/teacher_behind_path.py train --seed 3301 --out RUN
    python experiments/robust_policy/teacher_behind_path.py evaluate RUN \\
        --runs 256 --seed 5501 --conditions clean,disturbed,spin --out RUN_eval
"""

from __future__ import annotations

import sys
import tempfile
from importlib import resources
from pathlib import Path

from harv_jax.cli import main
from harv_jax.control.base import Controller
from harv_jax.control.registry import (
    ControllerOptions,
    build_controller,
    parse_measurement_path,
    register,
    with_measurement_path,
)

TEACHER = "smc-brake-lp2"
V8 = "\n".join(
    [
        "description = \"robust_v8: the robust preset taught by the braking SMC behind the policy's 2 Hz "
        f'low-pass ({TEACHER}); experiments/robust_policy/teacher_behind_path.py."',
        'base = "robust.toml"',
        "",
        "[env]",
        f'teacher = "{TEACHER}"',
        "",
    ]
)


def smc_brake_behind_lp2(opts: ControllerOptions) -> Controller:
    """``smc-brake`` fed its measured states through the 2 Hz Butterworth low-pass."""
    path = parse_measurement_path("lp2")
    assert path is not None
    return with_measurement_path(build_controller("smc-brake", opts), path)


def v8_preset(folder: Path) -> Path:
    """v8's preset in ``folder``, beside copies of the shipped presets it builds on."""
    for f in (resources.files("harv_jax.training") / "presets").iterdir():
        if f.name.endswith(".toml"):
            (folder / f.name).write_text(f.read_text())
    (folder / "robust_v8.toml").write_text(V8)
    return folder / "robust_v8.toml"


if __name__ == "__main__":
    register(TEACHER, smc_brake_behind_lp2, help="smc-brake behind the 2 Hz low-pass (robust_policy)")
    with tempfile.TemporaryDirectory() as tmp:
        if sys.argv[1:2] == ["train"] and "--preset" not in sys.argv:
            sys.argv[2:2] = ["--preset", str(v8_preset(Path(tmp)))]
        main()
