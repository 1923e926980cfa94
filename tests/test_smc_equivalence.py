"""The SMC step and the model give the stored outputs: Lie terms, guarded solve, command, Monte Carlo.

The outputs and how they are made and regenerated: ``tests/smc_reference_outputs.py``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from smc_reference_outputs import (
    LIE_NAMES,
    MC_LONG,
    MC_SHORT,
    N_SOLVE,
    command,
    lie_terms,
    load,
    matrices,
    monte_carlo,
    solve,
)

STORED = load()


def _stored(group: str) -> dict[str, np.ndarray]:
    return {k.split("/", 1)[1]: v for k, v in STORED.items() if k.startswith(group + "/")}


def _scaled_diff(new, old) -> float:
    """Largest |new - old| per sample relative to the largest |old| of that sample (over all its entries)."""
    new, old = np.asarray(new, np.float64), np.asarray(old, np.float64)
    new, old = new.reshape(new.shape[0], -1), old.reshape(old.shape[0], -1)
    return float(np.max(np.max(np.abs(new - old), axis=1) / (np.max(np.abs(old), axis=1) + 1e-30)))


def test_stored_outputs_are_small_and_complete():
    assert {k.split("/")[0] for k in STORED} == {
        "lie32",
        "lie64",
        "solve32",
        "solve64",
        "command",
        "mc",
        "mc_long",
    }
    assert sum(v.nbytes for v in STORED.values()) < 400_000


@pytest.mark.parametrize("dtype, tol", [(jnp.float32, 1e-5), (jnp.float64, 1e-12)])
def test_lie_terms_equal_stored(dtype, tol):
    group = "lie32" if dtype == jnp.float32 else "lie64"
    with jax.enable_x64(dtype == jnp.float64):
        new = lie_terms(dtype)
    old = _stored(group)
    for name in LIE_NAMES:
        assert new[name].dtype == old[name].dtype, name
        assert _scaled_diff(new[name], old[name]) < tol, name


def _oracle_singular_values(dtype) -> np.ndarray:
    """[N_SOLVE, 3] singular values (float64, numpy) of the solve's matrices as rounded to ``dtype``; rows of
    matrices with a non-finite entry are NaN."""
    a = np.asarray(np.asarray(matrices(N_SOLVE, 1), dtype), np.float64)
    s = np.full((N_SOLVE, 3), np.nan)
    ok = np.all(np.isfinite(a.reshape(N_SOLVE, -1)), axis=1)
    s[ok] = np.linalg.svd(a[ok], compute_uv=False)
    return s


@pytest.mark.parametrize("dtype, tol", [(jnp.float32, 1e-5), (jnp.float64, 1e-12)])
def test_guarded_solve_equals_stored(dtype, tol):
    """Both branches (damped or not), zeros, rank-deficient and non-finite matrices.

    In float32 the solve's rounding depends on the CPU's instructions, and an ill-conditioned matrix magnifies
    it by its condition number: there u and cond agree with the stored outputs to 10 eps cond (the
    condition number of the matrix from a float64 oracle) and rho2 to 10 eps s_max^2, and at least to ``tol``
    where that is larger; float64 to ``tol``. For a matrix with a non-finite entry only the finiteness of u is
    compared (its value is the rounding of a degenerate factorization).
    """
    with jax.enable_x64(dtype == jnp.float64):
        new = solve(dtype)
    old = _stored("solve32" if dtype == jnp.float32 else "solve64")
    np.testing.assert_array_equal(new["guard_active"], old["guard_active"])
    assert 0.2 < float(np.mean(old["guard_active"])) < 0.9  # both branches are exercised
    np.testing.assert_array_equal(np.isfinite(new["u"]), np.isfinite(old["u"]))
    sv = _oracle_singular_values(dtype)
    finite_a = np.all(np.isfinite(sv), axis=1)
    # a zero matrix counts as well-conditioned (u = 0 exactly); a singular one as infinitely ill-conditioned
    cond = np.where(sv[:, 2] > 0, sv[:, 0] / np.where(sv[:, 2] > 0, sv[:, 2], 1.0), np.inf)
    cond = np.where(sv[:, 0] > 0, cond, 1.0)
    k_eps = 10 * float(np.finfo(np.float32).eps) if dtype == jnp.float32 else 0.0
    if k_eps == 0.0:
        cond = np.ones_like(cond)  # float64: ``tol`` alone
    fin = finite_a & np.all(np.isfinite(old["u"]), axis=1)
    u_tol = np.maximum(tol, k_eps * cond[fin])
    u_new, u_old = np.asarray(new["u"], np.float64)[fin], np.asarray(old["u"], np.float64)[fin]
    scaled = np.max(np.abs(u_new - u_old), axis=1) / (np.max(np.abs(u_old), axis=1) + 1e-30)
    assert np.all(scaled <= u_tol), float(np.max(scaled / u_tol))
    rho2_new, rho2_old = np.asarray(new["rho2"], np.float64), np.asarray(old["rho2"], np.float64)
    rho2_tol = np.maximum(tol * np.abs(rho2_old[finite_a]), k_eps * sv[finite_a, 0] ** 2) + 1e-30
    assert np.all(np.abs(rho2_new[finite_a] - rho2_old[finite_a]) <= rho2_tol)
    ok = (old["cond"] < 1e5) & finite_a & (sv[:, 0] > 0)  # (near rank-deficient: s_min is rounding)
    cond_tol = np.maximum(100 * tol, k_eps * cond[ok])
    rel = np.abs(np.asarray(new["cond"], np.float64)[ok] / np.asarray(old["cond"], np.float64)[ok] - 1.0)
    assert np.all(rel <= cond_tol), float(np.max(rel / cond_tol))


def test_command_equals_stored():
    """The SMC law and the hybrid's feedback term (u_offset = u_RL) on random states, float32."""
    new, old = command(), _stored("command")
    for name in ("smc", "offset"):
        assert _scaled_diff(new[f"{name}_u"], old[f"{name}_u"]) < 1e-5
        assert _scaled_diff(new[f"{name}_s"], old[f"{name}_s"]) < 1e-5
        np.testing.assert_array_equal(new[f"{name}_guard_active"], old[f"{name}_guard_active"])
        np.testing.assert_allclose(new[f"{name}_cond"], old[f"{name}_cond"], rtol=1e-4)


def _assert_mc_equal(new: dict[str, np.ndarray], old: dict[str, np.ndarray]) -> None:
    np.testing.assert_array_equal(new["outcome"], old["outcome"])
    np.testing.assert_array_equal(new["recovered"], old["recovered"])
    np.testing.assert_allclose(new["t_recover_s"], old["t_recover_s"], atol=0.011)
    np.testing.assert_allclose(new["terminal_error_rad"], old["terminal_error_rad"], atol=1e-5)
    np.testing.assert_array_equal(new["recovery_rate"], old["recovery_rate"])
    np.testing.assert_allclose(new["control_tv_mean"], old["control_tv_mean"], rtol=1e-4)


def test_monte_carlo_equals_stored_short():
    """16 runs x 10 s, alpha, beta, mu every 0.1 s (the default suite's size; 256 runs x 60 s: slow)."""
    new, old = monte_carlo(*MC_SHORT, history=True), _stored("mc")
    _assert_mc_equal(new, old)
    np.testing.assert_allclose(new["history"], old["history"], atol=1e-4)


@pytest.mark.slow
def test_monte_carlo_256_runs_60_s_equals_stored():
    new, old = monte_carlo(*MC_LONG, history=False), _stored("mc_long")
    assert float(new["recovery_rate"]) > 0.95
    _assert_mc_equal(new, old)
