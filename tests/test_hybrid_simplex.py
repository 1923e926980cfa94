"""The hybrid's ``simplex`` schedule: the policy alone until a monitor trips, then the SMC for good."""

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
from harv_jax.control.hybrid.law import HybridConfig, default_hybrid_gains, make_hybrid, path_hybrid_gains
from harv_jax.control.hybrid.zeta import (
    SIMPLEX_FALLBACK_SMC,
    SIMPLEX_REASONS,
    simplex_fallback_gains,
    simplex_init,
    simplex_step,
)
from harv_jax.control.rl import make_rl_controller
from harv_jax.control.smc import default_gains
from harv_jax.evaluation import closed_loop
from harv_jax.task.scenarios import sample_table_states

REF = jnp.array([0.349, 0.0, 0.0])
DT = 0.01
#: A disturbed state inside the default box: alpha 0.6, p 0.5, r 0.3.
X0 = jnp.array([500.0, 0.60, 0.05, 0.5, -0.05, 0.3, 0.4, 0.1, 0.0, 20000.0])
SPIN_DELTA0 = jnp.array([-0.436, 0.436, 0.524])
SIMPLEX = HybridConfig(schedule="simplex")
#: The SMC the simplex schedule hands over to (one object: ``_fly`` compiles it once).
SMC = make_smc(gains=simplex_fallback_gains(jnp.float32))


def _nominal():
    return jax.tree.map(lambda a: jnp.asarray(a, jnp.float32), harv())


SCALE = jnp.array([1 / 500.0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1])
N_STEPS = 600


def _weights(seed: int = 0):
    return jax.random.normal(jax.random.key(seed), (11, 3)) * 0.5


def _linear_policy(seed: int = 0):
    """A fixed random 'policy': tanh of a linear map of the scaled observation, actions in (-1, 1)."""
    w = _weights(seed)
    return lambda obs: jnp.tanh((obs * SCALE) @ w)


def _gains(deadline_s=1e9, tube_rad=(10.0, 10.0, 10.0), box_high=None):
    g = default_hybrid_gains(jnp.float32)
    sx = g.simplex.replace(deadline_s=jnp.float32(deadline_s), tube_rad=jnp.asarray(tube_rad, jnp.float32))
    if box_high is not None:
        sx = sx.replace(box_high=jnp.asarray(box_high, jnp.float32))
    return g.replace(simplex=sx)


@functools.partial(jax.jit, static_argnums=(0, 1), compiler_options=FAST_COMPILE)
def _fly(ctrl, n_steps, params, x0, delta0=None):
    return closed_loop(ctrl, params, x0, REF, jax.random.key(0), n_steps, delta0_rad=delta0)


@functools.partial(jax.jit, compiler_options=FAST_COMPILE)
def _fly_simplex(w, gains, params, x0, delta0):
    """The simplex hybrid with the linear policy of weights ``w`` (NaN weights: a non-finite policy) and
    ``gains``, both traced: one compilation serves every test."""
    hy = make_hybrid(lambda obs: jnp.tanh((obs * SCALE) @ w), SIMPLEX, gains)
    return closed_loop(hy, params, x0, REF, jax.random.key(0), N_STEPS, delta0_rad=delta0)


def _reason(info) -> np.ndarray:
    """Per step: 0 none, else the index in SIMPLEX_REASONS of the hand-over so far."""
    flags = np.stack([np.asarray(info[f"handover_{r}"]) for r in SIMPLEX_REASONS[1:]], axis=-1)
    assert np.all(flags.sum(-1) <= 1)
    return np.where(flags.any(-1), flags.argmax(-1) + 1, 0)


def test_before_any_hand_over_the_policy_flies_alone():
    params = _nominal()
    r_h = _fly_simplex(_weights(2), _gains(), params, X0, SPIN_DELTA0)
    r_r = _fly(make_rl_controller(_linear_policy(2)), N_STEPS, params, X0, SPIN_DELTA0)
    assert float(jnp.max(r_h.traj.info["zeta"])) == 0.0
    info = r_h.traj.info  # the policy's command acts as it is, except where the actuator box clips it
    assert bool(jnp.all(info["policy_unmodified"] | jnp.any(info["limit_active"], axis=-1)))
    assert float(jnp.mean(info["policy_unmodified"])) > 0.5
    assert np.all(_reason(r_h.traj.info) == 0)
    np.testing.assert_allclose(r_h.traj.delta_rad, r_r.traj.delta_rad, atol=1e-6)
    np.testing.assert_allclose(r_h.traj.x_wind[:, 1:9], r_r.traj.x_wind[:, 1:9], atol=1e-5)


