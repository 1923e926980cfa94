"""Domain randomization: draws within their documented ranges, switches, gust process.

That the draws change from one episode to the next *in the same env slot* (auto-reset) is tested in
``test_env.py::test_randomization_resampled_every_episode_in_the_same_slot``, where the env step is
compiled anyway.
"""

from __future__ import annotations

import functools
import math

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.aircraft.data_harv import AERO_COLUMNS
from harv_jax.aircraft.params import harv
from harv_jax.aircraft.randomize import AERO_GROUPS
from harv_jax.env import randomize
from harv_jax.env.config import DEFAULT_NOISE_STD_MAX, default_randomization_params

N_DRAWS = 4000
MAX_DELAY = 3
NOMINAL = harv()
#: Tests compile with XLA's backend optimizations off: a third of the compile time, same semantics.
jit_fast = functools.partial(jax.jit, compiler_options={"xla_backend_optimization_level": 0})


@functools.cache
def sampler():
    """[N_DRAWS] keys, RandomizationParams -> EpisodeParams; compiled once, ranges are traced."""
    f = jax.vmap(randomize.sample_episode, in_axes=(0, None, None, None))
    return jit_fast(lambda keys, rand: f(keys, NOMINAL, rand, MAX_DELAY))


def sample(seed, rand=None):
    keys = jax.random.split(jax.random.key(seed), N_DRAWS)
    return jax.device_get(sampler()(keys, rand if rand is not None else default_randomization_params()))


@pytest.fixture(scope="module")
def draws():
    return sample(0)


def _ratio(draws, name):
    return np.asarray(getattr(draws.aircraft, name)) / float(getattr(NOMINAL, name))


@pytest.mark.parametrize("name", ["mass_slug", "Ixx", "Iyy", "Izz", "Ixz"])
def test_mass_and_inertia_within_10_percent(draws, name):
    r = _ratio(draws, name)
    assert r.min() >= 0.9 - 1e-6 and r.max() <= 1.1 + 1e-6
    # the range is used: with 4000 uniform draws the extremes come within 0.5% of the bounds
    assert r.min() < 0.905 and r.max() > 1.095


def test_mass_and_inertia_factors_are_independent(draws):
    c = np.corrcoef(np.stack([_ratio(draws, n) for n in ("mass_slug", "Ixx", "Iyy", "Izz", "Ixz")]))
    off_diag = c[~np.eye(5, dtype=bool)]
    assert np.abs(off_diag).max() < 0.1  # 4000 draws: |r| of independent factors ~ 0.016 std


@pytest.mark.parametrize(
    ("group", "frac"), [("damping", 0.20), ("control", 0.15), ("static", 0.10), ("basic", 0.05)]
)
def test_aero_groups_within_ranges(draws, group, frac):
    scale = np.asarray(draws.aircraft.aero_scale)
    idx = [AERO_COLUMNS.index(c) for c in AERO_GROUPS[group]]
    s = scale[:, idx]
    assert s.min() >= 1 - frac - 1e-6 and s.max() <= 1 + frac + 1e-6
    assert s.min() < 1 - 0.95 * frac and s.max() > 1 + 0.95 * frac


def test_stabilator_pairs_share_a_factor(draws):
    scale = np.asarray(draws.aircraft.aero_scale)
    for coef in ("cy", "croll", "cn", "cd", "clift", "cm"):
        np.testing.assert_array_equal(
            scale[:, AERO_COLUMNS.index(f"{coef}_del")], scale[:, AERO_COLUMNS.index(f"{coef}_der")]
        )
    # the other columns are drawn independently: two damping columns are not equal
    assert not np.allclose(scale[:, AERO_COLUMNS.index("cm_q")], scale[:, AERO_COLUMNS.index("croll_p")])


def test_geometry_and_limits_not_randomized(draws):
    for name in ("S", "b", "cbar", "T_max", "throttle", "g"):
        np.testing.assert_array_equal(
            np.asarray(getattr(draws.aircraft, name)), float(getattr(NOMINAL, name))
        )
    np.testing.assert_array_equal(np.asarray(draws.aircraft.u_min_rad)[0], np.asarray(NOMINAL.u_min_rad))


def test_delay_gust_noise_ranges(draws):
    delay = np.asarray(draws.delay_steps)
    assert delay.dtype == np.int32
    assert set(np.unique(delay)) == {0, 1, 2}  # default delay_max_steps = 2, every value drawn
    # each of the 3 values has probability 1/3: 4000 draws -> 1333 +- 30 (1 std)
    assert np.all(np.abs(np.bincount(delay) - N_DRAWS / 3) < 200)
    std = np.asarray(draws.gust_std_fps)
    assert std.min() >= 0.0 and std.max() <= 10.0 and std.max() > 9.9
    tau = np.asarray(draws.gust_tau_s)
    assert tau.min() >= 1.0 and tau.max() <= 10.0
    noise = np.asarray(draws.noise_std)
    chex.assert_shape(noise, (N_DRAWS, 8))
    ratio = noise / DEFAULT_NOISE_STD_MAX  # one U(0, 1) factor per episode for all channels
    assert ratio.min() >= 0.0 and ratio.max() <= 1.0 + 1e-6
    np.testing.assert_allclose(ratio, ratio[:, :1] * np.ones((1, 8)), rtol=1e-5, atol=1e-7)


def test_draws_differ_between_keys_and_repeat_for_the_same_key(draws):
    chex.assert_trees_all_equal(draws, sample(0))  # same keys, same draws
    # every key its own aircraft. The draws have 16-bit resolution (randomize.uniform16), so single
    # factors collide now and then: 4000^2 / (2 * 65536) = 122 expected collisions among 4000 masses
    assert len(np.unique(np.asarray(draws.aircraft.mass_slug))) > 0.95 * N_DRAWS
    assert len(np.unique(np.asarray(draws.aircraft.aero_scale), axis=0)) == N_DRAWS


