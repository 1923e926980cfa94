"""A cheap controller for the tests whose point is not the SMC (it compiles in seconds, the SMC in tens), and
registering a test controller for the ``with`` block."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

import jax.numpy as jnp

from harv_jax.control import registry
from harv_jax.control.base import Controller


def make_damper() -> Controller:
    """A rate damper about a little nose-down stabilator: (de, da, dr) = (-0.05 - 0.5 q, -0.3 p, 0.3 r),
    rad, from the measured state (so sensor noise reaches the plant); no state, no diagnostics."""

    def init(params):
        del params
        return jnp.zeros(())

    def apply(state, x_wind, reference_rad, key):
        del reference_rad, key
        p, q, r = x_wind[3], x_wind[4], x_wind[5]
        return jnp.stack([-0.05 - 0.5 * q, -0.3 * p, 0.3 * r]).astype(x_wind.dtype), state, {}

    return Controller(init=init, apply=apply)


@contextlib.contextmanager
def registered(name: str, make: Callable[[], Controller], help: str) -> Iterator[str]:
    """``make()`` registered as the option-less controller ``name`` for the ``with`` block (removed after)."""
    registry.register(name, lambda opts: make(), options=(), help=help)
    try:
        yield name
    finally:
        registry.CONTROLLERS.pop(name, None)
