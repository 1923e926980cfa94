"""The pure recovery env: reset bounds, step, terminations, truncation, PBRS, auto-reset, traces.

Every env-level test shares one jitted, vmapped ``step`` (traced once: ``chex.assert_max_traces``);
variants go through the traced ``EnvParams`` and crafted states, not through recompiles.
"""

from __future__ import annotations

import functools
from types import SimpleNamespace

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.aircraft.params import U_MAX_RAD, U_MIN_RAD, U_RATE_MAX_RADPS
from harv_jax.dynamics import from_wind, to_wind
from harv_jax.env import (
    EnvConfig,
    TerminationFlags,
    default_params,
    default_randomization_params,
    make_env,
    recovery,
    reward,
    termination_flags,
)
from harv_jax.task.criteria import default_envelope as paper_envelope_params
from harv_jax.task.scenarios import RESET_HIGH, RESET_LOW
from harv_jax.task.spaces import ACTION_SIZE, OBS_HIGH, OBS_LOW, OBSERVATION_SIZE

N = 64
CONFIG = EnvConfig()
ENV = make_env(CONFIG)
# randomization on (documented defaults); two spin-entry slots so that the spin test needs no new shape
P = ENV.default_params()
P = P.replace(spin_states=jnp.tile(P.spin_states, (2, 1)))
P_QUIET = P.replace(randomization=default_randomization_params(enabled=False))  # traced switches off
#: Straight and level near trim at 600 ft/s, 25,000 ft (alpha 5.1 deg, MODEL.md trim table).
LEVEL = np.array([600.0, 0.089, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25000.0], dtype=np.float32)
FLAG_NAMES = TerminationFlags._fields
#: Tests compile with XLA's backend optimizations off: a third of the compile time, same semantics.
jit_fast = functools.partial(jax.jit, compiler_options={"xla_backend_optimization_level": 0})


@pytest.fixture(scope="module")
def fns():
    chex.clear_trace_counter()

    @chex.assert_max_traces(n=1)
    def vstep(keys, states, actions, params):
        return jax.vmap(ENV.step, in_axes=(0, 0, 0, None))(keys, states, actions, params)

    def set_wind(states, x, params):
        pot = jax.vmap(reward.state_potential, in_axes=(0, 0, None))(x, states.target_rad, params.reward)
        return states.replace(aircraft=jax.vmap(from_wind)(x), wind=x, potential=pot)

    return SimpleNamespace(
        to_wind=jit_fast(jax.vmap(to_wind)),
        potential=jit_fast(jax.vmap(reward.state_potential, in_axes=(0, 0, None))),
        vstep=jit_fast(vstep),
        vreset=jit_fast(jax.vmap(ENV.reset, in_axes=(0, None))),
        set_wind=jit_fast(set_wind),
    )


def keys(seed: int) -> jax.Array:
    return jax.random.split(jax.random.key(seed), N)


def rows(x) -> np.ndarray:
    return np.broadcast_to(np.asarray(x, dtype=np.float32), (N, 10))


def random_actions(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(N, 3)).astype(np.float32)


def level_states(fns, params, x=LEVEL, seed=0):
    _, states = fns.vreset(keys(seed), params)
    return fns.set_wind(states, rows(x), params)


def test_api_constants():
    assert ENV.observation_size == OBSERVATION_SIZE == recovery.observation_size == 11
    assert ENV.action_size == ACTION_SIZE == recovery.action_size == 3
    for leaf in jax.tree.leaves(P):
        assert not leaf.weak_type  # weak types retrace / break scan carries
    p = default_params(EnvConfig(h0_ft=30000.0, h_floor_ft=-1e9, discount=0.95))
    assert float(p.h0_ft) == 30000.0 and float(p.envelope.h_floor_ft) == -1e9
    assert float(p.reward.discount) == pytest.approx(0.95)
    with pytest.raises(ValueError, match="episode_steps"):
        EnvConfig(episode_steps=0)