def test_fallback_gains_are_the_default_gains_but_the_softer_reaching_and_surface():
    d, f = default_gains(jnp.float32), simplex_fallback_gains(jnp.float32)
    for name in d.__dataclass_fields__:
        want = SIMPLEX_FALLBACK_SMC.get(name)
        got, default = np.asarray(getattr(f, name)), np.asarray(getattr(d, name))
        assert got.shape == default.shape and got.dtype == default.dtype
        np.testing.assert_array_equal(got, default if want is None else np.full_like(default, want))
    assert set(SIMPLEX_FALLBACK_SMC) == {"lambda1_ps", "k_reach", "eps_radps2", "phi_radps"}
    chex.assert_trees_all_equal(default_hybrid_gains(jnp.float32).simplex.fallback_smc, f)  # what it flies


def test_behind_a_path_the_fallback_has_the_default_gains_and_nothing_else_changes():
    path, plain = path_hybrid_gains(jnp.float32), default_hybrid_gains(jnp.float32)
    chex.assert_trees_all_equal(path.simplex.fallback_smc, default_gains(jnp.float32))
    chex.assert_trees_all_equal(path.replace(simplex=plain.simplex), plain)
    chex.assert_trees_all_equal(path.simplex.replace(fallback_smc=plain.simplex.fallback_smc), plain.simplex)


def test_hand_over_at_engagement_flies_the_smc():
    """Tube 0 and deadline 0: the SMC from the first step, u_RL dropped (equal to the fallback SMC flown
    alone)."""
    params = _nominal()
    r_h = _fly_simplex(_weights(1), _gains(deadline_s=0.0, tube_rad=(0.0, 0.0, 0.0)), params, X0, SPIN_DELTA0)
    r_s = _fly(SMC, N_STEPS, params, X0, SPIN_DELTA0)
    assert np.all(_reason(r_h.traj.info) == SIMPLEX_REASONS.index("deadline"))
    assert float(jnp.max(jnp.abs(r_h.traj.info["u_rl_rad"]))) == 0.0
    np.testing.assert_allclose(r_h.traj.delta_rad, r_s.traj.delta_rad, atol=1e-5)
    np.testing.assert_allclose(r_h.traj.x_wind[:, 1:9], r_s.traj.x_wind[:, 1:9], atol=1e-5)


def test_after_a_hand_over_the_certificate_holds_for_the_fallback_smc():
    """The fallback SMC's own unclipped commands meet the reaching condition of its gains (eta = its eps):
    the certificate logged by the simplex hybrid is the fallback's, not the default SMC's (eta 0.2 > 0.1)."""
    gains = _gains(deadline_s=0.0, tube_rad=(0.0, 0.0, 0.0))
    info = _fly_simplex(_weights(1), gains, _nominal(), X0, SPIN_DELTA0).traj.info
    defined, holds = np.asarray(info["cert_free_defined"]), np.asarray(info["cert_free_holds"])
    assert defined.sum() > 100  # unclipped steps in the sliding mode exist on this flight
    assert np.all(holds[defined])


