"""The aircraft registry: a second aircraft registered with one call is flown by ``mc``, ``compare`` and
``train`` through ``--aircraft``, recorded by name, and differs from the HARV on the same seed.

The second aircraft is the HARV 10 % heavier (mass and inertias) with 5 % more lift and drag (its aero table's
CL and CD columns scaled). It is registered through the public ``register_aircraft`` and removed again after
each test (fixture ``heavy``). The command-line runs fly a constant-deflection controller (registered the
same way, fixture ``hold``): it compiles in seconds, and the plant alone tells the aircraft apart.
"""

from __future__ import annotations

import csv
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cheap_controller import registered
from cli_util import cli_run

from harv_jax.aircraft import (
    DEFAULT_AIRCRAFT,
    AircraftParams,
    aircraft_names,
    get_aircraft,
    harv,
    register_aircraft,
    unregister_aircraft,
)
from harv_jax.aircraft.aero import coefficients
from harv_jax.control.base import Controller
from harv_jax.env.config import EnvConfig, default_params

HEAVY = "harv-heavy"
MASS_FACTOR = 1.1
LIFT_DRAG_FACTOR = 1.05
LIFT_DRAG = ("clift0", "clift_q", "clift_del", "clift_der", "cd0", "cd_q", "cd_del", "cd_der")


def harv_heavy() -> AircraftParams:
    """The HARV with mass and inertias x 1.1 and its CL, CD table columns x 1.05."""
    p = harv()
    f = MASS_FACTOR
    table = p.aero_table.scaled({c: LIFT_DRAG_FACTOR for c in LIFT_DRAG})
    inertia = {"Ixx": f * p.Ixx, "Iyy": f * p.Iyy, "Izz": f * p.Izz, "Ixz": f * p.Ixz}
    return p.replace(mass_slug=f * p.mass_slug, aero_table=table, **inertia)


@pytest.fixture
def heavy():
    register_aircraft(HEAVY, harv_heavy)
    yield HEAVY
    unregister_aircraft(HEAVY)


WIDE = "harv-wide"


def harv_wide() -> AircraftParams:
    """The HARV with a stabilator up to +0.3 rad and a rudder limited to +-0.4 rad."""
    p = harv()
    return p.replace(
        u_min_rad=p.u_min_rad.at[2].set(-0.4), u_max_rad=p.u_max_rad.at[0].set(0.3).at[2].set(0.4)
    )


@pytest.fixture
def wide():
    register_aircraft(WIDE, harv_wide)
    yield WIDE
    unregister_aircraft(WIDE)


def make_hold() -> Controller:
    """A controller that always commands a little nose-down stabilator (no state, no diagnostics)."""

    def init(params):
        del params
        return jnp.zeros(())

    def apply(state, x_wind, reference_rad, key):
        del reference_rad, key
        return jnp.asarray([-0.05, 0.0, 0.0], x_wind.dtype), state, {}

    return Controller(init=init, apply=apply)


@pytest.fixture
def hold():
    with registered("hold", make_hold, "constant deflection") as name:
        yield name


# ------------------------------------------------------------------------------------------- registry


def test_the_default_is_harv():
    assert DEFAULT_AIRCRAFT == "harv" and aircraft_names() == ("harv",)
    a, b = get_aircraft(), harv()
    assert jax.tree.structure(a) == jax.tree.structure(b)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        assert x.dtype == y.dtype
        np.testing.assert_array_equal(x, y)
    assert default_params().aircraft.aero_table == b.aero_table


def test_unknown_name_is_one_line_naming_the_allowed(heavy):
    with pytest.raises(ValueError, match="unknown aircraft 'xyz'; allowed: harv, harv-heavy") as e:
        get_aircraft("xyz")
    assert "\n" not in str(e.value)
    with pytest.raises(ValueError, match="unknown aircraft 'xyz'"):
        EnvConfig(aircraft="xyz")


def test_duplicates_and_the_default_are_refused(heavy):
    with pytest.raises(ValueError, match="'harv-heavy' is already registered"):
        register_aircraft(HEAVY, harv)
    with pytest.raises(ValueError, match="'harv' is already registered"):
        register_aircraft("harv", harv_heavy)
    with pytest.raises(ValueError, match="is the default"):
        unregister_aircraft("harv")
    with pytest.raises(ValueError, match="non-empty word"):
        register_aircraft("a,b", harv)


def test_the_registered_aircraft_carries_its_table_and_mass(heavy):
    p, q = get_aircraft(), get_aircraft(heavy, throttle=0.5)
    assert float(q.mass_slug) == pytest.approx(MASS_FACTOR * float(p.mass_slug), rel=1e-6)
    assert float(q.throttle) == 0.5 and q.aero_table != p.aero_table
    args = (jnp.float32(0.3), jnp.float32(0.0), jnp.zeros(3), jnp.float32(500.0), jnp.zeros(3))
    cp, cq = coefficients(*args, p), coefficients(*args, q)
    assert float(cq.CL) == pytest.approx(LIFT_DRAG_FACTOR * float(cp.CL), rel=1e-6)
    assert float(cq.CD) == pytest.approx(LIFT_DRAG_FACTOR * float(cp.CD), rel=1e-6)
    assert float(cq.Cm) == float(cp.Cm)
    env = default_params(EnvConfig(aircraft=heavy))
    assert float(env.aircraft.Iyy) == pytest.approx(MASS_FACTOR * float(p.Iyy), rel=1e-6)


# ------------------------------------------------------------------------------------ command line