def test_reset_samples_the_paper_bounds(fns):
    obs, st = zip(*(fns.vreset(keys(s), P_QUIET) for s in range(4)), strict=True)
    obs = np.concatenate(obs)
    wind = np.concatenate([s.wind for s in st])
    # paper Table: V 100-1500, alpha -0.175-1.047, beta +-0.262, p +-2.094, q +-1.047, r +-0.524,
    # mu +-3.142 (wrapped to (-pi, pi]), gamma +-1.047
    lo, hi = RESET_LOW.copy(), RESET_HIGH.copy()
    lo[6], hi[6] = -np.pi, np.pi
    assert np.all(obs[:, :8] >= lo - 1e-4) and np.all(obs[:, :8] <= hi + 1e-4)
    assert obs[:, 0].min() < 200 and obs[:, 0].max() > 1400  # spread over the range (256 draws)
    assert np.all((obs[:, 8] >= -0.085 - 1e-6) & (obs[:, 8] <= 0.68 + 1e-6))  # alpha_d
    np.testing.assert_array_equal(obs[:, 9:], 0.0)  # beta_d = mu_d = 0
    np.testing.assert_array_equal(wind[:, 9], 25000.0)  # h0 default
    np.testing.assert_array_equal(np.concatenate([s.step for s in st]), 0)
    np.testing.assert_array_equal(np.concatenate([s.delta_rad for s in st]), 0.0)
    # the observation is the true state: to_wind of the integration state it starts from
    back = np.concatenate([fns.to_wind(s.aircraft) for s in st])
    np.testing.assert_allclose(obs[:, :8], back[:, :8], rtol=1e-4, atol=2e-5)
    # the stored potential is sigma of that state
    pot = np.concatenate([fns.potential(s.wind, s.target_rad, P.reward) for s in st])
    np.testing.assert_allclose(np.concatenate([s.potential for s in st]), pot, rtol=1e-6)


def test_reset_sensor_noise(fns):
    obs, st = fns.vreset(keys(1), P)
    err = np.asarray(obs[:, :8] - st.wind[:, :8])
    std = np.asarray(st.episode.noise_std)
    assert np.all(np.abs(err) <= 6 * std + 1e-4)
    assert np.mean(np.abs(err) > 0) > 0.9  # noise is on
    np.testing.assert_array_equal(obs[:, 8:], st.target_rad)  # targets are not measured


def test_step_outputs(fns):
    obs0, st = fns.vreset(keys(2), P)
    actions = random_actions(5)
    obs, st1, rew, done, info = fns.vstep(keys(3), st, actions, P)
    chex.assert_shape(obs, (N, OBSERVATION_SIZE))
    chex.assert_shape([rew, done, info["terminated"], info["truncation"]], (N,))
    chex.assert_shape(info["final_obs"], (N, OBSERVATION_SIZE))
    chex.assert_shape(info["final_state_wind"], (N, 10))
    assert done.dtype == jnp.bool_
    chex.assert_tree_all_finite((obs, rew, st1, info))
    assert set(info["reward_terms"]) == set(reward.RewardTerms._fields)
    assert set(info["termination"]) == set(FLAG_NAMES)
    np.testing.assert_array_equal(rew, info["reward_terms"]["total"])
    live = ~np.asarray(done)
    assert live.sum() > N // 2
    np.testing.assert_array_equal(np.asarray(st1.step)[live], 1)
    np.testing.assert_array_equal(np.asarray(obs)[live], np.asarray(info["final_obs"])[live])
    assert np.all(np.asarray(obs) >= OBS_LOW) and np.all(np.asarray(obs) <= OBS_HIGH)


def test_action_mapping_and_clipping(fns):
    cmd = recovery.action_to_command
    np.testing.assert_allclose(cmd(-jnp.ones(3), U_MIN_RAD, U_MAX_RAD), U_MIN_RAD, rtol=1e-6)
    np.testing.assert_allclose(cmd(jnp.ones(3), U_MIN_RAD, U_MAX_RAD), U_MAX_RAD, rtol=1e-6)
    # zero action = middle of the range: de (-0.436 + 0.175) / 2 = -0.1305, da = dr = 0
    np.testing.assert_allclose(cmd(jnp.zeros(3), U_MIN_RAD, U_MAX_RAD), [-0.1305, 0.0, 0.0], atol=1e-7)
    st = level_states(fns, P_QUIET)
    a1 = fns.vstep(keys(4), st, jnp.ones((N, 3)), P_QUIET)
    a5 = fns.vstep(keys(4), st, 5.0 * jnp.ones((N, 3)), P_QUIET)  # clipped to 1
    chex.assert_trees_all_equal(a1, a5)
    # the action penalty uses the clipped action: -(1 + 1 + 1)
    np.testing.assert_allclose(a5[4]["reward_terms"]["action"], -3.0)