def test_deadline_hands_over_for_good_and_the_rest_is_the_smc_from_there():
    params = _nominal()
    k = 200  # deadline 2 s with a tube no state meets: the hand-over is at step 200 exactly
    gains = _gains(deadline_s=k * DT, tube_rad=(1e-6, 1e-6, 1e-6))
    r_h = _fly_simplex(_weights(3), gains, params, X0, SPIN_DELTA0)
    zeta = np.asarray(r_h.traj.info["zeta"])
    assert np.all(zeta[:k] == 0.0) and np.all(zeta[k:] == 1.0)
    reason = _reason(r_h.traj.info)
    assert np.all(reason[:k] == 0) and np.all(reason[k:] == SIMPLEX_REASONS.index("deadline"))
    # from the hand-over on, the SMC started at that state and deflection (integral 0)
    x_k, d_k = r_h.traj.x_wind[k], r_h.traj.delta_rad[k - 1]
    r_s = _fly(SMC, N_STEPS, params, x_k, d_k)
    n = N_STEPS - k
    np.testing.assert_allclose(r_h.traj.delta_rad[k:], r_s.traj.delta_rad[:n], atol=1e-4)
    np.testing.assert_allclose(r_h.traj.x_wind[k:, 1:9], r_s.traj.x_wind[:n, 1:9], atol=1e-4)


def test_box_and_nonfinite_commands_hand_over_with_their_reason():
    params = _nominal()
    low_alpha = np.asarray(default_hybrid_gains().simplex.box_high).copy()
    low_alpha[1] = 0.5  # X0 has alpha 0.6: outside at once
    r_box = _fly_simplex(_weights(0), _gains(box_high=low_alpha), params, X0, jnp.zeros(3))
    assert np.all(_reason(r_box.traj.info) == SIMPLEX_REASONS.index("box"))
    r_nan = _fly_simplex(jnp.full((11, 3), jnp.nan), _gains(), params, X0, jnp.zeros(3))
    assert np.all(_reason(r_nan.traj.info) == SIMPLEX_REASONS.index("nonfinite"))
    assert bool(jnp.all(jnp.isfinite(r_nan.traj.delta_rad))) and not bool(r_nan.nonfinite)


FAST, CALM = jnp.asarray(600.0), jnp.asarray(0.1)  # ft/s, rad/s: not held


def test_simplex_step_by_hand():
    g = _gains(deadline_s=0.05, tube_rad=(0.1, 0.1, 0.1)).simplex
    s, t = simplex_init(jnp.float32), jnp.asarray(True)
    inside, outside = jnp.array([0.05, 0.0, -0.05]), jnp.array([0.05, 0.2, 0.0])
    for _ in range(5):  # before the deadline, outside the tube is allowed
        s = simplex_step(s, jnp.asarray(False), outside, t, g, DT, FAST, CALM)
    assert not bool(s.latched)
    s = simplex_step(s, jnp.asarray(False), inside, t, g, DT, FAST, CALM)  # at the deadline, inside
    assert not bool(s.latched)
    s = simplex_step(s, jnp.asarray(False), outside, t, g, DT, FAST, CALM)
    assert bool(s.latched) and int(s.reason) == SIMPLEX_REASONS.index("deadline")
    s = simplex_step(
        s, jnp.asarray(True), inside, jnp.asarray(False), g, DT, FAST, CALM
    )  # latched for good, first reason kept
    assert bool(s.latched) and int(s.reason) == SIMPLEX_REASONS.index("deadline")
    nan_err = simplex_step(
        simplex_init(jnp.float32), jnp.asarray(False), jnp.full((3,), jnp.nan), t, g, DT, FAST, CALM
    )
    assert not bool(nan_err.latched)  # before the deadline a non-finite error alone does not trip


def test_simplex_deadline_held_while_slow_and_calm():
    """Slow (V < hold speed) and calm (||omega|| < hold rate): the deadline waits until hold_until_s; fast, or
    rotating, or after hold_until_s it trips; the box trips while held."""
    g = _gains(deadline_s=0.05, tube_rad=(0.1, 0.1, 0.1)).simplex
    g = g.replace(hold_speed_fps=jnp.asarray(250.0), hold_rate_radps=jnp.asarray(0.5))
    g = g.replace(hold_until_s=jnp.asarray(0.2))
    outside, t, f = jnp.array([0.05, 0.2, 0.0]), jnp.asarray(True), jnp.asarray(False)
    slow, fast, calm, rotating = jnp.asarray(240.0), jnp.asarray(260.0), jnp.asarray(0.4), jnp.asarray(0.6)

    def after(n, speed, rate, box=f):
        s = simplex_init(jnp.float32)
        for _ in range(n):
            s = simplex_step(s, box, outside, t, g, DT, speed, rate)
        return s

    assert not bool(after(20, slow, calm).latched)  # t = 0 ... 0.19 s: held past the 0.05 s deadline
    held_out = after(21, slow, calm)  # the step at 0.2 s: the hold is over
    assert bool(held_out.latched) and int(held_out.reason) == SIMPLEX_REASONS.index("deadline")
    for speed, rate in ((fast, calm), (slow, rotating), (jnp.asarray(jnp.nan), calm)):
        s = after(6, speed, rate)  # trips at the deadline, as without a hold
        assert bool(s.latched) and int(s.reason) == SIMPLEX_REASONS.index("deadline")
        assert not bool(after(5, speed, rate).latched)
    boxed = after(1, slow, calm, box=jnp.asarray(True))
    assert bool(boxed.latched) and int(boxed.reason) == SIMPLEX_REASONS.index("box")


