"""RL-only controller: observation and action mapping identical to the env's."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.rl import make_rl_controller
from harv_jax.task.spaces import action_to_command, observation


def test_rl_controller_maps_like_the_env():
    seen = {}

    def act(obs):
        seen["obs"] = obs
        return jnp.array([-1.0, 0.0, 2.0])  # the last one out of range: clipped to +1

    params = harv()
    ctrl = make_rl_controller(act)
    x = jnp.array([500.0, 0.3, 0.05, 0.1, -0.2, 0.3, 0.4, -0.1, 0.0, 25000.0])
    ref = jnp.array([0.349, 0.0, 0.0])
    u, state, info = ctrl.apply(ctrl.init(params), x, ref, jax.random.key(0))
    np.testing.assert_allclose(seen["obs"], observation(x, ref))
    # action -1 -> lower limit, 0 -> mid-range, clipped +1 -> upper limit (per surface, rad)
    np.testing.assert_allclose(u, [params.u_min_rad[0], 0.0, params.u_max_rad[2]], atol=1e-7)
    np.testing.assert_allclose(
        u, action_to_command(jnp.array([-1.0, 0.0, 1.0]), params.u_min_rad, params.u_max_rad)
    )
    np.testing.assert_allclose(info["action"], [-1.0, 0.0, 1.0])


def test_rl_controller_nonfinite_state_gives_finite_command():
    ctrl = make_rl_controller(lambda obs: jnp.tanh(obs[:3]))
    x = jnp.full((10,), jnp.nan)
    u, _, _ = ctrl.apply(ctrl.init(harv()), x, jnp.zeros(3), jax.random.key(0))
    assert bool(jnp.all(jnp.isfinite(u)))
