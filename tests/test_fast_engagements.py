"""Weighted initial airspeeds (``EnvConfig.v0_fast_weight``): the piecewise-uniform draw, the env's resets."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.env import EnvConfig, default_params, make_env
from harv_jax.task.scenarios import weighted_airspeed


def test_weighted_airspeed_is_piecewise_uniform_with_the_asked_share():
    u = jnp.linspace(0.0, 1.0, 100_001)
    v = np.asarray(weighted_airspeed(u, 100.0, 1500.0, 1000.0, 3.0), np.float64)
    assert v[0] == pytest.approx(100.0) and v[-1] == pytest.approx(1500.0, rel=1e-6)
    assert np.all(np.diff(v) >= -1e-3)  # monotone: an inverse distribution function
    share_above = 3.0 * 500.0 / (900.0 + 3.0 * 500.0)  # 0.625
    assert np.mean(v > 1000.0) == pytest.approx(share_above, abs=1e-3)
    assert np.mean(v[v > 1000.0]) == pytest.approx(1250.0, abs=1.0)  # uniform within each band
    assert np.mean(v[v < 1000.0]) == pytest.approx(550.0, abs=1.0)
    flat = np.asarray(weighted_airspeed(u, 100.0, 1500.0, 1000.0, 1.0), np.float64)
    np.testing.assert_allclose(flat, 100.0 + 1400.0 * np.asarray(u, np.float64), atol=1e-3)


def _initial_states(config: EnvConfig, n: int) -> np.ndarray:
    env = make_env(config)
    params = default_params(config)
    keys = jax.random.split(jax.random.key(3), n)
    _, states = jax.jit(jax.vmap(env.reset, in_axes=(0, None)))(keys, params)
    return np.asarray(states.wind)


def test_env_resets_draw_fast_engagements_with_the_weight_and_nothing_else_changes():
    n = 8192
    base = _initial_states(EnvConfig(domain_randomization=False), n)
    fast = _initial_states(EnvConfig(domain_randomization=False, v0_fast_weight=3.0), n)
    np.testing.assert_array_equal(base[:, 1:], fast[:, 1:])  # only the airspeed moves
    assert np.mean(base[:, 0] > 1000.0) == pytest.approx(500.0 / 1400.0, abs=0.02)
    assert np.mean(fast[:, 0] > 1000.0) == pytest.approx(0.625, abs=0.02)
    assert fast[:, 0].min() >= 100.0 and fast[:, 0].max() <= 1500.0


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_weight_is_refused(bad):
    with pytest.raises(ValueError, match="v0_fast_weight"):
        EnvConfig(v0_fast_weight=bad)
