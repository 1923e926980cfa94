"""Recovery envelope map: grid layout, equality of a map point with a single closed-loop run, CLI."""

from __future__ import annotations

import csv
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cli_util import cli_run

from harv_jax.aircraft import harv
from harv_jax.control.smc import make_smc
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.envelope.grid import (
    DEFAULT_FIXED_STATE,
    envelope_inputs,
    grid_states,
    make_grid,
    run_envelope,
)
from harv_jax.evaluation.montecarlo.rollout import TERMINAL_WINDOW_S
from harv_jax.evaluation.summary import summarize_envelope
from harv_jax.task.criteria import OUTCOME_NAMES, tracking_errors

DT_S = 0.01
# 12 s with the 10 s hold window: the centre point (alpha0 = 0.436 rad, r0 = 0) recovers (about 0.2 s),
# the corners time out, so both kinds of outcome are compared with single runs.
N_STEPS = 1200
REF = jnp.array([0.349, 0.0, 0.0])


@pytest.fixture(scope="module")
def env3x3():
    grid = make_grid("alpha0", "r0", 3, 3)
    inputs = envelope_inputs(jax.random.key(0), grid, harv())
    emap, out, wall = run_envelope(make_smc(), inputs, grid, REF, N_STEPS, DT_S, chunk_size=9)
    return grid, inputs, emap, out, wall


def test_grid_layout_rows_are_y_columns_are_x():
    grid = make_grid("V0", "alpha0", 4, 3, x_range=(200.0, 800.0), fixed={"h": 20_000.0})
    x0 = grid_states(grid)
    assert x0.shape == (3, 4, 10)
    np.testing.assert_allclose(x0[:, :, 0], np.broadcast_to([200.0, 400.0, 600.0, 800.0], (3, 4)))
    np.testing.assert_allclose(x0[:, :, 1], np.broadcast_to(grid.y_values[:, None], (3, 4)))
    np.testing.assert_allclose(grid.y_values, np.linspace(-0.175, 1.047, 3))  # reset bounds of alpha
    # off-grid components: the defaults, with the override of h
    assert np.all(x0[:, :, 9] == 20_000.0)
    for i, name in enumerate(("beta", "p", "q", "r", "mu", "gamma", "chi")):
        assert np.all(x0[:, :, 2 + i] == DEFAULT_FIXED_STATE[name])
    # runs are the grid points in row-major order
    inputs = envelope_inputs(jax.random.key(0), grid, harv())
    assert inputs.x0_wind.shape == (12, 10) and inputs.keys.shape == (12,)
    np.testing.assert_allclose(np.asarray(inputs.x0_wind)[2 * 4 + 1], x0[2, 1], rtol=1e-6)
    # the same nominal aircraft in every run
    for leaf, nominal in zip(jax.tree.leaves(inputs.params), jax.tree.leaves(harv()), strict=True):
        assert bool(jnp.all(leaf == nominal[None]))


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"x_name": "zeta0"}, "unknown"),
        ({"y_name": "alpha0"}, "must differ"),
        ({"n_x": 1}, ">= 2 points"),
        ({"x_range": (1.0, 0.0)}, "low < high"),
        ({"fixed": {"V": 0.0}, "x_name": "beta0"}, "initial V"),
        ({"fixed": {"zz": 1.0}}, "fixed state 'zz'"),
    ],
)
def test_make_grid_rejects_bad_grids(kwargs, fragment):
    args = {"x_name": "alpha0", "y_name": "r0", "n_x": 3, "n_y": 3} | kwargs
    with pytest.raises(ValueError, match=fragment):
        make_grid(**args)


def test_map_shapes_and_outcome_accounting(env3x3):
    grid, _, emap, out, wall = env3x3
    for field in ("outcome", "recovered", "t_recover_s", "t_recover_alpha_s", "altitude_loss_ft"):
        assert getattr(emap, field).shape == (3, 3), field
    assert emap.terminal_error_rad.shape == (3, 3, 3)
    s = summarize_envelope(out, wall)
    assert sum(s["outcome_counts"].values()) == 9
    assert s["recovery_rate"] == pytest.approx(float(np.mean(emap.recovered)))
    # both outcomes occur, so the single-run comparisons below cover a recovered and an unrecovered point
    assert emap.recovered[1, 1] and not emap.recovered.all()
    assert np.isnan(emap.t_recover_s[~emap.recovered]).all()


@jax.jit
def _single_run(x0_wind, key):
    """One closed-loop SMC run of the nominal aircraft: (RunMetrics, terminal error [3] rad)."""
    res = closed_loop(make_smc(), harv(), x0_wind, REF, key, N_STEPS, DT_S)
    m, x_all = score(res, REF, harv(), DT_S)
    n_term = int(round(TERMINAL_WINDOW_S / DT_S))
    return m, jnp.mean(tracking_errors(x_all[-n_term:], REF), axis=0)


