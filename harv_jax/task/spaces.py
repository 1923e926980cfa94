"""Observation and action spaces of the paper's task, and the mapping of states and actions to them.

Observation [11] (paper Table "Observation and Action Space"; physical units, ft/s, rad, rad/s):
[V, alpha, beta, p, q, r, mu, gamma, alpha_d, beta_d, mu_d]: the first ``NUM_MEASURED`` components of the
wind-axis state, then the target. Two optional layouts extend it with components kept from earlier
observations ([`ObservationLayout`][], [`ObservationMemory`][]):

- ``[env] observe_engage_airspeed = true`` (12): ``V_engage``, the airspeed of the first observation of the
  recovery (ft/s, held for the whole recovery), so a policy can make choices that depend on how fast the
  recovery began;
- ``[env] observe_tracking_integral = true`` (14): the integral of the tracking error e = [alpha - alpha_d,
  beta - beta_d, mu - mu_d] (rad s) with the anti-windup rules of the SMC's defaults (it runs only while
  |e| < 5 deg per channel, mu only while |gamma| <= 45 deg, clipped to +-0.5 rad s), the memory a sliding
  surface with an integral term has and a memoryless policy lacks.

Action [3] in [-1, 1],
mapped affinely to [u_min, u_max] per channel (de, da, dr). The env (``harv_jax.env``) and the learned
controllers (``control.rl``, ``control.hybrid``) both use these functions, so a policy sees in flight exactly
what it saw in training.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.task.spec import (
    ALPHA_MAX_RAD,
    ALPHA_MIN_RAD,
    GAMMA_MAX_RAD,
    RATE_MAX_RADPS,
    V_MAX_FPS,
    V_MIN_FPS,
)
from harv_jax.units import RAD_PER_DEG

#: Names of the observation components, in order (paper: s = {V, alpha, beta, p, q, r, mu, gamma,
#: alpha_d, beta_d, mu_d}); units ft/s, rad, rad/s.
OBS_NAMES: tuple[str, ...] = ("V", "alpha", "beta", "p", "q", "r", "mu", "gamma", "alpha_d", "beta_d", "mu_d")
OBSERVATION_SIZE = len(OBS_NAMES)
ACTION_SIZE = 3
#: Names of the observation with the engagement airspeed (``observe_engage_airspeed``), in order.
ENGAGE_OBS_NAMES: tuple[str, ...] = (*OBS_NAMES, "V_engage")
ENGAGE_OBSERVATION_SIZE = len(ENGAGE_OBS_NAMES)
#: Names of the observation with the tracking-error integral (``observe_tracking_integral``), in order.
INTEGRAL_OBS_NAMES: tuple[str, ...] = (*OBS_NAMES, "int_e_alpha", "int_e_beta", "int_e_mu")
INTEGRAL_OBSERVATION_SIZE = len(INTEGRAL_OBS_NAMES)
#: The tracking-error integral runs on a channel only while |e| is below this, rad (the SMC's default band).
INTEGRAL_BAND_RAD = 5.0 * RAD_PER_DEG
#: Bound on each component of the tracking-error integral, rad s (the SMC's default clip).
INTEGRAL_CLIP_RAD_S = 0.5
#: The mu component of the integral runs only while |gamma| is at most this, rad (where the SMC's mu
#: sliding mode is fully active).
INTEGRAL_MU_GAMMA_MAX_RAD = 45.0 * RAD_PER_DEG
#: Number of leading observation components that are measured (sensor noise applies to them).
NUM_MEASURED = 8

_PI = math.pi
_RATE = RATE_MAX_RADPS
#: Observation bounds (paper Table "Observation and Action Space"); the targets get the alpha range
#: (alpha_d) and [-pi, pi] (beta_d, mu_d). Observations are clipped to these bounds, so they only bind
#: on a terminal observation (the envelope is the same box) or through sensor noise at the edge.
OBS_LOW = np.array(
    [V_MIN_FPS, ALPHA_MIN_RAD, -_PI, -_RATE, -_RATE, -_RATE, -_PI, -GAMMA_MAX_RAD, ALPHA_MIN_RAD, -_PI, -_PI],
    dtype=np.float32,
)
OBS_HIGH = np.array(
    [V_MAX_FPS, ALPHA_MAX_RAD, _PI, _RATE, _RATE, _RATE, _PI, GAMMA_MAX_RAD, ALPHA_MAX_RAD, _PI, _PI],
    dtype=np.float32,
)


def action_to_command(action: jnp.ndarray, u_min_rad: jnp.ndarray, u_max_rad: jnp.ndarray) -> jnp.ndarray:
    """Affine map of a normalized action [3] in [-1, 1] to deflections in [u_min, u_max], rad."""
    return u_min_rad + 0.5 * (action + 1.0) * (u_max_rad - u_min_rad)


def command_to_action(cmd_rad: jnp.ndarray, u_min_rad: jnp.ndarray, u_max_rad: jnp.ndarray) -> jnp.ndarray:
    """Inverse of [`action_to_command`][]: deflections [3], rad -> normalized action [3]."""
    return 2.0 * (cmd_rad - u_min_rad) / (u_max_rad - u_min_rad) - 1.0


def clean_observation(x_wind: jnp.ndarray, target_rad: jnp.ndarray) -> jnp.ndarray:
    """[11] observation of a wind-axis state [10] and target [3] without noise or clipping."""
    return jnp.concatenate([x_wind[:NUM_MEASURED], target_rad])


def finish_observation(obs: jnp.ndarray) -> jnp.ndarray:
    """Non-finite components -> 0, then clipped to the observation box [11]."""
    obs = jnp.nan_to_num(obs, nan=0.0, posinf=0.0, neginf=0.0)
    return jnp.clip(obs, jnp.asarray(OBS_LOW, obs.dtype), jnp.asarray(OBS_HIGH, obs.dtype))


def observation(x_wind: jnp.ndarray, target_rad: jnp.ndarray) -> jnp.ndarray:
    """[11] noise-free observation as the policy sees it in the env (non-finite -> 0, clipped to the box)."""
    return finish_observation(clean_observation(x_wind, target_rad))


def with_engage_airspeed(obs: jnp.ndarray, v_engage_fps: jnp.ndarray) -> jnp.ndarray:
    """[11] observation -> [12] with the engagement airspeed appended (clipped to the airspeed bounds)."""
    v = jnp.clip(jnp.asarray(v_engage_fps, obs.dtype), V_MIN_FPS, V_MAX_FPS)
    return jnp.concatenate([obs, v[None]])


def tracking_integral_step(integral_rad_s: jnp.ndarray, obs: jnp.ndarray, dt_s: float) -> jnp.ndarray:
    """One step of the tracking-error integral [3] (rad s) from an [11] observation: e = [alpha - alpha_d,
    beta - beta_d, wrap(mu - mu_d)] is added times ``dt_s`` on the channels where |e| < ``INTEGRAL_BAND_RAD``
    (mu only while |gamma| <= ``INTEGRAL_MU_GAMMA_MAX_RAD``), then clipped to +-``INTEGRAL_CLIP_RAD_S``."""
    d_mu = obs[6] - obs[10]
    e = jnp.stack([obs[1] - obs[8], obs[2] - obs[9], jnp.arctan2(jnp.sin(d_mu), jnp.cos(d_mu))])
    active = jnp.abs(e) < INTEGRAL_BAND_RAD
    active = active.at[2].set(active[2] & (jnp.abs(obs[7]) <= INTEGRAL_MU_GAMMA_MAX_RAD))
    step = jnp.asarray(dt_s, obs.dtype) * jnp.where(active, e, 0.0)
    return jnp.clip(integral_rad_s.astype(obs.dtype) + step, -INTEGRAL_CLIP_RAD_S, INTEGRAL_CLIP_RAD_S)


@struct.dataclass
class ObservationMemory:
    """What an extended observation keeps from earlier observations of the same recovery.

    Attributes:
        v_engage_fps: airspeed of the first observation, ft/s (set at the first observation).
        engaged: whether an observation has been seen (``v_engage_fps`` is set).
        integral_rad_s: [3] tracking-error integral, rad s ([`tracking_integral_step`][]).
    """

    v_engage_fps: jnp.ndarray
    engaged: jnp.ndarray
    integral_rad_s: jnp.ndarray


def observation_memory_init(dtype) -> ObservationMemory:
    """The memory before the first observation (zeros, not engaged)."""
    return ObservationMemory(
        v_engage_fps=jnp.zeros((), dtype), engaged=jnp.asarray(False), integral_rad_s=jnp.zeros((3,), dtype)
    )


@dataclasses.dataclass(frozen=True)
class ObservationLayout:
    """Which components follow the paper's 11 observations (static: changing it recompiles).

    Attributes:
        engage_airspeed: the airspeed of the first observation (12 observations, ``ENGAGE_OBS_NAMES``).
        tracking_integral: the tracking-error integral [3] (14 observations, ``INTEGRAL_OBS_NAMES``).
    """

    engage_airspeed: bool = False
    tracking_integral: bool = False

    def __post_init__(self) -> None:
        if self.engage_airspeed and self.tracking_integral:
            raise ValueError(
                "observe_engage_airspeed and observe_tracking_integral are both on; allowed: one of them or "
                "neither"
            )

    @property
    def names(self) -> tuple[str, ...]:
        """Names of the observation's components, in order."""
        if self.engage_airspeed:
            return ENGAGE_OBS_NAMES
        return INTEGRAL_OBS_NAMES if self.tracking_integral else OBS_NAMES

    @property
    def size(self) -> int:
        """Number of observation components (11, 12 or 14)."""
        return len(self.names)

    @property
    def has_memory(self) -> bool:
        """Whether the observation depends on earlier observations."""
        return self.engage_airspeed or self.tracking_integral

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) float32 bounds of every component."""
        if self.engage_airspeed:
            return np.append(OBS_LOW, np.float32(V_MIN_FPS)), np.append(OBS_HIGH, np.float32(V_MAX_FPS))
        if self.tracking_integral:
            c = np.full(3, INTEGRAL_CLIP_RAD_S, np.float32)
            return np.append(OBS_LOW, -c), np.append(OBS_HIGH, c)
        return OBS_LOW, OBS_HIGH

    def extend(
        self, obs: jnp.ndarray, memory: ObservationMemory, dt_s: float
    ) -> tuple[jnp.ndarray, ObservationMemory]:
        """(the observation of this layout, the memory to keep) from an [11] observation: the engagement
        airspeed is this observation's at the first call and the kept one afterwards; the integral steps
        by ``dt_s`` (s) with this observation's error. The paper's layout returns ``obs`` unchanged."""
        engaged = jnp.asarray(True)
        if self.engage_airspeed:
            v = jnp.where(memory.engaged, memory.v_engage_fps, obs[0]).astype(memory.v_engage_fps.dtype)
            return with_engage_airspeed(obs, v), memory.replace(v_engage_fps=v, engaged=engaged)
        if self.tracking_integral:
            integral = tracking_integral_step(memory.integral_rad_s, obs, dt_s)
            integral = integral.astype(memory.integral_rad_s.dtype)
            out = jnp.concatenate([obs, integral.astype(obs.dtype)])
            return out, memory.replace(integral_rad_s=integral, engaged=engaged)
        return obs, memory


#: Every layout, by observation size.
LAYOUTS: dict[int, ObservationLayout] = {
    lay.size: lay
    for lay in (
        ObservationLayout(),
        ObservationLayout(engage_airspeed=True),
        ObservationLayout(tracking_integral=True),
    )
}


#: The observation sizes a policy may have, in words (for one-line errors).
ALLOWED_OBSERVATION_SIZES = (
    f"{OBSERVATION_SIZE} (the paper's observations), {ENGAGE_OBSERVATION_SIZE} (and the engagement airspeed) "
    f"or {INTEGRAL_OBSERVATION_SIZE} (and the tracking-error integral)"
)


def layout_of_size(observation_size: int) -> ObservationLayout:
    """The layout a policy of ``observation_size`` inputs expects; ValueError for a size no layout has."""
    if observation_size not in LAYOUTS:
        raise ValueError(
            f"a policy with {observation_size} observations does not fit this task; allowed: "
            f"{ALLOWED_OBSERVATION_SIZES}"
        )
    return LAYOUTS[observation_size]
