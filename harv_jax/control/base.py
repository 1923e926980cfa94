"""The controller interface shared by every controller (SMC, RL-only, hybrid).

A controller is a pair of pure functions, optax-style (``optax.GradientTransformation``):

    ctrl_state = controller.init(params)
    u_rad, ctrl_state, info = controller.apply(ctrl_state, x_wind, reference_rad, key)

``params`` is the aircraft (``AircraftParams``) the controller is built for; whatever per-aircraft
data the controller needs (its model, its integrator states) lives in ``ctrl_state``, so a batch of
aircraft is simply ``jax.vmap(controller.apply)`` over batched states. ``x_wind`` is the wind-axis
state [10] (V ft/s, alpha, beta rad, p, q, r rad/s, mu, gamma, chi rad, h ft); ``reference_rad`` is
[alpha_d, beta_d, mu_d] in rad; ``key`` is a PRNG key (unused by deterministic controllers).
``u_rad`` is the deflection command [de, da, dr] in rad; position and rate limits are applied by
the plant's actuator model (``harv_jax.dynamics.actuator_step``). ``info`` is a flat dict of arrays
of fixed shapes (per-step diagnostics, e.g. sliding variables); its structure must not depend on
values so that it can be stacked by ``lax.scan``. A controller state with a field ``u_prev_rad`` (its
last command) is started at the plant's initial deflections by ``harv_jax.evaluation.closed_loop``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams

CtrlState = Any
Info = dict[str, jnp.ndarray]
InitFn = Callable[[AircraftParams], CtrlState]
ApplyFn = Callable[[CtrlState, jnp.ndarray, jnp.ndarray, jax.Array], tuple[jnp.ndarray, CtrlState, Info]]


class Controller(NamedTuple):
    """A controller as two pure functions (see the module docstring for the signatures).

    Attributes:
        init: ``init(params) -> ctrl_state``.
        apply: ``apply(ctrl_state, x_wind[10], reference_rad[3], key) -> (u_rad[3], ctrl_state, info)``.
    """

    init: InitFn
    apply: ApplyFn