@pytest.mark.parametrize(
    "iy, ix", [(1, 1), pytest.param(0, 2, marks=pytest.mark.slow), pytest.param(2, 0, marks=pytest.mark.slow)]
)
def test_map_point_equals_single_closed_loop_run(env3x3, iy, ix):
    """The vmapped, chunked map gives at (iy, ix) what one closed-loop run from that state gives."""
    grid, inputs, emap, _, _ = env3x3
    k = iy * grid.n_x + ix
    x0 = jnp.asarray(grid_states(grid)[iy, ix], jnp.float32)
    m, term = _single_run(x0, inputs.keys[k])
    assert OUTCOME_NAMES[int(m.outcome)] == OUTCOME_NAMES[int(emap.outcome[iy, ix])]
    assert bool(m.recovered) == bool(emap.recovered[iy, ix])
    np.testing.assert_allclose(float(m.t_recover_s), emap.t_recover_s[iy, ix], atol=1e-6, equal_nan=True)
    np.testing.assert_allclose(
        float(m.t_recover_alpha_s), emap.t_recover_alpha_s[iy, ix], atol=1e-6, equal_nan=True
    )
    # altitudes near 25,000 ft carry a float32 ulp of 0.002 ft
    np.testing.assert_allclose(float(m.altitude_loss_ft), emap.altitude_loss_ft[iy, ix], atol=0.02)
    np.testing.assert_allclose(np.asarray(term), emap.terminal_error_rad[iy, ix], atol=1e-5)


def _run(monkeypatch, capsys, *args):
    return cli_run(monkeypatch, capsys, "envelope", *args)


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--grid", "alpha0"], "must name two axes as X:Y"),
        (["--grid", "alpha0:alpha0"], "names alpha0 twice"),
        (["--grid", "zeta0:r0"], "--grid axis 'zeta0' is unknown"),
        (["--grid", "alpha0=1,0:r0"], "LOW < HIGH"),
        (["--grid", "alpha0=a,1:r0"], "'a' is not a number"),
        (["--grid", "alpha0=0,1,2:r0"], "NAME=LOW,HIGH"),
        (["--n", "1"], "--n 1 must be in [2, 1000]"),
        (["--fixed", "V0=-5"], "initial V must be in (0, 2000] ft/s"),
        (["--fixed", "alpha0=0.1"], "--fixed sets alpha0, which is a grid axis"),
        (["--fixed", "zz=1"], "--fixed 'zz=1' must be NAME=VALUE"),
        (["--controller", "pid"], "unknown controller 'pid'"),
        (["--controller", "rl", "--policy", "/nonexistent/p.npz"], "'/nonexistent/p.npz' does not exist"),
        (["--duration", "0"], "--duration 0.0 s: allowed (10, 600]"),
        (["--target-alpha", "3"], "--target-alpha 3.0 rad is outside"),
    ],
)
def test_bad_flags_are_one_line_errors(monkeypatch, capsys, tmp_path, args, needle):
    code, _, err = _run(monkeypatch, capsys, *args, "--out", str(tmp_path / "o"))
    assert code == 2
    assert needle in err
    assert err.startswith("harv-jax: error:") and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


def test_cli_writes_outputs_and_refuses_existing_dir(monkeypatch, capsys, tmp_path, damper, figure_texts):
    """The files of ``envelope`` (a cheap registered controller: the point is the outputs, not the SMC)."""
    out = tmp_path / "env"
    args = ["--grid", "V0=300,900:alpha0", "--n", "3", "--duration", "10.5", "--fixed", "h0=20000",
            "--controller", damper]  # fmt: skip
    code, stdout, err = _run(monkeypatch, capsys, *args, "--out", str(out))
    assert code == 0, err
    for f in ("envelope_recovery.png", "envelope_time.png", "envelope.json", "envelope_grid.csv"):
        assert (out / f).stat().st_size > 0, f
    assert {"envelope_recovery.png", "envelope_time.png"} <= set(figure_texts)
    assert not any(figure_texts.values()), figure_texts  # every text inside its figure
    doc = json.loads((out / "envelope.json").read_text())
    assert doc["grid"]["x"]["name"] == "V0" and doc["grid"]["x"]["values"] == [300.0, 600.0, 900.0]
    assert doc["grid"]["fixed_state"]["h"] == 20_000.0 and "V" not in doc["grid"]["fixed_state"]
    assert doc["runs_per_controller"] == 9 and doc["seed"] == 0
    smc = doc["controllers"][damper]
    assert sum(smc["outcome_counts"].values()) == 9
    assert set(smc["wall_time_s"]) == {"compile", "run"}
    with np.load(out / "envelope_grid.npz") as z:
        assert z[f"{damper}/outcome"].shape == (3, 3) and z["x0_wind"].shape == (3, 3, 10)
        assert np.all(z["x0_wind"][:, :, 9] == 20_000.0)
        outcome = z[f"{damper}/outcome"]
    with (out / "envelope_grid.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 9
    assert [r["outcome"] for r in rows] == [OUTCOME_NAMES[c] for c in outcome.ravel()]  # row-major
    assert smc["recovery_rate"] == pytest.approx(np.mean(outcome == 0))

    before = (out / "envelope.json").read_text()
    code, _, err = _run(monkeypatch, capsys, *args, "--out", str(out))
    assert code == 2 and "--force" in err and err.count("\n") == 1
    assert (out / "envelope.json").read_text() == before
