"""Fixed-step RK4 integration of the singularity-free state (the plant step is ``dynamics.plant``)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics.eom import body_derivatives, derivatives
from harv_jax.dynamics.state import WIND_INDEX, BodyState, check_shape, from_wind, to_wind


def _axpy(a, x: BodyState, y: BodyState) -> BodyState:
    return jax.tree.map(lambda xi, yi: yi + a * xi, x, y)


def _restacked(state: BodyState) -> BodyState:
    """The state rebuilt from its components (equal values).

    Vmapped, a ``[N, k]`` leaf is stored aircraft-major while XLA stores the stacked derivatives
    component-major. The stages added the two through a transpose inside every fusion that read a stage's
    input. Rebuilt by a stack, the state gets the derivatives' layout once per step (a fusion XLA keeps).
    """
    return jax.tree.map(lambda leaf: jnp.stack([leaf[i] for i in range(leaf.shape[0])]), state)


def rk4_body_step(
    state: BodyState,
    u: jnp.ndarray,
    params: AircraftParams,
    dt_s: float | jnp.ndarray,
    wind_body_fps: jnp.ndarray | None = None,
    wind_pqr_radps: jnp.ndarray | None = None,
) -> BodyState:
    """One RK4 step of the body-axis state (controls and wind held over the step).

    The quaternion is renormalized after the step.
    """

    def f(s):
        return body_derivatives(s, u, params, wind_body_fps, wind_pqr_radps)

    state = _restacked(state)
    k1 = f(state)
    k2 = f(_axpy(0.5 * dt_s, k1, state))
    k3 = f(_axpy(0.5 * dt_s, k2, state))
    k4 = f(_axpy(dt_s, k3, state))
    incr = jax.tree.map(lambda a, b, c, d: (a + 2.0 * b + 2.0 * c + d) * (dt_s / 6.0), k1, k2, k3, k4)
    new = jax.tree.map(jnp.add, state, incr)
    return new.replace(quat=new.quat / jnp.linalg.norm(new.quat))


def rk4_step(
    x: BodyState | jnp.ndarray,
    u: jnp.ndarray,
    params: AircraftParams,
    dt_s: float | jnp.ndarray,
    wind_body_fps: jnp.ndarray | None = None,
) -> BodyState | jnp.ndarray:
    """One RK4 step of the flight model.

    Args:
        x: a BodyState (integration state), or a wind-axis state [10]; the latter is converted to the
            body form, stepped there (no wind-axis singularity inside the step) and converted back.
        u: [3] deflections [de, da, dr], rad, held over the step.
        params: aircraft parameters.
        dt_s: step, s (the paper's is ``task.spec.DT_S``).
        wind_body_fps: optional [3] wind in body axes.

    Returns:
        The stepped state, of the same kind as ``x``.
    """
    check_shape(u, (3,), "control u [de, da, dr]")
    if isinstance(x, BodyState):
        return rk4_body_step(x, u, params, dt_s, wind_body_fps)
    body = from_wind(x)
    new = rk4_body_step(body, u, params, dt_s, wind_body_fps)
    out = to_wind(new)
    # chi is only defined modulo 2 pi; keep it continuous with the input
    chi = WIND_INDEX["chi"]
    return out.at[chi].set(x[chi] + jnp.mod(out[chi] - x[chi] + jnp.pi, 2 * jnp.pi) - jnp.pi)


def rk4_step_wind(
    x: jnp.ndarray, u: jnp.ndarray, params: AircraftParams, dt_s: float | jnp.ndarray
) -> jnp.ndarray:
    """One RK4 step of the paper's wind-axis equations themselves (singular at |gamma| = 90 deg).

    For analysis and cross-checks; simulations use the body form.
    """

    def f(s):
        return derivatives(s, u, params)

    k1 = f(x)
    k2 = f(x + 0.5 * dt_s * k1)
    k3 = f(x + 0.5 * dt_s * k2)
    k4 = f(x + dt_s * k3)
    return x + (dt_s / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
