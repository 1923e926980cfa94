"""Hybrid controller: identities with SMC-only and RL-only, no Zeno, safety filter, supervisor, vmap."""

from __future__ import annotations

import functools

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from compile_options import FAST_COMPILE

from harv_jax.aircraft import harv
from harv_jax.control import make_smc
from harv_jax.control.hybrid.law import HybridConfig, default_hybrid_gains, make_hybrid, zero_policy_action
from harv_jax.control.hybrid.safety import cap_authority, filter_command, limit_box
from harv_jax.control.hybrid.supervisor import (
    FallbackReason,
    default_supervisor_gains,
    record_intervention,
    supervise,
    supervisor_init,
)
from harv_jax.control.hybrid.zeta import continuous_zeta, hysteresis_step, zeta_init
from harv_jax.control.rl import make_rl_controller
from harv_jax.evaluation import closed_loop
from harv_jax.evaluation.certificate import empirical_certificate, unsaturated_steps

DT = 0.01
REF = jnp.array([0.349, 0.0, 0.0])
#: A disturbed state inside the trusted box: alpha 0.6, p 0.5, r 0.3.
X0 = jnp.array([500.0, 0.60, 0.05, 0.5, -0.05, 0.3, 0.4, 0.1, 0.0, 20000.0])


def _nominal():
    return jax.tree.map(lambda a: jnp.asarray(a, jnp.float32), harv())


def _linear_policy(seed: int = 0):
    """A fixed random 'policy': tanh of a linear map of the scaled observation, actions in (-1, 1)."""
    w = jax.random.normal(jax.random.key(seed), (11, 3)) * 0.5
    scale = jnp.array([1 / 500.0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1])
    return lambda obs: jnp.tanh((obs * scale) @ w)


@functools.partial(jax.jit, static_argnums=(0, 1), compiler_options=FAST_COMPILE)
def _fly(ctrl, n_steps, params, x0, delta0=None):
    return closed_loop(ctrl, params, x0, REF, jax.random.key(0), n_steps, delta0_rad=delta0)


#: The pro-spin deflections (de, da, dr), rad: a start far from zero deflection.
SPIN_DELTA0 = jnp.array([-0.436, 0.436, 0.524])


def test_zero_policy_with_zeta_one_equals_smc():
    params = _nominal()
    za = zero_policy_action(params)
    hy = make_hybrid(lambda obs: za, HybridConfig(schedule="always", supervisor=False))
    # from the pro-spin deflections: the filter's rate box starts at the actual deflections
    r_h = _fly(hy, 600, params, X0, SPIN_DELTA0)
    r_s = _fly(make_smc(), 600, params, X0, SPIN_DELTA0)
    np.testing.assert_allclose(r_h.traj.delta_rad, r_s.traj.delta_rad, atol=1e-5)
    np.testing.assert_allclose(r_h.traj.x_wind[:, 1:9], r_s.traj.x_wind[:, 1:9], atol=1e-5)
    np.testing.assert_allclose(r_h.traj.x_wind[:, 0], r_s.traj.x_wind[:, 0], rtol=1e-5)
    assert float(jnp.max(jnp.abs(r_h.traj.info["u_rl_rad"]))) < 1e-6


def test_any_policy_with_zeta_one_is_the_smc_command():
    """u_RL + u_fb = u_SMC where the solve is unguarded (the identity of the paper's law), per step."""
    params = _nominal()
    hy = make_hybrid(_linear_policy(1), HybridConfig(schedule="always", supervisor=False))
    smc = make_smc()
    dx = jnp.array([0, 0.1, 0.02, 0.2, 0.1, -0.1, 0.3, 0.05, 0, 0])
    xs = X0[None, :] + jnp.linspace(-1, 1, 5)[:, None] * dx[None, :]

    @jax.jit
    def both(x):
        u_h, _, info_h = hy.apply(hy.init(params), x, REF, jax.random.key(0))
        _, _, info_s = smc.apply(smc.init(params), x, REF, jax.random.key(0))
        return info_h["u_rl_rad"] + info_h["u_fb_rad"], info_s["u_unsat_rad"], info_s["guard_active"]

    for x in xs:
        u_sum, u_smc, guard = both(x)
        assert not bool(guard)
        np.testing.assert_allclose(u_sum, u_smc, rtol=1e-4, atol=1e-5)


