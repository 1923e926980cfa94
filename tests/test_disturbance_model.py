"""dynamics.disturbance_model: a disturbance added to the table flies in the one disturbed step.

In process and fast (``tests/test_toy_disturbance.py``, -m slow, adds toys to a copy of the package and flies
them through the commands and the env): a model's measurement and wind enter ``measured`` and ``air_data``,
its state starts from and steps with keys of its own, and the built-in disturbances' draws are unchanged.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.dynamics.disturbance_model import DisturbanceModel, model_key
from harv_jax.dynamics.disturbances import DisturbanceParams, step_normals
from harv_jax.dynamics.disturbed_step import air_data, disturbance_init, disturbed_plant_step, measured
from harv_jax.dynamics.state import WIND_INDEX, from_wind

#: A toy: the alpha vane reads high by a state drawn N(level, 0.1 level) at engagement and redrawn each
#: step; the air mass moves along body z at the level, ft/s.
TOY = DisturbanceModel(
    init=lambda level, key: level * (1.0 + 0.1 * jax.random.normal(key, ())),
    step=lambda state, level, key, dt_s: level * (1.0 + 0.1 * jax.random.normal(key, ())),
    wind_fps=lambda state, level: jnp.stack([0.0 * level, 0.0 * level, level]),
    measure=lambda x, state, level: x.at[WIND_INDEX["alpha"]].add(state),
)
X0 = jnp.array([500.0, 0.3, 0.05, 0.1, -0.1, 0.2, 0.3, -0.2, 0.0, 25000.0])


def _levels(with_toy: bool) -> DisturbanceParams:
    added = {"added_levels": {"toy": jnp.asarray(0.02)}, "added_models": (("toy", TOY),)} if with_toy else {}
    return DisturbanceParams(
        jnp.full(8, 0.01), jnp.asarray(1, jnp.int32), jnp.asarray(4.0), jnp.asarray(2.0), **added
    )


def test_the_added_model_enters_the_step_and_leaves_every_other_draw_alone():
    key0, key1 = jax.random.key(7), jax.random.key(8)
    states, steps, airs, ys = {}, {}, {}, {}
    for with_toy in (False, True):
        lv = _levels(with_toy)
        st = disturbance_init(step_normals(key0), lv, jnp.zeros(3), jnp.asarray(0.0), 2, key0)
        body = from_wind(X0)
        air = air_data(body, st, lv)
        ys[with_toy] = measured(air.x_wind, st, lv)
        airs[with_toy] = air
        steps[with_toy] = disturbed_plant_step(
            body, jnp.zeros(3), st, jnp.full(3, 0.05), air, harv(), lv, 0.01, key1
        )
        states[with_toy] = st
    toy0 = 0.02 * (1.0 + 0.1 * jax.random.normal(model_key(key0, "toy"), ()))
    assert states[True].added["toy"] == toy0 and states[False].added == {}
    for part in ("gust_fps", "noise_normals", "cmd_buffer_rad"):  # the built-in draws: bit for bit
        np.testing.assert_array_equal(getattr(states[True], part), getattr(states[False], part))
        np.testing.assert_array_equal(
            getattr(steps[True].disturbance, part), getattr(steps[False].disturbance, part)
        )
    np.testing.assert_array_equal(airs[True].wind_fps, airs[False].wind_fps + jnp.array([0.0, 0.0, 0.02]))
    # the sensors: the air data of the moved air mass, plus the same noise, plus the vane's bias
    no_bias = measured(airs[True].x_wind, states[True], _levels(False))
    np.testing.assert_allclose(ys[True] - no_bias, np.eye(10)[WIND_INDEX["alpha"]] * float(toy0), atol=1e-7)
    toy1 = 0.02 * (1.0 + 0.1 * jax.random.normal(model_key(key1, "toy"), ()))
    assert steps[True].disturbance.added["toy"] == toy1
    # held without a key, as the gust and the noise are
    held = disturbed_plant_step(
        from_wind(X0), jnp.zeros(3), states[True], jnp.zeros(3), airs[True], harv(), _levels(True), 0.01, None
    )
    assert held.disturbance.added["toy"] == states[True].added["toy"]
