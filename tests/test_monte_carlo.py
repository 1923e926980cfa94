"""Monte Carlo: outcome accounting, common random numbers, equality with single runs, CLI errors."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

from harv_jax.aircraft import harv
from harv_jax.cli import app
from harv_jax.control.smc import make_smc
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.montecarlo.rollout import (
    TERMINAL_WINDOW_S,
    run_mc,
    sample_mc_inputs,
)
from harv_jax.evaluation.summary import summarize_controller
from harv_jax.guards import AUTO_CHUNK_RUNS_PER_CPU_DEVICE, auto_chunk, closed_loop_chunk_bytes
from harv_jax.task.criteria import tracking_errors

N_STEPS = 300  # 3 s: enough for distinct outcomes (most runs TIMEOUT, some DEPARTED)
REF = jnp.array([0.349, 0.0, 0.0])


@pytest.fixture(scope="module")
def mc32():
    inputs = sample_mc_inputs(jax.random.key(3), 32, harv())
    out, wall = run_mc(make_smc(), inputs, REF, N_STEPS, record_every=10, chunk_size=16)
    return inputs, out, wall


def test_outcome_counts_sum_to_runs(mc32):
    _, out, wall = mc32
    s = summarize_controller(out, wall)
    assert sum(s["outcomes"].values()) == 32
    assert set(s["outcomes"]) == {"recovered", "departed", "nonfinite", "timeout"}
    for ch in ("alpha", "beta", "mu"):
        assert set(s["terminal_error_deg"][ch]) >= {
            "mean",
            "std",
            "p5",
            "p50",
            "p95",
            "within_0p5",
            "within_2",
        }


@jax.jit
def _single_run(params, x0_wind, key):
    """One unbatched closed-loop SMC run scored as ``evaluate`` scores it: (RunMetrics, the N_STEPS + 1 wind
    states). Module level: one compile serves the tests below."""
    res = closed_loop(make_smc(), params, x0_wind, REF, key, N_STEPS)
    return score(res, REF, params)


def _run_i(inputs, i):
    return _single_run(jax.tree.map(lambda a: a[i], inputs.params), inputs.x0_wind[i], inputs.keys[i])


def test_mc_equals_single_runs(mc32):
    """The chunked vmapped MC gives, run by run, what 32 single closed-loop runs give."""
    inputs, out, _ = mc32
    for i in range(32):
        m, _ = _run_i(inputs, i)
        assert int(m.outcome) == int(out.metrics.outcome[i])
        np.testing.assert_allclose(np.asarray(m.final_error_rad), out.metrics.final_error_rad[i], atol=1e-5)
        # altitudes near 25,000 ft carry a float32 ulp of 0.002 ft
        np.testing.assert_allclose(float(m.altitude_loss_ft), out.metrics.altitude_loss_ft[i], atol=0.02)


def test_auto_chunk_per_device_memory_and_device_multiple(monkeypatch):
    import harv_jax.guards as guards

    monkeypatch.setattr(guards, "machine_memory_bytes", lambda: 64 * 2**30)
    assert auto_chunk(1000, 6000, 2, 512) == 1000  # under 512 per device: all runs, a multiple of 2
    assert auto_chunk(10_000, 6000, 2, 512) == 1024
    assert auto_chunk(1001, 6000, 2, 512) == 1000
    assert auto_chunk(10_000, 6000, 1, None) == 7_456  # a GPU: all runs, up to 1/8 of memory
    assert closed_loop_chunk_bytes(7_456, 6000) <= 8 * 2**30 < closed_loop_chunk_bytes(7_457, 6000)
    monkeypatch.setattr(guards, "machine_memory_bytes", lambda: 2**30)
    assert auto_chunk(1000, 6000, 2, 512) == 116  # 1/8 GiB at 192 bytes per run-step: 116 runs
    assert auto_chunk(3, 10**9, 2, 512) == 2  # memory share below one run: one run per device
    with pytest.raises(ValueError, match="n_devices=0"):
        auto_chunk(10, 10, 0, 512)


@pytest.mark.slow
def test_default_chunk_is_automatic_recorded_and_equal_in_outcomes(mc32):
    inputs, out16, _ = mc32
    out, wall = run_mc(make_smc(), inputs, REF, N_STEPS, record_every=10)
    expected = auto_chunk(32, N_STEPS, jax.local_device_count(), AUTO_CHUNK_RUNS_PER_CPU_DEVICE)
    assert wall["chunk_runs"] == expected == 32 and summarize_controller(out, wall)["chunk_runs"] == 32
    np.testing.assert_array_equal(out.metrics.outcome, out16.metrics.outcome)  # floats: rounding only
    np.testing.assert_allclose(out.metrics.final_error_rad, out16.metrics.final_error_rad, atol=1e-5)


def test_terminal_error_is_mean_over_last_second(mc32):
    """Terminal error = mean tracking error over the last 1 s, checked on a recomputed trajectory."""
    inputs, out, _ = mc32
    i = 5
    x_all = np.asarray(_run_i(inputs, i)[1])
    n_term = int(round(TERMINAL_WINDOW_S / 0.01))
    expected = np.mean(np.asarray(tracking_errors(jnp.asarray(x_all[-n_term:]), REF)), axis=0)
    np.testing.assert_allclose(out.terminal_error_rad[i], expected, atol=1e-5)
    # the stored history is the decimated alpha, beta, mu of the same trajectory
    np.testing.assert_allclose(out.history[i, :, 0], x_all[:-1:10, 1], atol=1e-5)


def test_summary_percentiles_match_numpy(mc32):
    _, out, wall = mc32
    s = summarize_controller(out, wall)
    e = np.degrees(out.terminal_error_rad[:, 0])
    assert s["terminal_error_deg"]["alpha"]["p50"] == pytest.approx(float(np.percentile(e, 50)))
    assert s["terminal_error_deg"]["alpha"]["p95"] == pytest.approx(float(np.percentile(e, 95)))
    assert s["terminal_error_deg"]["alpha"]["within_2"] == pytest.approx(float(np.mean(np.abs(e) <= 2)))
    tv = np.asarray(out.metrics.control_tv_rad, np.float64)
    assert s["control_tv"]["by_channel"]["aileron"] == pytest.approx(float(tv[:, 1].mean()))
    for block in ("control_tv", "chatter_index"):
        assert sum(s[block]["by_channel"].values()) == pytest.approx(s[block]["mean"], rel=1e-5)


def test_common_random_numbers():
    """Same seed -> identical initial states and aircraft, whatever the controller; other seed differs."""
    sample = jax.jit(sample_mc_inputs, static_argnums=1, static_argnames="randomize")  # one compile
    a = sample(jax.random.key(7), 16, harv(), randomize=True)
    b = sample(jax.random.key(7), 16, harv(), randomize=True)
    c = sample(jax.random.key(8), 16, harv(), randomize=True)
    chex_equal = jax.tree.map(
        lambda x, y: bool(jnp.all(x == y)), (a.x0_wind, a.params), (b.x0_wind, b.params)
    )
    assert all(jax.tree.leaves(chex_equal))
    assert not bool(jnp.all(a.x0_wind == c.x0_wind))
    # the paper's MC samples V, alpha, beta, p, q, r only: mu = gamma = 0
    assert bool(jnp.all(a.x0_wind[:, 6:8] == 0.0))
    # randomized aircraft differ from run to run
    assert float(jnp.std(a.params.mass_slug)) > 0


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--controller", "pid"], "unknown controller 'pid'"),
        (["--runs", "0"], "--runs 0"),
        (["--duration", "-5"], "--duration -5"),
        (["--target-alpha", "3"], "--target-alpha 3"),
        (["--controller", "smc,smc"], "twice"),
        (["--controller", "rl", "--policy", "nowhere.npz"], "policy 'nowhere.npz' does not exist"),
        (["--controller", "smc,hybrid", "--zeta", "bang"], "--zeta 'bang' is unknown"),
    ],
)
def test_bad_flags_one_line_error(tmp_path, args, fragment):
    from harv_jax.cli import main  # noqa: F401  (the entry point turns UsageError into exit 2)

    r = CliRunner().invoke(app, ["mc", *args, "--out", str(tmp_path / "o")], standalone_mode=False)
    assert r.exception is not None and fragment in str(r.exception)
    assert "\n" not in str(r.exception)
    assert not (tmp_path / "o").exists()


def test_cli_writes_outputs_and_refuses_existing_dir(tmp_path, damper):
    """The files of ``mc`` (a cheap registered controller: the point is the outputs, not the SMC)."""
    out = tmp_path / "mc"
    args = ["mc", "--controller", damper, "--runs", "8", "--duration", "11", "--chunk", "8",
            "--out", str(out), "--save-trajectories"]  # fmt: skip
    r = CliRunner().invoke(app, args, standalone_mode=False)
    assert r.exception is None, r.output
    # the bands are the numpy percentiles of the saved trajectories
    tr = np.load(out / "trajectories_damper.npz", allow_pickle=False)
    bands = np.loadtxt(out / "bands_damper.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(bands[:, 0], tr["t_s"], atol=1e-9)
    deg = np.degrees(tr["alpha_beta_mu_rad"])
    assert deg.shape[0] == 8
    for i in range(3):
        for j, q in enumerate((5, 25, 50, 75, 95)):
            np.testing.assert_allclose(
                bands[:, 1 + 5 * i + j], np.percentile(deg[:, :, i], q, axis=0), rtol=1e-5, atol=1e-5
            )
    s = json.loads((out / "summary.json").read_text())
    assert s["runs"] == 8 and sum(s["controllers"][damper]["outcomes"].values()) == 8
    for f in ("bands_damper.png", "terminal_errors.png", "runs.csv"):
        assert (out / f).stat().st_size > 0
    before = (out / "summary.json").read_text()
    r = CliRunner().invoke(app, args, standalone_mode=False)
    assert r.exception is not None and "--force" in str(r.exception)
    assert (out / "summary.json").read_text() == before