@pytest.mark.parametrize("delay", [0, 2])
def test_actuator_rate_limit_and_delay(fns, delay):
    # full nose-down stabilator command (+1 -> +0.175 rad) from 0 rad; rate limit 40 deg/s * 0.01 s
    # = 0.0069813 rad per step. The command reaches the actuator `delay` steps late.
    st = level_states(fns, P_QUIET)
    st = st.replace(episode=st.episode.replace(delay_steps=np.full((N,), delay, dtype=np.int32)))
    action = jnp.zeros((N, 3)).at[:, 0].set(1.0)
    de = []
    for i in range(4):
        _, st, _, done, _ = fns.vstep(keys(10 + i), st, action, P_QUIET)
        assert not np.any(done)
        de.append(float(st.delta_rad[0, 0]))
    step_rad = U_RATE_MAX_RADPS[0] * 0.01
    expected = [max(0, i + 1 - delay) * step_rad for i in range(4)]
    np.testing.assert_allclose(de, expected, rtol=1e-5, atol=1e-8)


TERMINATION_CASES = {
    # name: (state modifications, envelope modifications, expected flag)
    "alpha_high": ({1: 1.65, 0: 300.0}, {}, "alpha"),  # alpha > 1.571
    "alpha_low": ({1: -0.40, 0: 300.0}, {}, "alpha"),  # alpha < -0.244
    "speed_high": ({0: 2100.0, 1: 0.02}, {}, "speed"),  # V > 2000
    "speed_low": ({0: 300.0}, {"v_min_fps": 500.0}, "speed"),  # V <= v_min
    "rates": ({3: 40.0}, {}, "rates"),  # |p| > 10 pi = 31.4
    "gamma": ({7: 0.8}, {"gamma_max_rad": 0.5}, "gamma"),  # |gamma| > gamma_max
    "altitude": ({}, {"h_floor_ft": 30000.0}, "altitude"),  # h = 25,000 < floor
    "nonfinite": (None, {}, "nonfinite"),
}


@pytest.mark.parametrize("case", list(TERMINATION_CASES))
def test_termination_paths(fns, case):
    mods, env_mods, flag = TERMINATION_CASES[case]
    params = P_QUIET.replace(
        envelope=P_QUIET.envelope.replace(**{k: jnp.float32(v) for k, v in env_mods.items()})
    )
    x = LEVEL.copy()
    for i, v in (mods or {}).items():
        x[i] = v
    st = level_states(fns, params, x)
    if mods is None:
        st = st.replace(aircraft=st.aircraft.replace(uvw_fps=np.full((N, 3), np.nan, dtype=np.float32)))
    obs, st1, rew, done, info = fns.vstep(keys(20), st, jnp.zeros((N, 3)), params)
    assert np.all(info["terminated"]) and np.all(done) and not np.any(info["truncation"])
    for name in FLAG_NAMES:
        assert np.all(info["termination"][name]) == (name == flag), name
    # terminal reward -1000 plus the shaping to the zero potential of the absorbing state: -sigma_t
    np.testing.assert_allclose(rew, -1000.0 - st.potential, rtol=1e-6)
    # auto-reset: a new episode starts (finite, step 0), the finished one's last observation is kept
    np.testing.assert_array_equal(st1.step, 0)
    chex.assert_tree_all_finite((obs, st1, info["final_obs"], rew))
    assert not np.allclose(obs, info["final_obs"])


def test_termination_flags_at_the_paper_bounds():
    env = paper_envelope_params()

    check = jit_fast(termination_flags)

    def flags(**kw):
        x = LEVEL.copy()
        for i, name in enumerate(("V", "alpha", "beta", "p", "q", "r", "mu", "gamma", "chi", "h")):
            if name in kw:
                x[i] = kw[name]
        f = check(x, np.True_, env)
        return {k for k, v in f._asdict().items() if bool(v)}

    assert flags() == set()
    # V in (0, 2000]; alpha in [-0.244, 1.571]; |p|,|q|,|r| <= 10 pi; |gamma| <= 1.745; h >= 0
    assert flags(V=2000.0) == set() and flags(V=2000.5) == {"speed"} and flags(V=0.0) == {"speed"}
    assert flags(alpha=1.571) == set() and flags(alpha=1.5711) == {"alpha"}
    assert flags(alpha=-0.244) == set() and flags(alpha=-0.2441) == {"alpha"}
    assert flags(q=-31.4) == set() and flags(q=-31.5) == {"rates"} and flags(r=31.5) == {"rates"}
    assert flags(gamma=1.745) == set() and flags(gamma=-1.8) == {"gamma"}
    assert flags(h=0.0) == set() and flags(h=-1.0) == {"altitude"}
    assert flags(beta=3.0, mu=-3.1) == set()  # beta, mu in [-pi, pi] always
    nan = check(np.full(10, np.nan, dtype=np.float32), np.False_, env)
    assert {k for k, v in nan._asdict().items() if bool(v)} == {"nonfinite"}