def test_switches_off_give_nominal():
    rand = default_randomization_params(enabled=False)
    ep = sample(1, rand)
    first = jax.tree.map(lambda x: x[0], ep)
    chex.assert_trees_all_equal(first.aircraft, jax.device_get(NOMINAL))
    for leaf_draws, leaf_nominal in zip(jax.tree.leaves(ep.aircraft), jax.tree.leaves(NOMINAL), strict=True):
        np.testing.assert_array_equal(leaf_draws, np.broadcast_to(leaf_nominal, leaf_draws.shape))
    np.testing.assert_array_equal(ep.delay_steps, 0)
    np.testing.assert_array_equal(ep.gust_std_fps, 0.0)
    np.testing.assert_array_equal(ep.noise_std, 0.0)
    chex.assert_trees_all_equal(randomize.nominal_episode(NOMINAL, rand).aircraft, NOMINAL)


def test_single_switch_only_changes_its_item():
    rand = default_randomization_params(enabled=False).replace(aero_on=jnp.array(True))
    ep = sample(1, rand)
    np.testing.assert_array_equal(ep.aircraft.mass_slug, float(NOMINAL.mass_slug))
    assert np.all(np.any(np.asarray(ep.aircraft.aero_scale) != 1.0, axis=1))
    np.testing.assert_array_equal(ep.gust_std_fps, 0.0)
    np.testing.assert_array_equal(ep.delay_steps, 0)


def test_delay_capped_by_static_buffer():
    rand = default_randomization_params().replace(delay_max_steps=jnp.array(10, dtype=jnp.int32))
    d = np.asarray(sample(2, rand).delay_steps)
    assert set(np.unique(d)) == set(range(MAX_DELAY + 1))  # 0..3, not 0..10


def test_gust_step_hand_worked():
    # tau = 1 s, dt = 0.01 s: a = exp(-0.01) = 0.99004983; std 5 ft/s:
    # g' = a g + 5 sqrt(1 - a^2) n = a g + 5 * sqrt(1 - exp(-0.02)) n = a g + 0.70358593 n
    ep = randomize.nominal_episode(NOMINAL, default_randomization_params()).replace(
        gust_std_fps=jnp.array(5.0), gust_tau_s=jnp.array(1.0)
    )
    g = randomize.gust_step(jnp.array([1.0, 0.0, 2.0]), ep, 0.01, jnp.array([0.0, 1.0, -1.0]))
    np.testing.assert_allclose(g, [0.99004983, 0.70358593, 2 * 0.99004983 - 0.70358593], rtol=1e-6)


def test_gust_keeps_its_stationary_std():
    # from the stationary N(0, std^2) the OU step keeps the variance: a^2 std^2 + std^2 (1 - a^2) = std^2
    ep = randomize.nominal_episode(NOMINAL, default_randomization_params()).replace(
        gust_std_fps=jnp.array(5.0), gust_tau_s=jnp.array(0.5)
    )
    rng = np.random.default_rng(4)
    n = 20000

    @jit_fast
    def run(normal0, normals, ep):
        # the functions broadcast over leading axes: [n, 3] gusts with one episode's scalars
        g0 = randomize.gust_init(normal0, ep)
        g, _ = jax.lax.scan(lambda g, z: (randomize.gust_step(g, ep, 0.01, z), None), g0, normals)
        return g0, g

    # 50 steps = 0.5 s = one correlation time
    z0 = rng.standard_normal((n, 3), dtype=np.float32)
    g0, g = run(z0, rng.standard_normal((50, n, 3), dtype=np.float32), ep)
    # 60,000 samples: relative std error of the sample std ~ 1/sqrt(2 * 60000) = 0.3%
    assert float(jnp.std(g)) == pytest.approx(5.0, rel=0.02)
    # lag correlation after one correlation time: exp(-1) = 0.3679
    corr = float(jnp.mean(g * g0) / jnp.mean(g0 * g0))
    assert corr == pytest.approx(math.exp(-1.0), abs=0.02)


def test_uniform16():
    u = np.asarray(randomize.uniform16(jax.random.key(6), 20001))
    chex.assert_shape(u, (20001,))
    assert u.min() > 0.0 and u.max() < 1.0  # strictly inside: (k + 0.5) / 65536
    k = u * 65536 - 0.5
    np.testing.assert_allclose(k, np.round(k), atol=1e-3)  # on the 16-bit grid
    assert abs(u.mean() - 0.5) < 0.01 and abs(u.var() - 1 / 12) < 0.003
    # the two halves of a word are not correlated
    n = (20001 + 1) // 2
    assert abs(np.corrcoef(u[: n - 1], u[n : 2 * n - 1])[0, 1]) < 0.05


def test_normals_from_uniform():
    u = np.random.default_rng(5).uniform(size=(50000, 12)).astype(np.float32)
    z = np.asarray(randomize.normals_from_uniform(u))
    chex.assert_shape(z, (50000, 12))
    assert np.all(np.isfinite(z))
    # 600,000 draws: std error of the mean 0.0013, of the std 0.0009
    assert abs(z.mean()) < 0.01 and abs(z.std() - 1.0) < 0.01
    assert abs(np.mean(np.abs(z) < 1.0) - 0.6827) < 0.005  # P(|Z| < 1)
    c = np.corrcoef(z[:, :4].T)
    assert np.abs(c[~np.eye(4, dtype=bool)]).max() < 0.02
    # the extreme u = 0 stays finite (1 - u = 1 -> radius 0)
    assert np.all(np.isfinite(randomize.normals_from_uniform(jnp.zeros(2))))
