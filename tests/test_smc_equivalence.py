"""The SMC step equals the slower reference implementation: Lie terms, solve, command, MC.

The references are the previous implementations, kept verbatim in ``tests/speed_reference.py``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from speed_reference import (
    guarded_solve_reference,
    smc_lie_terms_reference,
    use_reference,
)

from harv_jax.aircraft import harv
from harv_jax.control.lie import smc_lie_terms
from harv_jax.control.smc import SMCConfig, default_gains, guarded_solve, make_smc, smc_command
from harv_jax.evaluation.monte_carlo import run_mc, sample_mc_inputs
from harv_jax.evaluation.summary import summarize_controller

REF = jnp.array([0.349, 0.0, 0.0])
#: Wide state box: deep stall, inverted, steep, fast and slow [V, alpha, beta, p, q, r, mu, gamma, chi, h].
LO = np.array([100.0, -0.5, -0.4, -2.0, -1.0, -1.0, -3.0, -1.4, -3.0, 5000.0])
HI = np.array([1500.0, 1.6, 0.4, 2.0, 1.0, 1.0, 3.0, 1.4, 3.0, 40000.0])


def _states(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(LO, HI, (n, 10))


def _scaled_diff(new, old) -> float:
    """Largest |new - old| per sample relative to the largest |old| of that sample (over all its entries)."""
    new, old = np.asarray(new, np.float64), np.asarray(old, np.float64)
    new, old = new.reshape(new.shape[0], -1), old.reshape(old.shape[0], -1)
    return float(np.max(np.max(np.abs(new - old), axis=1) / (np.max(np.abs(old), axis=1) + 1e-30)))


@pytest.mark.parametrize("dtype, tol", [(jnp.float32, 2e-5), (jnp.float64, 1e-12)])
def test_lie_terms_equal_reference(dtype, tol):
    with jax.enable_x64(dtype == jnp.float64):
        params = jax.tree.map(lambda a: jnp.asarray(a, dtype), harv())
        xs = jnp.asarray(_states(512, 0), dtype)
        new = jax.jit(jax.vmap(lambda x: smc_lie_terms(x, params)))(xs)
        old = jax.jit(jax.vmap(lambda x: smc_lie_terms_reference(x, params)))(xs)
        for name, a, b in zip(
            ("y", "lf_y", "lf2_y", "lglf_y", "p_w", "lf_pw", "lg_pw"),
            (*new[0], *new[1]),
            (*old[0], *old[1]),
            strict=True,
        ):
            assert _scaled_diff(a, b) < tol, name


def _matrices(n: int, seed: int) -> np.ndarray:
    """3x3 matrices with condition numbers from 1 to 1e7, rank-deficient ones, zeros and NaN/inf entries."""
    rng = np.random.default_rng(seed)
    q1 = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    q2 = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    cond = 10.0 ** rng.uniform(0, 7, n)
    s = np.stack([np.ones(n), 10.0 ** rng.uniform(-1, 0, n) * np.ones(n), 1 / cond], 1)
    s = s * 10.0 ** rng.uniform(-3, 2, (n, 1))
    a = np.einsum("nij,nj,nkj->nik", q1, s, q2)
    a[:8] = 0.0
    a[8:16, 2] = a[8:16, 0] * 2.0  # rank 2
    a[16:24, 1, 1] = np.nan
    a[24:32, 0, 2] = np.inf
    return a


def _solve(fn, a: np.ndarray, b: np.ndarray, dtype):
    args = (jnp.asarray(1e3, dtype), jnp.asarray(1e-4, dtype))
    return jax.jit(jax.vmap(lambda aa, bb: fn(aa, bb, *args)))(jnp.asarray(a, dtype), jnp.asarray(b, dtype))


def test_guarded_solve_equals_lapack_svd_reference():
    """Jacobi SVD vs LAPACK SVD: equal in float64; in float32 equal where well conditioned and no less
    accurate (against float64) where the damping acts (cond up to 1e7: there both lose digits)."""
    a = _matrices(2048, 1)
    b = np.random.default_rng(2).normal(size=(2048, 3))
    with jax.enable_x64(True):
        u64, i64 = _solve(guarded_solve, a, b, jnp.float64)
        u64_ref, i64_ref = _solve(guarded_solve_reference, a, b, jnp.float64)
        u64, u64_ref = np.asarray(u64), np.asarray(u64_ref)
        i64, i64_ref = jax.device_get((i64, i64_ref))
    np.testing.assert_array_equal(i64.guard_active, i64_ref.guard_active)
    assert 0.2 < float(np.mean(i64_ref.guard_active)) < 0.9  # both branches are exercised
    scale = np.maximum(np.max(np.abs(u64_ref), axis=1), 1e-300)
    assert float(np.max(np.max(np.abs(u64 - u64_ref), axis=1) / scale)) < 1e-8
    np.testing.assert_allclose(i64.rho2, i64_ref.rho2, rtol=1e-8, atol=1e-20)
    ok = i64_ref.cond < 1e12  # (exactly rank-deficient matrices: s_min is rounding, cond meaningless)
    np.testing.assert_allclose(i64.cond[ok], i64_ref.cond[ok], rtol=1e-6)

    (u32, i32), (u32_ref, i32_ref) = (
        _solve(fn, a, b, jnp.float32) for fn in (guarded_solve, guarded_solve_reference)
    )
    err = np.max(np.abs(np.asarray(u32, np.float64) - u64_ref), axis=1) / scale
    err_ref = np.max(np.abs(np.asarray(u32_ref, np.float64) - u64_ref), axis=1) / scale
    well = ~np.asarray(i64_ref.guard_active) & np.all(np.isfinite(a), axis=(1, 2))
    assert well.sum() > 200
    assert float(np.max(err[well])) < 1e-4 and float(np.max(err_ref[well])) < 1e-4
    assert np.max(err) <= np.max(err_ref) and np.percentile(err, 99) <= np.percentile(err_ref, 99)
    np.testing.assert_array_equal(np.asarray(i32.guard_active)[well], np.asarray(i32_ref.guard_active)[well])


def test_command_equals_reference_on_random_states():
    params, gains = harv(), default_gains()
    xs = jnp.asarray(_states(1024, 3), jnp.float32)
    ints = jnp.asarray(np.random.default_rng(4).uniform(-0.3, 0.3, (1024, 3)), jnp.float32)
    u_rl = jnp.asarray(np.random.default_rng(5).uniform(-0.2, 0.2, (1024, 3)), jnp.float32)

    def cmd(x, i, off):
        return smc_command(x, REF, i, params, gains, SMCConfig(), off)

    def both(x, i, off):  # the SMC law and the hybrid's feedback term (u_offset = u_RL)
        return cmd(x, i, None), cmd(x, i, off)

    new = jax.jit(jax.vmap(both))(xs, ints, u_rl)
    with use_reference():
        old = jax.jit(jax.vmap(both))(xs, ints, u_rl)
    for (u_n, t_n), (u_o, t_o) in zip(new, old, strict=True):
        assert _scaled_diff(u_n, u_o) < 1e-4
        assert _scaled_diff(t_n.s, t_o.s) < 1e-5
        np.testing.assert_array_equal(t_n.solve.guard_active, t_o.solve.guard_active)
        np.testing.assert_allclose(t_n.solve.cond, t_o.solve.cond, rtol=1e-3)


def _mc(n_runs: int, n_steps: int):
    inputs = sample_mc_inputs(jax.random.key(0), n_runs, harv())
    out, wall = run_mc(make_smc(), inputs, REF, n_steps, record_every=10, chunk_size=n_runs)
    return out, summarize_controller(out, wall, n_steps)


def _assert_mc_equal(new, old):
    (out_n, sum_n), (out_o, sum_o) = new, old
    np.testing.assert_array_equal(out_n.metrics.outcome, out_o.metrics.outcome)
    np.testing.assert_array_equal(out_n.metrics.recovered, out_o.metrics.recovered)
    np.testing.assert_allclose(out_n.metrics.t_recover_s, out_o.metrics.t_recover_s, atol=0.05)
    # alpha, beta, mu every 0.1 s: float32 rounding differences grow in transients (the 256-run, 60 s
    # Monte Carlo: 29 of 460,800 samples beyond 2e-3 rad, at most 3.1e-3 rad, all in one run's mu)
    diff = np.abs(out_n.history - out_o.history)
    assert float(np.mean(diff < 1e-3)) > 0.999
    np.testing.assert_allclose(out_n.history, out_o.history, atol=1e-2)
    np.testing.assert_allclose(out_n.terminal_error_rad, out_o.terminal_error_rad, atol=1e-4)
    assert sum_n["outcomes"] == sum_o["outcomes"]
    assert sum_n["recovery_rate"] == sum_o["recovery_rate"]
    for key in ("mean", "p50", "p95"):  # (None where no run recovered)
        t_n, t_o = sum_n["recovery_time_s"][key], sum_o["recovery_time_s"][key]
        assert (t_n is None) == (t_o is None)
        if t_o is not None:
            np.testing.assert_allclose(t_n, t_o, atol=0.02)
    np.testing.assert_allclose(sum_n["control_tv"]["mean"], sum_o["control_tv"]["mean"], rtol=1e-3)


def test_monte_carlo_equals_reference_short():
    """16 runs x 10 s (the default suite's size; the 256-run, 60 s version is marked slow)."""
    new = _mc(16, 1000)
    with use_reference():
        old = _mc(16, 1000)
    _assert_mc_equal(new, old)


@pytest.mark.slow
def test_monte_carlo_256_runs_60_s_equals_reference():
    new = _mc(256, 6000)
    with use_reference():
        old = _mc(256, 6000)
    assert new[1]["recovery_rate"] > 0.95
    _assert_mc_equal(new, old)
