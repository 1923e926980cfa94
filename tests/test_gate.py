"""Certificate-gated zeta: identity where the policy meets the reaching condition, the condition met wherever
the box allows it, zeta = 1 is the SMC command, vmap over aircraft, one trace, the fixture policies."""

from __future__ import annotations

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from compile_options import FAST_COMPILE
from policy_fixtures import FIXTURE_POLICIES, write_fixture_policies

from harv_jax.aircraft import harv
from harv_jax.control.hybrid.gate import certificate_bounds, gate, inv3, signed_residual
from harv_jax.control.hybrid.law import HybridConfig, default_hybrid_gains, make_hybrid
from harv_jax.control.hybrid.safety import limit_box
from harv_jax.control.smc import SMCConfig, smc_command
from harv_jax.policy import load
from harv_jax.task.scenarios import sample_table_states

REF = jnp.array([0.349, 0.0, 0.0])
G = default_hybrid_gains(jnp.float32)
NO_MU_BLEND = jnp.zeros((3,), bool)
WIDE_LO, WIDE_HI = jnp.full((3,), -10.0), jnp.full((3,), 10.0)
DT = 0.01


@jax.jit
def _bounds(s):
    return jax.vmap(lambda si: certificate_bounds(si, G.smc, G.gate, "sat", DT))(s)


def _nominal():
    return jax.tree.map(lambda a: jnp.asarray(a, jnp.float32), harv())


def _synthetic(key, n):
    """Well-conditioned A, s, u_RL, u_fb [n, ...]."""
    k1, k2, k3, k4 = jax.random.split(key, 4)
    a = jnp.eye(3)[None] * 5.0 + jax.random.normal(k1, (n, 3, 3))
    s = jax.random.normal(k2, (n, 3)) * 0.5
    return a, s, jax.random.normal(k3, (n, 3)) * 0.1, jax.random.normal(k4, (n, 3)) * 0.1


def _gate(u_rl, u_fb, a, s, lo, hi, unchecked=NO_MU_BLEND, force=False):
    return gate(u_rl, u_fb, a, s, lo, hi, G.smc, G.gate, "sat", DT, unchecked, jnp.asarray(force))


@jax.jit
def _gate_wide(u_rl, u_fb, a, s, unchecked, force):
    """``_gate`` over a batch in the wide box; ``unchecked`` and ``force`` traced (one compile per size)."""
    return jax.vmap(lambda *z: _gate(*z, WIDE_LO, WIDE_HI, unchecked, force))(u_rl, u_fb, a, s)


def test_gate_is_the_identity_where_the_policy_meets_the_condition():
    a, s, u_rl, _ = _synthetic(jax.random.key(0), 512)  # the batch size of the next test: one compile
    upper, lower = _bounds(s)
    # a policy whose residual r(u_RL) = -A u_fb meets -L <= sign(s) r <= U on every channel
    frac = jax.random.uniform(jax.random.key(1), (512, 3), minval=0.0, maxval=0.99)
    side = jax.random.bernoulli(jax.random.key(6), 0.5, (512, 3))
    r = jnp.where(s >= 0, 1.0, -1.0) * frac * jnp.where(side, upper, -lower)
    u_fb = -jnp.linalg.solve(a, r[..., None])[..., 0]
    res = _gate_wide(u_rl, u_fb, a, s, NO_MU_BLEND, False)
    assert bool(jnp.all(res.zeta == 0.0))
    np.testing.assert_array_equal(res.u_raw_rad, u_rl)  # bit for bit


def test_least_zeta_meets_the_condition_with_equality_and_zeta_one_is_the_smc_command():
    a, s, u_rl, u_fb = _synthetic(jax.random.key(2), 512)
    res = _gate_wide(u_rl, u_fb, a, s, NO_MU_BLEND, False)
    upper, lower = _bounds(s)
    q = jax.jit(jax.vmap(signed_residual))(a, res.u_raw_rad, u_rl + u_fb, s)
    assert bool(jnp.all((q <= upper + 1e-4) & (q >= -lower - 1e-4)))
    inner = (res.zeta > 0) & (res.zeta < 1)
    assert int(jnp.sum(inner)) > 50 and int(jnp.sum(res.zeta == 0)) > 50
    bound = jnp.where(q > 0, upper, -lower)
    np.testing.assert_allclose(q[inner], bound[inner], atol=1e-4)  # least zeta: the condition is tight
    forced = _gate_wide(u_rl, u_fb, a, s, NO_MU_BLEND, True)
    assert bool(jnp.all(forced.zeta == 1.0))
    np.testing.assert_array_equal(forced.u_raw_rad, u_rl + u_fb)
    mu_blend = jnp.array([False, False, True])
    res_mu = _gate_wide(u_rl, u_fb, a, s, mu_blend, False)
    assert bool(jnp.all(res_mu.zeta[:, 2] == 1.0))


