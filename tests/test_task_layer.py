"""The task layer and the shared plant step: one definition, the same numbers wherever it is used."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.aircraft.randomize import default_aircraft_randomization, sample_aircraft
from harv_jax.dynamics import actuator_step, from_wind, plant_step, rk4_body_step, to_wind
from harv_jax.env import default_randomization_params
from harv_jax.env.randomize import sample_episode
from harv_jax.task import spec
from harv_jax.task.criteria import default_envelope
from harv_jax.task.scenarios import RESET_HIGH, RESET_LOW
from harv_jax.task.spaces import OBS_HIGH, OBS_LOW

X0 = jnp.array([500.0, 0.6, 0.05, 0.5, -0.05, 0.3, 0.4, 0.1, 0.0, 20000.0], jnp.float32)


def test_plant_step_is_actuator_then_rk4_then_wind_bit_for_bit():
    params = jax.tree.map(lambda a: jnp.asarray(a, jnp.float32), harv())
    body, delta, cmd = from_wind(X0), jnp.zeros(3, jnp.float32), jnp.array([-0.3, 0.2, 0.1], jnp.float32)
    gust = jnp.array([1.0, -2.0, 0.5], jnp.float32)

    def by_hand(body, delta):
        d = actuator_step(delta, cmd, params, spec.DT_S)
        b = rk4_body_step(body, d, params, spec.DT_S, gust)
        return b, d, to_wind(b)

    got = jax.jit(lambda b, d: plant_step(b, d, cmd, params, spec.DT_S, gust))(body, delta)
    want = jax.jit(by_hand)(body, delta)
    for g, w in zip(jax.tree.leaves(tuple(got)), jax.tree.leaves(want), strict=True):
        np.testing.assert_array_equal(np.asarray(g), np.asarray(w))


def test_sample_aircraft_is_the_env_episode_aircraft():
    nominal = harv()
    key = jax.random.key(11)
    a = sample_aircraft(key, nominal, default_aircraft_randomization(True))
    b = sample_episode(key, nominal, default_randomization_params(True), 2).aircraft
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))


def test_spaces_and_bounds_come_from_spec():
    lo = [spec.RESET_BOUNDS[n][0] for n in spec.RESET_STATE_NAMES]
    hi = [spec.RESET_BOUNDS[n][1] for n in spec.RESET_STATE_NAMES]
    np.testing.assert_array_equal(RESET_LOW, lo)
    np.testing.assert_array_equal(RESET_HIGH, hi)
    assert OBS_LOW[1] == np.float32(spec.ALPHA_MIN_RAD) and OBS_HIGH[1] == np.float32(spec.ALPHA_MAX_RAD)
    env = default_envelope()
    assert float(env.v_max_fps) == spec.V_MAX_FPS and float(env.h_floor_ft) == spec.H_FLOOR_FT