def test_default_simplex_hold():
    g = default_hybrid_gains().simplex
    assert float(g.hold_speed_fps) == 250.0 and float(g.hold_rate_radps) == 0.5
    assert float(g.hold_until_s) == 30.0 and float(g.deadline_s) == 10.0


@chex.assert_max_traces(n=1)
def _apply_simplex_batch(hy, params, x, state):
    return jax.vmap(hy.apply, in_axes=(0, 0, None, None))(state, x, REF, jax.random.key(0))


@pytest.mark.slow
def test_vmaps_over_aircraft_equal_to_single_runs_with_one_trace():
    hy = make_hybrid(_linear_policy(4), SIMPLEX)
    n = 6
    base = _nominal()
    params = jax.vmap(lambda s: base.replace(mass_slug=base.mass_slug * s))(jnp.linspace(0.9, 1.1, n))
    xs = sample_table_states(jax.random.key(4), n)
    state = jax.vmap(hy.init)(params)
    f = jax.jit(_apply_simplex_batch, static_argnums=0, compiler_options=FAST_COMPILE)
    u, state2, _ = f(hy, params, xs, state)
    f(hy, params, xs, state2)  # second call: no retrace
    single = jax.jit(hy.apply, compiler_options=FAST_COMPILE)
    for i in range(n):
        p_i = jax.tree.map(lambda a, i=i: a[i], params)
        u_i, _, _ = single(hy.init(p_i), xs[i], REF, jax.random.key(0))
        np.testing.assert_allclose(u[i], u_i, rtol=1e-5, atol=1e-6)


def test_simplex_summary_counts_runs_by_reason():
    from harv_jax.evaluation.montecarlo.rollout import simplex_summary

    info = {  # time means per run of the hand-over flags: run 0 box, run 2 deadline, runs 1 and 3 none
        "handover_box": np.array([0.9, 0.0, 0.0, 0.0]),
        "handover_deadline": np.array([0.0, 0.0, 0.2, 0.0]),
        "handover_nonfinite": np.zeros(4),
    }
    s = simplex_summary(info)["handover_run_fraction"]
    assert s == {"any": 0.5, "box": 0.25, "deadline": 0.25, "nonfinite": 0.0}
    assert simplex_summary({"zeta": np.zeros(4)}) == {}


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["bang-bang"])
def test_mc_cli_reports_the_hand_overs(tmp_path, kind):
    import json

    from policy_fixtures import write_fixture_policies
    from typer.testing import CliRunner

    from harv_jax.cli import app

    pol = write_fixture_policies(tmp_path)[kind]
    out = tmp_path / "mc"
    args = ["mc", "--controller", "hybrid", "--zeta", "simplex", "--policy", str(pol), "--runs", "2",
            "--duration", "10.5", "--chunk", "2", "--out", str(out)]  # fmt: skip
    r = CliRunner().invoke(app, args, standalone_mode=False)
    assert r.exception is None, r.output
    s = json.loads((out / "summary.json").read_text())
    assert s["zeta_schedule"] == "simplex"
    h = s["controllers"]["hybrid"]["hybrid"]["handover_run_fraction"]
    assert set(h) == {"any", "box", "deadline", "nonfinite"}
    assert all(0.0 <= v <= 1.0 for v in h.values()) and h["any"] >= max(h["box"], h["deadline"])