def test_truncation_is_not_termination(fns):
    st = level_states(fns, P_QUIET)
    st = st.replace(step=np.full((N,), CONFIG.episode_steps - 1, dtype=np.int32))
    obs, st1, rew, done, info = fns.vstep(keys(30), st, jnp.zeros((N, 3)), P_QUIET)
    assert np.all(done) and np.all(info["truncation"]) and not np.any(info["terminated"])
    np.testing.assert_array_equal(info["reward_terms"]["terminal"], 0.0)
    np.testing.assert_allclose(rew, info["reward_terms"]["total"])
    assert np.all(rew > -100.0)  # an ordinary step's reward near level flight
    # bootstrap target: the last observation of the truncated episode (noise off: exactly the state)
    final = np.concatenate([info["final_state_wind"][:, :8], st.target_rad], axis=1)  # clean observation
    np.testing.assert_allclose(info["final_obs"], final, rtol=1e-6)
    np.testing.assert_allclose(info["final_state_wind"][:, 0], 600.0, rtol=1e-2)
    np.testing.assert_array_equal(st1.step, 0)  # a new episode
    # at the time limit, leaving the envelope is a termination, not a truncation
    st_bad = level_states(fns, P_QUIET, np.where(np.arange(10) == 1, 1.65, LEVEL).astype(np.float32))
    st_bad = st_bad.replace(step=st.step)
    _, _, rew_bad, done_bad, info_bad = fns.vstep(keys(31), st_bad, jnp.zeros((N, 3)), P_QUIET)
    assert np.all(done_bad) and np.all(info_bad["terminated"]) and not np.any(info_bad["truncation"])
    np.testing.assert_allclose(rew_bad, -1000.0 - st_bad.potential, rtol=1e-6)


def test_pbrs_telescopes_along_an_episode(fns):
    # a rolling, pitching start so that the potential changes: p 0.6, q -0.2, r 0.1 rad/s
    x = LEVEL.copy()
    x[3:6] = [0.6, -0.2, 0.1]
    st = level_states(fns, P_QUIET, x)
    sigma0 = np.asarray(st.potential, dtype=np.float64)
    gamma = float(P_QUIET.reward.discount)
    total = np.zeros(N)
    n_steps = 60
    for t in range(n_steps):
        _, st, _, done, info = fns.vstep(keys(40 + t), st, np.full((N, 3), 0.2, dtype=np.float32), P_QUIET)
        assert not np.any(done)
        total += gamma**t * np.asarray(info["reward_terms"]["shaping"], dtype=np.float64)
        # the carried potential is sigma of the current state
        pot = fns.potential(st.wind, st.target_rad, P.reward)
        np.testing.assert_allclose(st.potential, pot, rtol=1e-6)
    expected = gamma**n_steps * np.asarray(st.potential, dtype=np.float64) - sigma0
    assert np.abs(sigma0 - np.asarray(st.potential)).max() > 0.02  # the potential did move
    np.testing.assert_allclose(total, expected, rtol=1e-4, atol=1e-5)


def test_randomization_resampled_every_episode_in_the_same_slot(fns):
    # a floor above h0 ends every episode on its first step, so each step starts a new episode
    params = P.replace(envelope=P.envelope.replace(h_floor_ft=jnp.float32(1e6)))
    _, st = fns.vreset(keys(50), params)
    history = [st]
    for t in range(3):
        _, st, _, done, _ = fns.vstep(keys(51 + t), st, jnp.zeros((N, 3)), params)
        assert np.all(done)
        history.append(st)
    for a, b in zip(history[:-1], history[1:], strict=True):
        # every slot gets a new aircraft, target and initial state at every episode
        assert np.all(a.episode.aircraft.mass_slug != b.episode.aircraft.mass_slug)
        assert np.all(np.any(a.episode.aircraft.aero_scale != b.episode.aircraft.aero_scale, axis=1))
        assert np.all(a.episode.gust_tau_s != b.episode.gust_tau_s)
        assert np.all(a.target_rad[:, 0] != b.target_rad[:, 0])
        assert np.all(a.wind[:, 0] != b.wind[:, 0])
    # and the slots differ from each other
    assert len(np.unique(np.asarray(history[-1].episode.aircraft.mass_slug))) == N