@pytest.fixture(scope="module")
def real_steps():
    """Gate inputs on sampled aircraft states with a random policy command and a random rate box."""
    params = _nominal()
    n = 256
    k1, k2, k3 = jax.random.split(jax.random.key(3), 3)
    xs = sample_table_states(k1, n)
    u_rl = jax.random.uniform(k2, (n, 3), minval=params.u_min_rad, maxval=params.u_max_rad)
    u_prev = jax.random.uniform(k3, (n, 3), minval=params.u_min_rad, maxval=params.u_max_rad)
    integral = jnp.zeros((3,))

    @jax.jit
    @jax.vmap
    def one(x, ur, up):
        u_fb, terms = smc_command(x, REF, integral, params, G.smc, SMCConfig(), u_offset_rad=ur)
        lo, hi = limit_box(up, params, 0.01)
        blend = jnp.stack([jnp.asarray(False), jnp.asarray(False), terms.w_mu < 1.0])
        res = gate(ur, u_fb, terms.decoupling, terms.s, lo, hi, G.smc, G.gate, "sat", DT, blend,
                   terms.solve.guard_active)  # fmt: skip
        u_smc = ur + u_fb
        q = signed_residual(terms.decoupling, jnp.clip(res.u_raw_rad, lo, hi), u_smc, terms.s)
        q_smc = signed_residual(terms.decoupling, jnp.clip(u_smc, lo, hi), u_smc, terms.s)
        upper, lower = certificate_bounds(terms.s, G.smc, G.gate, "sat", DT)
        checked = ~blend & ~terms.solve.guard_active
        return res, q, q_smc, upper, lower, checked

    return one(xs, u_rl, u_prev)


def test_gated_command_meets_the_condition_wherever_the_box_allows_it(real_steps):
    res, q, q_smc, upper, lower, checked = real_steps
    tol = 1e-4 * (1.0 + jnp.abs(upper))
    # wherever the box-clipped SMC command meets the condition on a channel, the gated command does too
    feasible = checked & (q_smc <= upper) & (q_smc >= -lower)
    assert int(jnp.sum(feasible)) > 100
    assert bool(jnp.all(jnp.where(feasible, (q <= upper + tol) & (q >= -lower - tol), True)))
    # elsewhere at least the SMC's own progress
    ok = (q <= jnp.maximum(upper, q_smc) + tol) & (q >= jnp.minimum(-lower, q_smc) - tol)
    assert bool(jnp.all(jnp.where(checked, ok, True)))
    assert bool(jnp.all((res.zeta >= 0) & (res.zeta <= 1)))
    assert float(jnp.mean(res.zeta < 1)) > 0.05  # the random policy is not always overridden


@chex.assert_max_traces(n=1)
def _apply_batch(hy, params, x, state):
    return jax.vmap(hy.apply, in_axes=(0, 0, None, None))(state, x, REF, jax.random.key(0))


