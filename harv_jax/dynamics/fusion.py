"""Shapes of the plant step that XLA's CPU backend compiles well (values unchanged up to float32 rounding).

XLA's CPU fusion copies cheap elementwise producers into every consumer fusion, and ``arctan2`` is a scalar
library call (~10 ns per element). Two tools:

- [`evaluated_once`][]: ``fn(x)`` computed in a ``while_loop`` that runs once. A loop is a fusion
  boundary XLA keeps (``optimization_barrier`` is removed before fusion on the CPU), so ``fn``'s outputs are
  materialized once. A custom JVP differentiates ``fn`` itself (forward and reverse mode work).
- [`atan2`][] / [`airflow_angles`][]: in float32 on the CPU a vectorized ``arctan2`` ([`atan2_f32`][],
  Cephes ``atanf``, <= 3.1 ulp); in the RK4 stages alpha and beta are computed once per stage in such a loop
  (without it XLA copied the polynomial into the 33-column table interpolation).

Float64 and accelerators keep ``jnp.arctan2`` and no loops. Values equal the plain step's to float32
rounding: after 100 steps of 1,024 tumbling aircraft, 2e-4 relative at most (the arctan2's last bits,
amplified). The speed-ups, measured side by side, are in `benchmarks/README.md` ("Speed log").
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

_TAN_PI_8 = float(np.tan(np.pi / 8))


def _on_cpu() -> bool:
    return jax.default_backend() == "cpu"


def opaque_one() -> jax.Array:
    """The int32 1, behind an ``optimization_barrier``: XLA cannot fold a loop bounded by it.

    A constant, so the loop's trip count is the same on every device without communication (a bound
    computed from sharded data made the partitioner add an all-reduce per loop).
    """
    return jax.lax.optimization_barrier(jnp.int32(1))


def evaluated_once(fn: Callable[[Any], Any], x: Any) -> Any:
    """``fn(x)``, evaluated inside a one-trip ``while_loop`` on the CPU (a fusion boundary), else plainly.

    (No loop on an accelerator: it would evaluate the loop condition on the host.)

    Args:
        fn: a pure function of one pytree (it may close over traced values).
        x: its argument (a pytree of arrays).

    Returns:
        ``fn(x)``; forward and reverse mode differentiate ``fn`` itself.
    """
    if not _on_cpu():
        return fn(x)
    converted, consts = jax.closure_convert(fn, x)  # closed-over tracers become explicit arguments
    return _once(converted, x, *consts)


@partial(jax.custom_jvp, nondiff_argnums=(0,))
def _once(fn: Callable[..., Any], x: Any, *consts: Any) -> Any:
    out0 = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), jax.eval_shape(fn, x, *consts))
    trips = opaque_one()

    def body(carry: tuple) -> tuple:
        i, arg, _ = carry
        return i + 1, arg, fn(arg, *consts)

    return jax.lax.while_loop(lambda c: c[0] < trips, body, (jnp.zeros((), jnp.int32), x, out0))[2]


@_once.defjvp
def _once_jvp(fn: Callable[..., Any], primals: tuple, tangents: tuple) -> tuple:
    return jax.jvp(fn, primals, tangents)


def atan2_f32(y: jax.Array, x: jax.Array) -> jax.Array:
    """``arctan2(y, x)`` in float32 from elementwise arithmetic only (XLA vectorizes it).

    Octant reduction to ``atan(t)``, ``0 <= t <= 1``, then ``t -> (t - 1) / (t + 1)`` above tan(pi/8) and
    Cephes' ``atanf`` polynomial. Within 3.1 ulp of the float64 ``arctan2`` (XLA's own: 1.4), same signed
    zeros and infinities as ``numpy.arctan2``; NaN in, NaN out.
    """
    ax, ay = jnp.abs(x), jnp.abs(y)
    hi, lo = jnp.maximum(ax, ay), jnp.minimum(ax, ay)
    t = lo / jnp.where(hi > 0, hi, 1.0)
    t = jnp.where(jnp.isinf(ax) & jnp.isinf(ay), 1.0, t)
    big = t > _TAN_PI_8
    r = jnp.where(big, (t - 1.0) / (t + 1.0), t)
    z = r * r
    poly = (((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z - 3.33329491539e-1) * z
    a = jnp.where(big, np.float32(np.pi / 4), np.float32(0.0)) + (r + r * poly)
    a = jnp.where(ay > ax, np.float32(np.pi / 2) - a, a)
    a = jnp.where(jnp.signbit(x), np.float32(np.pi) - a, a)
    a = jnp.where(jnp.isnan(x) | jnp.isnan(y), jnp.nan, a)
    return jnp.where(jnp.signbit(y), -a, a)


def _vectorized_atan2(*args: jax.Array) -> bool:
    """Float32 on the CPU: [`atan2_f32`][] replaces the library's scalar ``arctan2``."""
    return _on_cpu() and jnp.result_type(*args) == jnp.float32


def atan2(y: jax.Array, x: jax.Array) -> jax.Array:
    """``arctan2(y, x)``: [`atan2_f32`][] in float32 on the CPU (vectorized), else ``jnp.arctan2``."""
    return atan2_f32(y, x) if _vectorized_atan2(y, x) else jnp.arctan2(y, x)


def airflow_angles(wa: jax.Array, ua: jax.Array, va: jax.Array, uw: jax.Array) -> tuple[jax.Array, jax.Array]:
    """(alpha, beta) = (arctan2(w, u), arctan2(v, sqrt(u^2 + w^2))) of the air-relative velocity, rad.

    Float32 on the CPU: [`atan2_f32`][] of both, evaluated once ([`evaluated_once`][]); otherwise
    ``jnp.arctan2``.
    """
    if not _vectorized_atan2(wa, ua, va, uw):
        return jnp.arctan2(wa, ua), jnp.arctan2(va, uw)

    def both(v: tuple) -> jax.Array:
        return jnp.stack([atan2_f32(v[0], v[1]), atan2_f32(v[2], v[3])])

    angles = evaluated_once(both, (wa, ua, va, uw))
    return angles[0], angles[1]
