"""Configuration of the recovery environment: a frozen static part and traced parameter pytrees.

Static (``EnvConfig``, closed over by ``make_env``; changing it recompiles): step size, episode length,
delay-buffer size, the master domain-randomization switch, and the *defaults* of a few traced values.

Traced (``EnvParams`` and its parts, passed to ``reset``/``step``; changing them does not recompile):
reward weights (``RewardParams``), randomization ranges and switches (``RandomizationParams``),
reset bounds (``ResetParams``), the flight envelope (``task.criteria.Envelope``), the initial altitude,
and the spin-entry reset states. The paper's numbers come from ``harv_jax.task.spec``.

Sources: paper Section IV-A (reward, weights, terminal reward) and its Tables (observation/action ranges,
reset bounds); docs/model.md ("Envelope and reset bounds").
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.aircraft.params import DEFAULT_THROTTLE, AircraftParams
from harv_jax.aircraft.randomize import AircraftRandomization, default_aircraft_randomization
from harv_jax.aircraft.registry import DEFAULT_AIRCRAFT, check_aircraft_name, get_aircraft
from harv_jax.dynamics.disturbances import (
    DEFAULT_DELAY_MAX_STEPS,
    DEFAULT_GUST_STD_MAX_FPS,
    DEFAULT_GUST_TAU_S,
    DEFAULT_NOISE_STD_MAX,
)
from harv_jax.dynamics.turbulence import POE_ALTITUDES_FT
from harv_jax.env.reward_params import RewardParams, paper_reward_params
from harv_jax.task.criteria import Envelope, default_envelope
from harv_jax.task.scenarios import RESET_HIGH, RESET_LOW
from harv_jax.task.spec import (
    ALPHA_TARGET_BOUNDS_RAD,
    BETA_TARGET_RAD,
    DT_S,
    H0_FT,
    H_FLOOR_FT,
    MU_TARGET_RAD,
)
from harv_jax.units import RAD_PER_DEG

#: Placeholder spin-entry state (wind axes [10]): level trim at 400 ft/s, 25,000 ft (docs/model.md trim table,
#: alpha = 11.1793 deg). Replaced by real spin-entry states from ``harv_jax.task.spin_bank`` by the caller.
PLACEHOLDER_SPIN_STATE = np.array([400.0, 11.1793 * RAD_PER_DEG, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, H0_FT])
#: Default half-widths of the uniform perturbation added to a spin-entry state, same order and units
#: as the wind-axis state: V 10 ft/s; alpha, beta 0.02 rad; p, q, r 0.05 rad/s; mu, gamma 0.02 rad;
#: chi and h unperturbed.
DEFAULT_SPIN_PERTURB = np.array([10.0, 0.02, 0.02, 0.05, 0.05, 0.05, 0.02, 0.02, 0.0, 0.0])


@dataclasses.dataclass(frozen=True)
class EnvConfig:
    """Static configuration (sets shapes, loop lengths and which code is traced).

    Attributes:
        dt_s: control and integration step, s (paper: 0.01).
        episode_steps: time limit in steps, a truncation (paper: 20,000 steps = 200 s).
        max_delay_steps: size of the actuator-command delay buffer minus one; the per-episode delay is
            drawn in 0..min(RandomizationParams.delay_max_steps, max_delay_steps).
        domain_randomization: master switch. False traces none of the randomization code (nominal
            aircraft, no gust, no noise, no delay) whatever ``RandomizationParams`` says.
        turbulence: trace the Dryden turbulence (with ``domain_randomization``): the env then flies it
            and observes, rewards and terminates on the air data (the state relative to the air mass, as
            the Monte Carlo scores it). Off, the env sees the inertial state (the paper's env, whose gust
            the aircraft flies but the observation does not see). The settings set it from the
            ``[randomization]`` table's ``turbulence``; it is not an ``[env]`` key.
        throttle: fixed throttle of the nominal aircraft in [0, 1].
        aircraft: name of the nominal aircraft (``harv_jax.aircraft.registry``; default ``"harv"``).
        h0_ft: default initial altitude, ft (copied into ``EnvParams.h0_ft``).
        h_floor_ft: default altitude floor, ft (copied into ``EnvParams.envelope.h_floor_ft``).
        discount: default PBRS discount Gamma (= the PPO discount; paper 0.99).
    """

    dt_s: float = DT_S
    episode_steps: int = 20_000
    max_delay_steps: int = 3
    domain_randomization: bool = True
    throttle: float = DEFAULT_THROTTLE
    h0_ft: float = H0_FT
    h_floor_ft: float = H_FLOOR_FT
    discount: float = 0.99
    aircraft: str = DEFAULT_AIRCRAFT
    turbulence: bool = False

    def __post_init__(self) -> None:
        if not self.dt_s > 0:
            raise ValueError(f"dt_s={self.dt_s!r} must be > 0")
        if self.episode_steps < 1:
            raise ValueError(f"episode_steps={self.episode_steps!r} must be >= 1")
        if self.max_delay_steps < 0:
            raise ValueError(f"max_delay_steps={self.max_delay_steps!r} must be >= 0")
        if not 0.0 < self.discount <= 1.0:
            raise ValueError(f"discount={self.discount!r} must be in (0, 1]")
        check_aircraft_name(self.aircraft)
        if self.turbulence and not self.domain_randomization:
            raise ValueError("turbulence needs domain_randomization")


@struct.dataclass
class RandomizationParams(AircraftRandomization):
    """Domain-randomization switches and ranges, resampled every episode. All traced.

    Each ``*_on`` is a bool switch; a switched-off item takes its nominal value. Ranges are half-widths
    of uniform draws of multiplicative factors ``1 + frac * U(-1, 1)`` unless stated.

    The aircraft draws' fields come first, inherited from ``aircraft.randomize.AircraftRandomization`` (with
    its defaults): this pytree is one wherever that one is asked for. The env's own:

    Attributes:
        gust_on: body-axis Ornstein-Uhlenbeck gust.
        gust_std_max_fps: per-episode stationary gust std per axis ~ U(0, this), ft/s (default 10).
        gust_tau_min_s, gust_tau_max_s: per-episode gust correlation time ~ U(min, max), s (default
            1-10 s: tau = L/V with the Dryden length L = 1750 ft above 2000 ft, MIL-HDBK-1797, spans
            1.2-17 s over V = 100-1500 ft/s).
        noise_on: additive white Gaussian sensor noise on the 8 measured observations.
        noise_std_max: [8] per-channel noise std; the per-episode std is U(0, 1) times this
            (default V 2 ft/s; alpha, beta 0.005 rad; p, q, r 0.01 rad/s; mu 0.01 rad; gamma 0.005 rad).
        delay_on: actuator command delay.
        delay_max_steps: per-episode delay ~ randint(0, delay_max_steps) steps inclusive (default 2 =
            up to 20 ms at dt 0.01 s), capped at ``EnvConfig.max_delay_steps``.
        lag_max_s: per-episode first-order actuator lag ~ U(0, this), s (default 0: none).
        turbulence_sigma_table_fps: [12] the Dryden turbulence's largest sigma at each altitude of
            ``dynamics.turbulence.POE_ALTITUDES_FT`` (the preset's ``turbulence``: a named intensity or a
            sigma); each episode flies U(0, 1) times it (default 0: none). Only flown when
            ``EnvConfig.turbulence`` is on.
        turbulence_wind_20ft_fps: the same for the low-altitude model's wind at 20 ft, ft/s.
        added_max: name -> per-episode maximum of each disturbance added to the table (its
            ``[randomization]`` key; ``dynamics.disturbance_model``); each episode flies U(0, 1) times it
            (default: none).
    """

    gust_on: jnp.ndarray
    gust_std_max_fps: jnp.ndarray
    gust_tau_min_s: jnp.ndarray
    gust_tau_max_s: jnp.ndarray
    noise_on: jnp.ndarray
    noise_std_max: jnp.ndarray
    delay_on: jnp.ndarray
    delay_max_steps: jnp.ndarray
    lag_max_s: jnp.ndarray
    turbulence_sigma_table_fps: jnp.ndarray
    turbulence_wind_20ft_fps: jnp.ndarray
    added_max: dict[str, jnp.ndarray] = struct.field(default_factory=dict)


def default_randomization_params(enabled: bool = True, dtype=None) -> RandomizationParams:
    """Documented default ranges (the aircraft's: ``aircraft.randomize``); ``enabled`` sets all switches."""
    dtype = dtype or jnp.result_type(float)

    def f(v):
        return jnp.asarray(v, dtype=dtype)

    on = jnp.asarray(enabled, dtype=bool)
    ac = default_aircraft_randomization(enabled, dtype)
    return RandomizationParams(
        **{k.name: getattr(ac, k.name) for k in dataclasses.fields(ac)},
        gust_on=on,
        gust_std_max_fps=f(DEFAULT_GUST_STD_MAX_FPS),
        gust_tau_min_s=f(DEFAULT_GUST_TAU_S[0]),
        gust_tau_max_s=f(DEFAULT_GUST_TAU_S[1]),
        noise_on=on,
        noise_std_max=f(DEFAULT_NOISE_STD_MAX),
        delay_on=on,
        delay_max_steps=jnp.asarray(DEFAULT_DELAY_MAX_STEPS, dtype=jnp.int32),
        lag_max_s=f(0.0),
        turbulence_sigma_table_fps=f(np.zeros(POE_ALTITUDES_FT.shape)),
        turbulence_wind_20ft_fps=f(0.0),
    )


@struct.dataclass
class ResetParams:
    """Uniform reset bounds (paper Table "Bounds for random initialization"). Traced.

    Attributes:
        low, high: [8] bounds of [V ft/s, alpha, beta, p, q, r, mu, gamma] (rad, rad/s).
        alpha_d_low_rad, alpha_d_high_rad: target angle-of-attack range, rad (paper -0.085..0.68).
        beta_d_rad, mu_d_rad: fixed sideslip and bank targets, rad (paper 0).
    """

    low: jnp.ndarray
    high: jnp.ndarray
    alpha_d_low_rad: jnp.ndarray
    alpha_d_high_rad: jnp.ndarray
    beta_d_rad: jnp.ndarray
    mu_d_rad: jnp.ndarray


def paper_reset_params(dtype=None) -> ResetParams:
    """The paper's reset bounds."""

    def f(v):
        return jnp.asarray(v, dtype=dtype or jnp.result_type(float))

    return ResetParams(
        low=f(RESET_LOW),
        high=f(RESET_HIGH),
        alpha_d_low_rad=f(ALPHA_TARGET_BOUNDS_RAD[0]),
        alpha_d_high_rad=f(ALPHA_TARGET_BOUNDS_RAD[1]),
        beta_d_rad=f(BETA_TARGET_RAD),
        mu_d_rad=f(MU_TARGET_RAD),
    )


@struct.dataclass
class EnvParams:
    """Everything traced that ``reset``/``step`` read (vmap or sweep it without recompiling).

    Attributes:
        aircraft: nominal aircraft; per-episode draws are made around it.
        reward: reward weights.
        randomization: domain-randomization switches and ranges.
        reset: uniform reset bounds.
        envelope: termination envelope.
        h0_ft: initial altitude of uniform resets, ft.
        spin_states: [K, 10] wind-axis spin-entry states (their own h is used).
        spin_delta_rad: [K, 3] surface deflections of each spin state (the pro-spin controls of a developed
            spin; an episode that starts from ``spin_states[k]`` starts with these deflections).
        spin_reset_prob: probability that a reset starts from a spin-entry state (default 0).
        spin_perturb: [10] half-widths of the uniform perturbation of a spin-entry state.
    """

    aircraft: AircraftParams
    reward: RewardParams
    randomization: RandomizationParams
    reset: ResetParams
    envelope: Envelope
    h0_ft: jnp.ndarray
    spin_states: jnp.ndarray
    spin_delta_rad: jnp.ndarray
    spin_reset_prob: jnp.ndarray
    spin_perturb: jnp.ndarray


def strip_weak_type(tree):
    """Make every leaf a strongly typed array (avoids retraces and scan-carry dtype mismatches)."""

    def f(leaf):
        leaf = jnp.asarray(leaf)
        return leaf.astype(leaf.dtype)

    return jax.tree.map(f, tree)


def default_params(config: EnvConfig | None = None, dtype=None) -> EnvParams:
    """Default traced parameters: the paper's reward, reset bounds and envelope; documented ranges.

    Args:
        config: static config whose ``aircraft``, ``throttle``, ``h0_ft``, ``h_floor_ft`` and ``discount``
            seed the traced values (default ``EnvConfig()``).
        dtype: float dtype (default: jax's default float).

    Returns:
        EnvParams with strongly typed leaves.
    """
    config = config or EnvConfig()
    dtype = dtype or jnp.result_type(float)

    def f(v):
        return jnp.asarray(v, dtype=dtype)

    spin = PLACEHOLDER_SPIN_STATE.copy()
    spin[9] = config.h0_ft
    params = EnvParams(
        aircraft=get_aircraft(config.aircraft, throttle=config.throttle, dtype=dtype),
        reward=paper_reward_params(config.discount, dtype),
        randomization=default_randomization_params(True, dtype),
        reset=paper_reset_params(dtype),
        envelope=default_envelope(config.h_floor_ft, dtype),
        h0_ft=f(config.h0_ft),
        spin_states=f(spin[None, :]),
        spin_delta_rad=f(np.zeros((1, 3))),
        spin_reset_prob=f(0.0),
        spin_perturb=f(DEFAULT_SPIN_PERTURB),
    )
    return strip_weak_type(params)