@pytest.mark.slow
def test_gated_hybrid_vmaps_over_aircraft_equal_to_single_runs_with_one_trace(tmp_path):
    pol = load(write_fixture_policies(tmp_path)["random"]).deterministic
    hy = make_hybrid(pol, HybridConfig(schedule="gated"))
    n = 6
    base = _nominal()
    params = jax.vmap(lambda s: base.replace(mass_slug=base.mass_slug * s))(jnp.linspace(0.9, 1.1, n))
    xs = sample_table_states(jax.random.key(4), n)
    state = jax.vmap(hy.init)(params)
    f = jax.jit(_apply_batch, static_argnums=0, compiler_options=FAST_COMPILE)
    u, state2, info = f(hy, params, xs, state)
    f(hy, params, xs, state2)  # second call: no retrace
    assert info["zeta_channels"].shape == (n, 3) and info["zeta"].shape == (n,)
    single = jax.jit(hy.apply, compiler_options=FAST_COMPILE)
    for i in range(n):
        p_i = jax.tree.map(lambda a, i=i: a[i], params)
        u_i, _, info_i = single(hy.init(p_i), xs[i], REF, jax.random.key(0))
        np.testing.assert_allclose(u[i], u_i, rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(info["zeta_channels"][i], info_i["zeta_channels"], atol=1e-5)


def test_fixture_policies_load_and_behave_as_named(tmp_path):
    paths = write_fixture_policies(tmp_path)
    assert tuple(paths) == FIXTURE_POLICIES
    xs = sample_table_states(jax.random.key(5), 64)
    from harv_jax.task.spaces import observation

    obs = jax.vmap(lambda x: observation(x, REF))(xs)
    acts = {k: np.asarray(load(p).deterministic(obs)) for k, p in paths.items()}
    assert np.all(acts["zero"] == 0.0)
    assert np.all(np.abs(acts["bang-bang"]) == 1.0) and np.all(np.std(acts["bang-bang"], axis=0) > 0.5)
    assert np.all(np.std(acts["random"], axis=0) > 0.1) and np.mean(np.abs(acts["random"]) < 1.0) > 0.5


def test_gate_summary_pools_steps_over_runs():
    from harv_jax.evaluation.montecarlo.rollout import gate_summary

    rng = np.random.default_rng(0)
    n = 5
    defined = rng.uniform(0.2, 0.6, (n, 3))
    info = {
        "zeta_channels": rng.uniform(0, 1, (n, 3)),
        "policy_unmodified": rng.uniform(0, 1, n),
        "correction_rad": rng.uniform(0, 0.1, (n, 3)),
        "cert_free_defined": defined,
        "cert_free_holds": defined * 0.9,
        "cert_sat_defined": 1.0 - defined,
        "cert_sat_holds": (1.0 - defined) * rng.uniform(0, 1, (n, 3)),
    }
    s = gate_summary(info)
    np.testing.assert_allclose(list(s["certificate"]["holds_unsaturated"].values()), 0.9)
    sat = info["cert_sat_holds"].sum(0) / info["cert_sat_defined"].sum(0)
    np.testing.assert_allclose(list(s["certificate"]["holds_saturated"].values()), sat)
    np.testing.assert_allclose(s["certificate"]["saturated_step_fraction"], np.mean(1.0 - defined))
    np.testing.assert_allclose(list(s["zeta_mean_by_channel"].values()), info["zeta_channels"].mean(0))
    assert gate_summary({"zeta": np.zeros(n)}) == {}


@pytest.mark.slow
def test_mc_cli_flies_the_gated_hybrid_and_summarizes_it(tmp_path):
    import json

    from typer.testing import CliRunner

    from harv_jax.cli import app

    pol = write_fixture_policies(tmp_path)["bang-bang"]
    out = tmp_path / "mc"
    args = ["mc", "--controller", "hybrid", "--zeta", "gated", "--policy", str(pol), "--runs", "2",
            "--duration", "10.5", "--chunk", "2", "--out", str(out)]  # fmt: skip
    r = CliRunner().invoke(app, args, standalone_mode=False)
    assert r.exception is None, r.output
    s = json.loads((out / "summary.json").read_text())
    assert s["zeta_schedule"] == "gated"
    h = s["controllers"]["hybrid"]["hybrid"]
    assert all(0.0 <= v <= 1.0 for v in h["zeta_mean_by_channel"].values())
    assert 0.0 <= h["policy_unmodified_fraction"] <= 1.0
    assert all(v is None or 0.0 <= v <= 1.0 for v in h["certificate"]["holds_saturated"].values())


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_inv3_equals_lapack_to_condition_times_rounding(dtype):
    a = np.random.default_rng(0).normal(size=(2000, 3, 3))
    with jax.enable_x64(dtype == np.float64):
        got = np.asarray(jax.vmap(inv3)(jnp.asarray(a, dtype)), np.float64)
    ref = np.linalg.inv(a)
    err = np.max(np.abs(got - ref), axis=(1, 2)) / np.max(np.abs(ref), axis=(1, 2))
    assert np.all(err <= 8.0 * np.linalg.cond(a) * np.finfo(dtype).eps)
    singular = inv3(jnp.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]]))
    assert not np.all(np.isfinite(np.asarray(singular)))  # the gate then falls back to the SMC command