def test_zeta_zero_equals_filtered_rl_only():
    params = _nominal()
    pol = _linear_policy(2)
    hy = make_hybrid(pol, HybridConfig(schedule="never", supervisor=False))
    r_h = _fly(hy, 600, params, X0, SPIN_DELTA0)
    r_r = _fly(make_rl_controller(pol), 600, params, X0, SPIN_DELTA0)
    # the filter's box is the plant's own position/rate limits: the deflections are identical
    np.testing.assert_allclose(r_h.traj.delta_rad, r_r.traj.delta_rad, atol=1e-6)
    np.testing.assert_allclose(r_h.traj.x_wind[:, 1:9], r_r.traj.x_wind[:, 1:9], atol=1e-5)
    assert float(jnp.max(r_h.traj.info["zeta"])) == 0.0


def test_hysteresis_switches_on_outer_and_off_inner_tube():
    st = zeta_init(jnp.float32)
    on, off, dwell = jnp.float32(0.05), jnp.float32(0.02), jnp.float32(0.0)
    seq = [0.03, 0.06, 0.04, 0.03, 0.019, 0.04, 0.051]
    expect = [0, 1, 1, 1, 0, 0, 1]
    for e, z in zip(seq, expect, strict=True):
        st, _ = hysteresis_step(st, jnp.array([0.0, e, -0.001]), on, off, dwell, DT)
        assert int(st.on) == z, (e, z)
    assert int(st.n_switches) == 3


def test_hysteresis_no_zeno_on_noisy_error():
    key = jax.random.key(3)
    n = 5000
    # error hovering across both tube radii with noise larger than the tube width
    e = 0.035 + 0.03 * jax.random.normal(key, (n,))
    g = default_hybrid_gains(jnp.float32)

    def step(st, ei):
        st, sw = hysteresis_step(
            st, jnp.array([ei, 0.0, 0.0]), g.e_on_rad, g.e_off_rad, g.zeta_min_dwell_s, DT
        )
        return st, sw

    st, switched = jax.lax.scan(step, zeta_init(jnp.float32), e)
    t_sw = np.flatnonzero(np.asarray(switched)) * DT
    assert t_sw.size >= 10  # it does switch, often
    assert np.min(np.diff(t_sw)) >= float(g.zeta_min_dwell_s) - 1e-6
    assert int(st.n_switches) == t_sw.size


def test_continuous_zeta_limits_and_monotone():
    on, off = jnp.float32(0.05), jnp.float32(0.02)
    es = jnp.linspace(0.0, 0.08, 81)
    z = jax.vmap(lambda e: continuous_zeta(jnp.array([e, -e / 2, 0.0]), on, off))(es)
    assert float(z[0]) == 0.0 and float(z[-1]) == 1.0
    assert bool(jnp.all(jnp.diff(z) >= 0))
    assert float(continuous_zeta(jnp.array([jnp.nan, 0.0, 0.0]), on, off)) == 1.0