def test_spin_entry_resets(fns):
    spin = np.array(
        [[250.0, 1.0, 0.05, 0.5, 0.3, 1.2, 0.3, -1.0, 0.0, 24000.0],
         [300.0, 0.8, -0.05, -0.5, 0.2, -1.0, -0.3, -0.9, 0.0, 26000.0]], dtype=np.float32,
    )  # fmt: skip
    params = P_QUIET.replace(spin_states=jnp.asarray(spin), spin_reset_prob=jnp.float32(1.0))
    _, st = fns.vreset(keys(60), params)
    w = np.asarray(st.wind)
    which = np.argmin(np.abs(w[:, 0:1] - spin[None, :, 0]), axis=1)
    assert set(which) == {0, 1}  # both states used
    dev = np.abs(w - spin[which])
    half = np.asarray(P.spin_perturb)
    assert np.all(dev[:, [0, 1, 2, 3, 4, 5, 7, 9]] <= half[[0, 1, 2, 3, 4, 5, 7, 9]] + 1e-3)
    assert np.all(dev[:, 0] > 0)  # perturbed
    _, st0 = fns.vreset(keys(60), P_QUIET)  # probability 0 (default): the uniform reset
    assert np.all(np.asarray(st0.wind)[:, 9] == 25000.0)


def test_no_nan_random_actions(fns):
    """Default-suite version of the 4096 x 1000 check: 64 envs x 300 steps, randomization on."""
    _, st = fns.vreset(keys(70), P)
    n_done = 0
    for t in range(300):
        obs, st, rew, done, info = fns.vstep(keys(1000 + t), st, random_actions(1000 + t), P)
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(rew)), t
        n_done += int(done.sum())
    chex.assert_tree_all_finite(st)
    assert n_done > 0  # random stick from the reset bounds leaves the envelope now and then


def test_step_traced_once_across_params_and_states(fns):
    """``vstep`` carries chex.assert_max_traces(n=1): every test above reused one trace."""
    _, st = fns.vreset(keys(80), P)
    other = P.replace(
        reward=P.reward.replace(w_p1=jnp.float32(0.5), discount=jnp.float32(0.95)),
        randomization=P.randomization.replace(gust_std_max_fps=jnp.float32(20.0)),
        h0_ft=jnp.float32(30000.0),
    )
    for params in (P, other, P_QUIET):
        out = fns.vstep(keys(81), st, jnp.zeros((N, 3)), params)
        chex.assert_tree_all_finite(out[0])


@pytest.mark.slow
def test_4096_envs_1000_steps_no_nan():
    n, t_steps = 4096, 1000
    env = make_env(EnvConfig())
    params = env.default_params()

    @jax.jit
    def run(key):
        k_reset, k_run = jax.random.split(key)
        _, st = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(k_reset, n), params)

        def body(st, k):
            ka, ks = jax.random.split(k)
            a = jax.random.uniform(ka, (n, 3), minval=-1.0, maxval=1.0)
            obs, st, rew, done, _ = jax.vmap(env.step, in_axes=(0, 0, 0, None))(
                jax.random.split(ks, n), st, a, params
            )
            ok = jnp.all(jnp.isfinite(obs)) & jnp.all(jnp.isfinite(rew))
            return st, (ok, done.sum())

        st, (ok, n_done) = jax.lax.scan(body, st, jax.random.split(k_run, t_steps))
        return st, ok, n_done

    st, ok, n_done = run(jax.random.key(0))
    assert bool(jnp.all(ok))
    chex.assert_tree_all_finite(st)
    assert int(n_done.sum()) > 0