def test_unknown_aircraft_on_the_command_line(monkeypatch, capsys, tmp_path):
    out = tmp_path / "mc"
    code, _, err = cli_run(monkeypatch, capsys, "mc", "--aircraft", "xyz", "--runs", "2", "--out", out)
    assert code == 2 and err == "harv-jax: error: --aircraft 'xyz' is unknown; allowed: harv\n"
    assert not out.exists()


def test_train_resume_keeps_the_stored_aircraft(monkeypatch, capsys, tmp_path):
    code, _, err = cli_run(monkeypatch, capsys, "train", "--resume", tmp_path, "--aircraft", "harv")
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("harv-jax: error: --resume continues the stored configuration; drop --aircraft")


def _runs(path) -> list[dict[str, str]]:
    with path.open() as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_mc_flies_the_registered_aircraft(heavy, hold, monkeypatch, capsys, tmp_path):
    """Same seed, same initial states; the heavy aircraft flies another trajectory, recorded by name."""
    args = ("--controller", hold, "--runs", "4", "--duration", "10.5", "--seed", "3")
    for name in ("harv", heavy):
        code, _, err = cli_run(monkeypatch, capsys, "mc", *args, "--aircraft", name, "--out", tmp_path / name)
        assert code == 0, err
        assert json.loads((tmp_path / name / "summary.json").read_text())["aircraft"] == name
    a, b = _runs(tmp_path / "harv" / "runs.csv"), _runs(tmp_path / heavy / "runs.csv")
    assert [r["V0"] for r in a] == [r["V0"] for r in b]
    assert [r["altitude_loss_ft"] for r in a] != [r["altitude_loss_ft"] for r in b]


@pytest.mark.slow
def test_compare_flies_the_registered_aircraft(heavy, hold, monkeypatch, capsys, tmp_path):
    args = ("--controller", hold, "--spin-s", "0", "--duration", "10.5", "--seed", "3")
    for name in ("harv", heavy):
        out = tmp_path / name
        code, _, err = cli_run(monkeypatch, capsys, "compare", *args, "--aircraft", name, "--out", out)
        assert code == 0, err
        assert json.loads((out / "compare.json").read_text())["aircraft"] == name
    a, b = (_runs(tmp_path / n / "compare_metrics.csv") for n in ("harv", heavy))
    assert [r["altitude_loss_ft"] for r in a] != [r["altitude_loss_ft"] for r in b]


@pytest.mark.slow
def test_train_uses_the_registered_aircraft(heavy, monkeypatch, capsys, tmp_path):
    """`harv-jax train --aircraft` on the smoke preset, tiny budget: recorded, rebuilt, other metrics."""
    from harv_jax.training.environment import make_harv_env

    flags = (
        "--preset smoke --steps 64 --num-envs 2 --unroll 32 --minibatches 1 --epochs 1 --periods 1 --seed 0 "
        "--watchdog-s 0"
    ).split()
    rows = {}
    for name in ("harv", heavy):
        out = tmp_path / name
        code, _, err = cli_run(monkeypatch, capsys, "train", *flags, "--aircraft", name, "--out", out)
        assert code == 0, err
        env_table = json.loads((out / "config.json").read_text())["env"]
        assert env_table["aircraft"] == name
        _, params = make_harv_env(env_table)
        assert params.aircraft.aero_table == get_aircraft(name).aero_table
        last = _runs(out / "metrics.csv")[-1]
        rows[name] = {k: v for k, v in last.items() if k not in ("wall_s", "period_s")}
    assert rows["harv"].keys() == rows[heavy].keys() and rows["harv"] != rows[heavy]


def test_simulate_checks_the_controls_against_the_chosen_aircraft(wide, monkeypatch, capsys, tmp_path):
    """de = 0.2 rad is past the HARV's stabilator limit and within the wide one's; dr = 0.45 rad the other
    way round. ``--dt 0`` fails after the control check, so a control that passes flies nothing."""
    out = tmp_path / "never"
    cases = [
        ("harv", "de=0.2", "control de=0.2 rad is outside [-0.436, 0.175]"),
        (wide, "de=0.2", "--dt 0.0 must be in (0, 0.05] s"),
        (wide, "de=0.35", "control de=0.35 rad is outside [-0.436, 0.3]"),
        ("harv", "dr=0.45", "--dt 0.0 must be in (0, 0.05] s"),
        (wide, "dr=-0.45", "control dr=-0.45 rad is outside [-0.4, 0.4]"),
    ]
    for name, controls, message in cases:
        args = ("--aircraft", name, "--controls", controls, "--dt", "0", "--out", out)
        code, _, err = cli_run(monkeypatch, capsys, "simulate", *args)
        assert (code, err) == (2, f"harv-jax: error: {message}\n"), (name, controls)
    assert not out.exists()
    args = ("--controls", "de=0.3,dr=0.4", "--duration", "0.05", "--out", out)
    code, stdout, err = cli_run(monkeypatch, capsys, "simulate", "--aircraft", wide, *args)
    assert code == 0, err
    assert "6 rows" in stdout and (out / "trajectory.csv").exists()


def test_the_spin_bank_records_its_aircraft(heavy):
    from harv_jax.env.spin_table import bank_provenance

    nested = {"spin": {"reset_prob": 0.5}, "randomization": {}}
    default = bank_provenance(EnvConfig(), nested)
    other = bank_provenance(EnvConfig(aircraft=heavy), nested)
    assert default["aircraft"] == "harv" and other["aircraft"] == heavy
    assert {k: v for k, v in other.items() if k != "aircraft"} == {
        k: v for k, v in default.items() if k != "aircraft"
    }