def test_safety_filter_idempotent_and_within_limits():
    params = _nominal()
    u_min, u_max = np.asarray(params.u_min_rad), np.asarray(params.u_max_rad)
    rate = np.asarray(params.u_rate_max_radps)
    rng = np.random.default_rng(4)
    n = 2000
    span = u_max - u_min
    u_prev = (u_min + rng.uniform(size=(n, 3)) * span).astype(np.float32)
    u = (u_min - 0.5 * span + rng.uniform(size=(n, 3)) * 2 * span).astype(np.float32)
    u[: n // 2] = u_prev[: n // 2] + rng.uniform(-1, 1, size=(n // 2, 3)).astype(np.float32) * rate * DT
    frac = rng.uniform(0.1, 1.0, size=n).astype(np.float32)
    f = jax.jit(jax.vmap(lambda uu, up: filter_command(uu, up, params, DT)))
    c = jax.jit(jax.vmap(lambda uu, fr: cap_authority(uu, params, fr)))
    u1, act1 = map(np.asarray, f(u, u_prev))
    u2, act2 = map(np.asarray, f(u1, u_prev))
    np.testing.assert_array_equal(u1, u2)
    assert not act2.any() and act1.any()
    lo, hi = map(np.asarray, jax.vmap(lambda up: limit_box(up, params, DT))(u_prev))
    assert np.all((u1 >= u_min) & (u1 <= u_max))
    assert np.all(np.abs(u1 - u_prev) <= rate * DT + 1e-7)
    assert np.all((u1 >= lo) & (u1 <= hi))
    # minimal modification: inside the box nothing changes
    inside = np.all((u >= lo) & (u <= hi), axis=1)
    assert inside.any()
    np.testing.assert_array_equal(u1[inside], u[inside])
    c1, _ = map(np.asarray, c(u, frac))
    c2, cact2 = map(np.asarray, c(c1, frac))
    np.testing.assert_array_equal(c1, c2)
    assert not cact2.any()
    assert np.all((c1 >= frac[:, None] * u_min - 1e-7) & (c1 <= frac[:, None] * u_max + 1e-7))


def _run_supervisor(xs, flags, gains):
    def step(st, inp):
        x, fl = inp
        st = supervise(st, x, gains, DT)
        out = (st.fallback, st.reason)
        return record_intervention(st, fl), out

    st, (fb, reason) = jax.lax.scan(step, supervisor_init(100, jnp.float32), (xs, flags))
    return st, np.asarray(fb), np.asarray(reason)


def test_supervisor_out_of_envelope_then_back_after_dwell():
    g = default_supervisor_gains(jnp.float32)
    n = 600
    xs = jnp.tile(X0, (n, 1))
    xs = xs.at[100:150, 5].set(2.0)  # yaw rate 2 rad/s: far outside the trusted box for 0.5 s
    st, fb, reason = _run_supervisor(xs, jnp.zeros(n, bool), g)
    assert not fb[:100].any()
    assert fb[100] and reason[100] == FallbackReason.OUT_OF_ENVELOPE
    dwell_steps = round(float(g.dwell_s) / DT)
    back = 150 + dwell_steps - 1  # normal from step 150; leaves once dwell_s of normal time accrued
    assert fb[100:back].all() and not fb[back:].any()
    assert reason[back] == FallbackReason.NONE
    assert int(st.n_fallbacks) == 1


def test_supervisor_repeated_interventions_then_back():
    g = default_supervisor_gains(jnp.float32)
    n = 800
    xs = jnp.tile(X0, (n, 1))
    flags = jnp.zeros(n, bool).at[:60].set(True)
    st, fb, reason = _run_supervisor(xs, flags, g)
    k = int(g.max_interventions)
    assert not fb[: k + 1].any()  # the window holds <= max_interventions up to step k
    assert fb[k + 1] and reason[k + 1] == FallbackReason.INTERVENTIONS
    # the window drains 100 steps after the last intervention, then the dwell runs
    assert fb[k + 1 : 100 + 10].all()
    back = np.flatnonzero(~fb[k + 1 :])[0] + k + 1
    last_trigger = np.flatnonzero(np.convolve(np.asarray(flags), np.ones(100))[:n] > k).max()
    assert back == last_trigger + 1 + round(float(g.dwell_s) / DT)
    assert not fb[back:].any() and int(st.n_fallbacks) == 1


def test_supervisor_window_count_is_the_trailing_sum_of_interventions():
    flags = jax.random.bernoulli(jax.random.key(3), 0.4, (350,))  # 3.5 turns of the 100-slot ring

    def step(st, fl):
        st = record_intervention(st, fl)
        return st, (st.window_count, jnp.sum(st.window))

    _, (count, summed) = jax.lax.scan(step, supervisor_init(100, jnp.float32), flags)
    trailing = np.convolve(np.asarray(flags, np.int32), np.ones(100, np.int32))[:350]
    np.testing.assert_array_equal(np.asarray(count), np.asarray(summed))
    np.testing.assert_array_equal(np.asarray(count), trailing)


def test_bang_bang_policy_triggers_intervention_fallback_in_closed_loop():
    params = _nominal()

    def bang(obs):  # full-range sign flips on q: the rate limits bind on every step
        return jnp.where(obs[4] > 0, 1.0, -1.0) * jnp.ones(3)

    hy = make_hybrid(bang, HybridConfig(schedule="never"))
    r = _fly(hy, 400, params, X0)
    info = r.traj.info
    assert bool(jnp.any(info["fallback_reason"] == FallbackReason.INTERVENTIONS))
    assert int(jnp.sum(r.final_ctrl_state.interventions)) > 50


@chex.assert_max_traces(n=1)
def _apply_batch(params, x, state):
    hy = make_hybrid(_linear_policy(0), HybridConfig(schedule="continuous"))
    return jax.vmap(hy.apply, in_axes=(0, 0, None, None))(state, x, REF, jax.random.key(0))


def test_vmaps_over_aircraft_with_one_trace():
    n = 8
    base = _nominal()
    scale = jnp.linspace(0.9, 1.1, n)
    params = jax.vmap(lambda s: base.replace(mass_slug=base.mass_slug * s))(scale)
    hy = make_hybrid(_linear_policy(0), HybridConfig(schedule="continuous"))
    state = jax.vmap(hy.init)(params)
    xs = jnp.tile(X0, (n, 1)).at[:, 1].set(jnp.linspace(0.1, 0.8, n))
    f = jax.jit(_apply_batch, compiler_options=FAST_COMPILE)
    u, state, info = f(params, xs, state)
    u2, state, _ = f(params, xs, state)
    assert u.shape == (n, 3) and info["zeta"].shape == (n,)
    floor = float(default_hybrid_gains().zeta_floor)
    assert floor > 0 and bool(jnp.all((info["zeta"] >= floor - 1e-6) & (info["zeta"] <= 1.0)))
    # the batch equals a loop of single applies (one compile serves the n of them)
    single = jax.jit(
        lambda p, x: hy.apply(hy.init(p), x, REF, jax.random.key(0))[0], compiler_options=FAST_COMPILE
    )
    for i in range(n):
        u_i = single(jax.tree.map(lambda a, i=i: a[i], params), xs[i])
        np.testing.assert_allclose(u[i], u_i, rtol=1e-5, atol=1e-6)


def test_certificate_recovers_an_injected_disturbance():
    """A synthetic sliding trajectory with a known disturbance: the estimated bound is that disturbance."""
    dt, n = 0.01, 3000
    k, eps, phi = np.full(3, 0.5), np.full(3, 0.2), np.full(3, 0.2)
    d_true = np.array([0.05, 0.1, 0.3])  # the mu channel's exceeds eps
    t = np.arange(n) * dt
    s = np.zeros((n, 3))
    s[0] = [1.0, -0.5, 2.0]
    for i in range(n - 1):
        d = d_true * np.sin(3.0 * t[i])
        s[i + 1] = s[i] + dt * (-(k * np.sqrt(np.abs(s[i])) + eps) * np.clip(s[i] / phi, -1, 1) + d)
    cert = empirical_certificate(s, np.ones(n), np.ones(n), k, eps, phi, dt)
    for i, name in enumerate(("alpha", "beta", "mu")):
        assert cert[name]["delta_max"] == pytest.approx(d_true[i], rel=1e-3)
    assert cert["alpha"]["holds"] and cert["beta"]["holds"] and not cert["mu"]["holds"]
    # excluded samples (valid = False) do not count
    half = np.arange(n) < n // 2
    cert_h = empirical_certificate(s, np.ones(n), np.ones(n), k, eps, phi, dt, valid=half)
    assert cert_h["alpha"]["n_samples"] == n // 2
    # zeta = 0 samples are excluded
    cert0 = empirical_certificate(s, np.zeros(n), np.ones(n), k, eps, phi, dt)
    assert cert0["alpha"]["n_samples"] == 0 and not cert0["alpha"]["holds"]


def test_unsaturated_steps_flags_position_and_rate_limits():
    u_min, u_max, step = np.array([-1.0, -1, -1]), np.array([1.0, 1, 1]), np.array([0.1, 0.1, 0.1])
    d = np.zeros((5, 3))
    d[1, 0] = 1.0  # at a position limit (and moved 1.0 > 0.1 from step 0 to 1: rate limited on step 0)
    d[3, 2] = 0.05  # a small move: free
    free = unsaturated_steps(d, u_min, u_max, step)
    np.testing.assert_array_equal(free, [False, False, True, True, True])


def test_hand_over_counter_on_a_hand_made_zeta_sequence():
    """ζ active for the last 15% of a run with one hand-over (the simplex schedule's shape): the summary
    says ζ mean 0.15 and 1 hand-over per run; a fallback in and out counts 2; a constant ζ counts none
    after its start."""
    import types

    from harv_jax.control.hybrid.law import zeta_handed_over
    from harv_jax.evaluation.summary import summarize_controller

    def handovers(seq: list[float]) -> list[bool]:
        prev = jnp.zeros(3)
        out = []
        for z in seq:
            zc = jnp.full(3, z)
            out.append(bool(zeta_handed_over(prev, zc)))
            prev = zc
        return out

    simplex = [0.0] * 85 + [1.0] * 15
    flags = handovers(simplex)
    assert sum(flags) == 1 and flags.index(True) == 85
    assert sum(handovers([0.0] * 10 + [1.0] * 5 + [0.0] * 10)) == 2  # a fallback, then back
    assert sum(handovers([1.0] * 20)) == 1  # the SMC alone: taken over at the first step
    assert sum(handovers([0.2] * 20 + [0.49] * 5)) == 0  # a floor below 1/2 hands nothing over
    # per channel: the mean over channels decides
    assert bool(zeta_handed_over(jnp.zeros(3), jnp.array([1.0, 1.0, 0.0])))
    assert not bool(zeta_handed_over(jnp.zeros(3), jnp.array([1.0, 0.0, 0.0])))

    n = len(simplex)
    one = np.ones(1)
    metrics = types.SimpleNamespace(
        outcome=np.zeros(1, int), recovered=np.ones(1, bool), t_recover_s=one * 20,
        t_recover_alpha_s=one * 10, altitude_loss_ft=one, control_tv_rad=np.ones((1, 3)),
        chatter_index_rad2=np.ones((1, 3)),
        sat_position_fraction=one * 0, sat_rate_fraction=one * 0, left_envelope=np.zeros(1, bool),
    )  # fmt: skip
    info = {
        "zeta": np.array([np.mean(simplex)]),
        "zeta_handed_over": np.array([np.mean(flags)]),
        "zeta_switched": np.zeros(1),
        "intervened": np.zeros(1),
    }
    out = types.SimpleNamespace(metrics=metrics, terminal_error_rad=np.zeros((1, 3)), info_means=info)
    hybrid = summarize_controller(out, {"compile": 0.0, "run": 0.0}, n_steps=n)["hybrid"]
    assert hybrid["zeta_active_fraction"] == pytest.approx(0.15)
    assert hybrid["zeta_handovers_per_run"] == pytest.approx(1.0)
    assert hybrid["zeta_switches_per_run"] == 0.0  # no hysteresis tube in this schedule