def test_batch_step_matches_vmap_step(fns):
    """``batch_step`` (resets under lax.cond) returns what vmap(step) returns, done or not."""
    batch_step = jit_fast(ENV.batch_step)
    st = level_states(fns, P)
    ks = keys(90)
    actions = random_actions(91)
    # no env done: the cond skips the resets
    out_vmap, out_batch = fns.vstep(ks, st, actions, P), batch_step(ks, st, actions, P)
    assert not np.any(out_vmap[3])
    chex.assert_trees_all_close(out_batch, out_vmap, rtol=1e-6, atol=1e-6)
    # half the batch leaves the envelope (alpha 1.65 rad): those envs restart, the others go on
    bad = np.where(np.arange(10) == 1, 1.65, LEVEL).astype(np.float32)
    x = np.where((np.arange(N) % 2 == 0)[:, None], bad[None], LEVEL[None])
    st = fns.set_wind(st, x, P)
    out_vmap, out_batch = fns.vstep(ks, st, actions, P), batch_step(ks, st, actions, P)
    np.testing.assert_array_equal(out_vmap[3], np.arange(N) % 2 == 0)
    chex.assert_trees_all_close(out_batch, out_vmap, rtol=1e-6, atol=1e-6)


@pytest.mark.slow
def test_turbulence_and_lag_draws_are_their_own():
    """The env's turbulence and lag: drawn per episode below their maxima from keys of their own (every
    other draw unchanged), the observation the air data, the paper's env unchanged without them."""
    from harv_jax.env.env_settings import EnvSettings

    base = {"episode_steps": 50, "domain_randomization": True}
    plain = EnvSettings.from_table(base)
    disturbed = EnvSettings.from_table({**base, "randomization": {"turbulence": "severe", "lag_max_s": 0.1}})
    assert not plain.config.turbulence and disturbed.config.turbulence
    n = 64
    ks = jax.random.split(jax.random.key(3), n)
    out = {}
    for name, s in (("plain", plain), ("disturbed", disturbed)):
        env, params = make_env(s.config), s.params()

        @jax.jit
        def reset_and_step(ks, params, env=env):
            obs, st = jax.vmap(env.reset, in_axes=(0, None))(ks, params)
            a = jnp.full((n, 3), 0.1, jnp.float32)
            obs1, st1, *_ = jax.vmap(env.step_no_reset, in_axes=(0, 0, 0, None))(ks, st, a, params)
            return obs, st, obs1, st1

        out[name] = reset_and_step(ks, params)
    obs_p, st_p, _, _ = out["plain"]
    obs_d, st_d, obs1_d, st1_d = out["disturbed"]
    # other draws unchanged: initial state, aircraft mass, noise, gust, delay
    np.testing.assert_array_equal(np.asarray(st_p.aircraft.uvw_fps), np.asarray(st_d.aircraft.uvw_fps))
    np.testing.assert_array_equal(
        np.asarray(st_p.episode.aircraft.mass_slug), np.asarray(st_d.episode.aircraft.mass_slug)
    )
    np.testing.assert_array_equal(
        np.asarray(st_p.disturbance.noise_normals), np.asarray(st_d.disturbance.noise_normals)
    )
    np.testing.assert_array_equal(
        np.asarray(st_p.disturbance.gust_fps), np.asarray(st_d.disturbance.gust_fps)
    )
    np.testing.assert_array_equal(np.asarray(st_p.episode.delay_steps), np.asarray(st_d.episode.delay_steps))
    # the lag and the turbulence: U(0, max) per episode, spread over the range
    lag = np.asarray(st_d.episode.aircraft.act_tau_s)
    assert np.all(np.asarray(st_p.episode.aircraft.act_tau_s) == 0)
    assert lag.min() >= 0 and lag.max() <= 0.1 and lag.max() - lag.min() > 0.05
    severe = np.asarray(disturbed.params().randomization.turbulence_sigma_table_fps)
    factor = np.asarray(st_d.episode.turbulence.sigma_table_fps)[:, 5] / severe[5]
    assert factor.min() >= 0 and factor.max() <= 1 and factor.max() - factor.min() > 0.5
    np.testing.assert_allclose(
        np.asarray(st_d.episode.turbulence.span_ft), np.asarray(st_d.episode.aircraft.b)
    )
    # the observation is the air data: it differs from the inertial state by the wind
    assert st_p.disturbance.turbulence is None and st_d.disturbance.turbulence is not None
    assert not np.array_equal(np.asarray(obs_p[:, :3]), np.asarray(obs_d[:, :3]))
    assert np.all(np.isfinite(np.asarray(obs1_d))) and np.all(np.isfinite(np.asarray(st1_d.wind)))
