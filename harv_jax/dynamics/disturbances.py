"""What comes between a controller and the aircraft: sensor noise, command delay and a body-axis gust.

One model, used by the training env (``harv_jax.env.recovery``) and the closed-loop evaluation
(``harv_jax.evaluation.closed_loop``), with the same code and the same draws:

- sensor noise: additive white Gaussian noise, std ``noise_std`` [8], on the 8 measured states
  [V, alpha, beta, p, q, r, mu, gamma];
- command delay: the plant receives the command of ``delay_steps`` steps ago (a FIFO of past commands);
- gust: a first-order Gauss-Markov (Ornstein-Uhlenbeck) wind per body axis, std ``gust_std_fps``,
  correlation time ``gust_tau_s``.

The gust is the first-order approximation of the Dryden spectrum, stepped exactly:
g_{k+1} = a g_k + std sqrt(1 - a^2) n_k, a = exp(-dt / tau), n_k ~ N(0, I); it starts in its stationary
distribution. Being defined in body axes, it turns with the aircraft (a simplification). An actuator lag
is part of the aircraft (``AircraftParams.act_tau_s``, ``dynamics.actuators``).

Order within one step k (env and closed loop alike): the controller sees x_k plus noise n_k; its command
enters the FIFO; the plant flies the command ``delay_steps`` old with the gust g_k; then one draw of
``NUM_STEP_NORMALS`` normals gives g_{k+1} and n_{k+1}.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.aircraft.randomize import uniform16
from harv_jax.dynamics.disturbance_model import Models
from harv_jax.dynamics.turbulence import TurbulenceParams

#: The training env's default maxima (``env.config.default_randomization_params``; the env draws each
#: episode's levels below them), and so the Monte Carlo's default levels.
#: Sensor-noise std per measured state [V, alpha, beta, p, q, r, mu, gamma] (ft/s, rad, rad/s).
DEFAULT_NOISE_STD_MAX = np.array([2.0, 0.005, 0.005, 0.01, 0.01, 0.01, 0.01, 0.005])
#: Stationary gust std per body axis, ft/s.
DEFAULT_GUST_STD_MAX_FPS = 10.0
#: Range of the gust correlation time, s (min, max): tau = L / V with the Dryden length L = 1750 ft above
#: 2000 ft (MIL-HDBK-1797) spans 1.2-17 s over V = 100-1500 ft/s.
DEFAULT_GUST_TAU_S = (1.0, 10.0)
#: Command delay, plant steps (20 ms at 0.01 s).
DEFAULT_DELAY_MAX_STEPS = 2

#: Number of measured states (the first entries of the wind state) that carry sensor noise.
NUM_NOISY_STATES = 8
#: N(0, 1) draws per step: gust 3, sensor noise 8.
NUM_STEP_NORMALS = 3 + NUM_NOISY_STATES
#: U(0, 1) draws behind one step's normals (Box-Muller works in pairs).
NUM_NORMAL_UNIFORMS = 2 * ((NUM_STEP_NORMALS + 1) // 2)


@struct.dataclass
class DisturbanceParams:
    """The disturbance levels of one run or episode (traced; batch them over runs).

    Attributes:
        noise_std: [8] sensor-noise std of [V, alpha, beta, p, q, r, mu, gamma] (ft/s, rad, rad/s).
        delay_steps: int32 command delay, plant steps.
        gust_std_fps: stationary gust std per body axis, ft/s (0 = no gust).
        gust_tau_s: gust correlation time, s.
        turbulence: Dryden turbulence (``dynamics.turbulence``), or None (none: the loop has no
            turbulence state and draws nothing for it).
        added_levels: name -> level of each disturbance added to the table (``dynamics.disturbance_model``).
        added_models: name -> model of those (static; empty: none added).
    """

    noise_std: jnp.ndarray
    delay_steps: jnp.ndarray
    gust_std_fps: jnp.ndarray
    gust_tau_s: jnp.ndarray
    turbulence: TurbulenceParams | None = None
    added_levels: dict[str, jnp.ndarray] = struct.field(default_factory=dict)
    added_models: Models = struct.field(pytree_node=False, default=())


def normals_from_uniform(u01: jnp.ndarray) -> jnp.ndarray:
    """[2m] independent N(0, 1) draws from [2m] U(0, 1) draws (Box-Muller).

    Lets one PRNG call per step serve every disturbance; u in [0, 1) is mapped to 1 - u in (0, 1] so that
    the logarithm stays finite. With ``uniform16`` draws the radius is at most
    sqrt(-2 ln(0.5 / 65536)) = 4.85, i.e. the normal tails are cut at 4.85 std (probability 1.2e-6).
    """
    m = u01.shape[-1] // 2
    radius = jnp.sqrt(-2.0 * jnp.log1p(-u01[..., :m]))
    angle = (2.0 * jnp.pi) * u01[..., m : 2 * m]
    return jnp.concatenate([radius * jnp.cos(angle), radius * jnp.sin(angle)], axis=-1)


def step_normals(key: jax.Array, dtype=None) -> jnp.ndarray:
    """[NUM_NORMAL_UNIFORMS] N(0, 1) draws of one step from one PRNG call (gust [:3], noise [3:11])."""
    return normals_from_uniform(uniform16(key, NUM_NORMAL_UNIFORMS, dtype))


def gust_init(normal3: jnp.ndarray, gust_std_fps: jnp.ndarray) -> jnp.ndarray:
    """[3] initial body-axis gust, ft/s, from the stationary distribution, given [3] N(0, 1) draws."""
    return gust_std_fps * normal3


def gust_step(
    gust_fps: jnp.ndarray,
    gust_std_fps: jnp.ndarray,
    gust_tau_s: jnp.ndarray,
    dt_s: float | jnp.ndarray,
    normal3: jnp.ndarray,
) -> jnp.ndarray:
    """Advance the [3] body-axis gust by dt_s (exact discretization; the stationary std is kept)."""
    a = jnp.exp(-dt_s / gust_tau_s)
    return a * gust_fps + gust_std_fps * jnp.sqrt(1.0 - a * a) * normal3


def sensor_noise(normal8: jnp.ndarray, noise_std: jnp.ndarray) -> jnp.ndarray:
    """[8] additive sensor noise of the measured states from [8] N(0, 1) draws."""
    return noise_std * normal8


def measured(x_wind: jnp.ndarray, noise8: jnp.ndarray) -> jnp.ndarray:
    """The wind state [10] as the sensors report it: ``noise8`` added to the first 8 components."""
    return x_wind.at[:NUM_NOISY_STATES].add(noise8.astype(x_wind.dtype))


def push_command(buffer_rad: jnp.ndarray, cmd_rad: jnp.ndarray) -> jnp.ndarray:
    """The command FIFO [D + 1, 3] (newest first) after ``cmd_rad`` [3] enters it."""
    return jnp.concatenate([cmd_rad[None], buffer_rad[:-1]], axis=0)


def delayed_command(buffer_rad: jnp.ndarray, delay_steps: jnp.ndarray) -> jnp.ndarray:
    """The command the plant flies: the FIFO's entry ``delay_steps`` old (0 = the newest)."""
    return buffer_rad[delay_steps]
