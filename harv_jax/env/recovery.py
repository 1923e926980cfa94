"""Spin/upset recovery environment: pure functional, gymnax-style, vmappable, ``lax.scan`` friendly.

    env = make_env(EnvConfig())
    params = default_params(env.config)
    obs, state = env.reset(key, params)
    obs, state, reward, done, info = env.step(key, state, action, params)

Observation [11] (physical units, from ``to_wind`` of the true state, plus sensor noise when enabled):
[V ft/s, alpha, beta, p, q, r, mu, gamma, alpha_d, beta_d, mu_d] (rad, rad/s). With turbulence
(``EnvConfig.turbulence``) the state is taken relative to the air mass (the air data, as the Monte Carlo
measures and scores it) for the observation, the reward and the terminations alike. NaNs are replaced by 0
and every component is clipped to the paper's observation box (``task.spaces.OBS_LOW``/``OBS_HIGH``); inside
the envelope the clip only touches noise at the edges. Action [3] in [-1, 1] (clipped), mapped affinely to
[u_min, u_max] per channel (de, da, dr); the actuator model adds rate limits (and the delay).

One step: ``dynamics.disturbed_step.disturbed_plant_step`` (the Monte Carlo's step: command FIFO ->
actuator -> RK4 in the gust and turbulence -> the next gust, noise and turbulence from the step's key)
-> terminations, reward terms, observation. Reward: see ``harv_jax.env.reward``.

Terminations (``done`` and ``info['terminated']``; reward = terminal_reward - sigma_t): see
``harv_jax.env.termination``. The time limit ``episode_steps`` is a truncation (``done`` and
``info['truncation']``, never both flags): bootstrap from ``info['final_obs']``.

Auto-reset (``step``): when ``done``, the returned ``obs`` and ``state`` are the *new* episode's first
observation and state (fresh draws of initial state, target and episode parameters);
``info['final_obs']`` is the observation of the state the finished episode reached (the one to bootstrap
a truncation from), ``info['final_state_wind']`` its wind-axis state [10]. When not done they equal
``obs`` and the new state's wind-axis state. ``step_no_reset`` is the same step without the reset (for
adapters that reset themselves).

``info`` (fixed structure, scan-friendly): ``reward_terms`` (every term of ``reward.RewardTerms``),
``termination`` (the causes, ``TerminationFlags``), ``terminated``, ``truncation``, ``episode_step``,
and from ``step`` also ``final_obs`` and ``final_state_wind``.

Potential across a reset: the shaping of the last step of an episode is Gamma * 0 - sigma_t on a
termination (absorbing state) and Gamma sigma(s_T) - sigma_t on a truncation (s_T is an ordinary state
that the learner bootstraps from); the new episode's state carries sigma of its own initial state, so
no shaping term spans two episodes. See ``harv_jax.env.reward``.

Retraces: pass strongly typed arrays (e.g. ``jnp.full((n, 3), 0.2, jnp.float32)``, not a weakly typed
``jnp.full((n, 3), 0.2)``); parameters from ``default_params`` are strongly typed.

Reset: with probability ``spin_reset_prob`` one of ``spin_states`` (uniform index) plus a uniform
perturbation, else a uniform draw over the paper's reset bounds at altitude ``h0_ft`` (chi = 0). Target
alpha_d ~ U(alpha_d_low, alpha_d_high), beta_d, mu_d fixed. Deflections and the delay buffer start at 0
rad (neutral surfaces; a spin reset starts at that spin state's deflections), the gust and the turbulence
in their stationary distributions.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.aero import wrap_angle_rad
from harv_jax.dynamics import BodyState, disturbance_model, from_wind, is_finite
from harv_jax.dynamics.disturbed_step import (
    AirData,
    DisturbanceState,
    air_data,
    body_wind_fps,
    disturbance_init,
    disturbed_plant_step,
    initial_heading,
)
from harv_jax.dynamics.state import WIND_INDEX, h_ft, omega_radps, vt_fps
from harv_jax.env import randomize, reward
from harv_jax.env.auto_reset import with_auto_reset
from harv_jax.env.config import EnvConfig, EnvParams, default_params
from harv_jax.env.randomize import EpisodeParams
from harv_jax.env.termination import termination_flags
from harv_jax.task.criteria import tracking_errors
from harv_jax.task.spaces import (
    ACTION_SIZE,
    NUM_MEASURED,
    OBSERVATION_SIZE,
    action_to_command,
    clean_observation,
    finish_observation,
)
from harv_jax.task.turbulent_criterion import TurbulentCriterion, filter_step, inside_bands, margins

_MU, _CHI = WIND_INDEX["mu"], WIND_INDEX["chi"]
#: Uniform draws of a reset's initial state: the 8 reset-bound components, the spin index (1), the spin
#: perturbation (10 = the wind state) and the spin choice (1).
_N_RESET_STATE = 8
_U_SPIN_INDEX = _N_RESET_STATE
_U_SPIN_PERTURB = slice(_U_SPIN_INDEX + 1, _U_SPIN_INDEX + 1 + 10)
_U_SPIN_CHOICE = _U_SPIN_PERTURB.stop


def _criterion_sample(x_wind: jnp.ndarray, target_rad: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """(tracking errors [3], body rates [3]) of a state: what the criterion in turbulence filters."""
    return tracking_errors(x_wind, target_rad), omega_radps(x_wind)


def _wrap_angles(x_wind: jnp.ndarray) -> jnp.ndarray:
    """mu and chi of a wind-axis state [10] wrapped to (-pi, pi]."""
    return x_wind.at[_MU].set(wrap_angle_rad(x_wind[_MU])).at[_CHI].set(wrap_angle_rad(x_wind[_CHI]))


observation_size = OBSERVATION_SIZE
action_size = ACTION_SIZE


@struct.dataclass
class EnvState:
    """Per-env state (one episode in flight).

    Attributes:
        aircraft: singularity-free integration state.
        wind: [10] wind-axis state of ``aircraft`` (cached: computed once per step); with turbulence
            relative to the air mass (the air data).
        delta_rad: [3] actual surface deflections [de, da, dr], rad.
        disturbance: the command FIFO, gust, sensor noise and turbulence (``dynamics.disturbed_step``).
        target_rad: [3] [alpha_d, beta_d, mu_d], rad.
        step: int32 steps taken in this episode.
        potential: PBRS potential sigma of the current state.
        episode: this episode's randomized parameters.
        criterion_filter: [6] with turbulence, the criterion in turbulence's low-passed errors and body
            rates (``task.turbulent_criterion.filter_step``) for the recovered reward; None without.
    """

    aircraft: BodyState
    wind: jnp.ndarray
    delta_rad: jnp.ndarray
    disturbance: DisturbanceState
    target_rad: jnp.ndarray
    step: jnp.ndarray
    potential: jnp.ndarray
    episode: EpisodeParams
    criterion_filter: jnp.ndarray | None = None


class Env(NamedTuple):
    """A pure environment: ``reset(key, params)``, ``step(key, state, action, params)``.

    Attributes:
        config: the static config it was built with.
        reset: (key, EnvParams) -> (obs [11], EnvState).
        step: (key, EnvState, action [3], EnvParams) -> (obs, state, reward, done, info), auto-reset.
        step_no_reset: (key, state, action, params) -> (obs, state, reward, terminated, truncated, info).
        default_params: () -> EnvParams for this config.
        reset_to: (key, x_wind [10], target [3], params) -> (obs, EnvState): start at a given state.
        batch_step: (keys [N], states, actions [N, 3], params) -> vmap(step) outputs, with the resets
            computed only on steps where some env is done (faster for long episodes).
        observation_size: 11.
        action_size: 3.
    """

    config: EnvConfig
    reset: Callable[..., tuple[jnp.ndarray, EnvState]]
    step: Callable[..., tuple[jnp.ndarray, EnvState, jnp.ndarray, jnp.ndarray, dict[str, Any]]]
    step_no_reset: Callable[..., tuple]
    default_params: Callable[[], EnvParams]
    reset_to: Callable[..., tuple[jnp.ndarray, EnvState]]
    batch_step: Callable[..., tuple[jnp.ndarray, EnvState, jnp.ndarray, jnp.ndarray, dict[str, Any]]]
    observation_size: int = OBSERVATION_SIZE
    action_size: int = ACTION_SIZE


def make_env(config: EnvConfig | None = None) -> Env:
    """Build the pure reset/step functions for a static config.

    Args:
        config: static configuration (default ``EnvConfig()``).

    Returns:
        Env with pure ``reset``/``step``/``step_no_reset`` closures (jit/vmap/scan them).
    """
    config = config or EnvConfig()
    dt_s = config.dt_s

    dr = config.domain_randomization
    # Uniform draws consumed per reset: initial state (8), spin index (1), spin perturbation (10), spin
    # choice (1), alpha_d (1); with randomization also the episode parameters and the normals (gust 3,
    # noise 8, via Box-Muller in pairs). Per step (randomization only): the step normals.
    # ``reset`` and ``step_no_reset`` make one PRNG draw each (``step`` adds one split): every PRNG call
    # site compiles its own hash (compile time), and with jax's partitionable threefry every drawn
    # element costs a hash block (run time; hence the 16-bit pairs of ``randomize.uniform16``).
    n_init_u = _U_SPIN_CHOICE + 1 + 1
    n_normal_u = 2 * ((randomize.NUM_STEP_NORMALS + 1) // 2)
    n_reset_u = n_init_u + ((randomize.NUM_EPISODE_UNIFORMS + n_normal_u) if dr else 0)
    turbulence = config.turbulence

    def _initial_wind(u01: jnp.ndarray, params: EnvParams) -> tuple[jnp.ndarray, jnp.ndarray]:
        """Initial wind-axis state [10] and deflections [3] from ``n_init_u - 1`` U(0, 1) draws."""
        rp = params.reset
        x_uniform = jnp.concatenate(
            [rp.low + (rp.high - rp.low) * u01[:_N_RESET_STATE], 0.0 * u01[:1], params.h0_ft[None]]
        )  # chi = 0, h = h0
        n_spin = params.spin_states.shape[0]
        idx = jnp.minimum(jnp.floor(u01[_U_SPIN_INDEX] * n_spin).astype(jnp.int32), n_spin - 1)
        x_spin = params.spin_states[idx] + params.spin_perturb * (2.0 * u01[_U_SPIN_PERTURB] - 1.0)
        use_spin = u01[_U_SPIN_CHOICE] < params.spin_reset_prob
        x0 = jnp.where(use_spin, x_spin, x_uniform)
        delta0 = jnp.where(use_spin, params.spin_delta_rad[idx], jnp.zeros_like(params.spin_delta_rad[idx]))
        # canonical angles so that the observation equals to_wind(from_wind(x0))
        return _wrap_angles(x0), delta0

    def _observe(dist: DisturbanceState, x_wind: jnp.ndarray, target_rad: jnp.ndarray, ep: EpisodeParams):
        # as ``disturbed_step.measured``: the noise, then the disturbances added to the table
        if dist.noise_normals is not None:
            x_wind = x_wind.at[:NUM_MEASURED].add(randomize.sensor_noise(dist.noise_normals, ep))
        x_wind = disturbance_model.measure(ep.added_models, x_wind, dist.added, ep.added_levels)
        return finish_observation(clean_observation(x_wind, target_rad))

    def _uniform(key: jax.Array, n: int, params: EnvParams) -> jnp.ndarray:
        dtype = params.reset.low.dtype
        return randomize.uniform16(key, n, dtype) if n else jnp.zeros((0,), dtype)

    def _reset_from_uniform(
        u01: jnp.ndarray,
        key: jax.Array,
        params: EnvParams,
        x0: jnp.ndarray | None = None,
        target: jnp.ndarray | None = None,
    ) -> tuple[jnp.ndarray, EnvState]:
        dtype = u01.dtype
        delta0 = jnp.zeros((3,), dtype=dtype)
        if x0 is None:
            x0, delta0 = _initial_wind(u01[: n_init_u - 1], params)
        else:
            x0 = jnp.asarray(x0, dtype=dtype)
            x0 = _wrap_angles(x0)
        if target is None:
            rp = params.reset
            alpha_d = rp.alpha_d_low_rad + (rp.alpha_d_high_rad - rp.alpha_d_low_rad) * u01[n_init_u - 1]
            target = jnp.stack([alpha_d, rp.beta_d_rad, rp.mu_d_rad])
        else:
            target = jnp.asarray(target, dtype=dtype)
        if dr:
            n_ep = randomize.NUM_EPISODE_UNIFORMS
            ep = randomize.episode_from_uniform(
                u01[n_init_u : n_init_u + n_ep], params.aircraft, params.randomization, config.max_delay_steps
            )
            extra_key = jax.random.fold_in(key, randomize.EXTRA_KEY_TAG)
            extra_u = randomize.uniform16(extra_key, randomize.NUM_EXTRA_UNIFORMS, dtype)
            ep = randomize.extra_from_uniform(extra_u, ep, params.randomization, turbulence)
            added_key = jax.random.fold_in(key, randomize.ADDED_KEY_TAG)
            ep = randomize.added_from_key(added_key, ep, params.randomization)
            normals = randomize.normals_from_uniform(u01[n_init_u + n_ep :])
        else:
            ep = randomize.nominal_episode(params.aircraft, params.randomization)
            normals = None
        body0 = from_wind(x0)
        x0_air = x0
        dist = disturbance_init(
            normals, ep.levels, delta0, initial_heading(body0), config.max_delay_steps, key
        )
        if turbulence:  # the env sees the air data: relative to the gust and the turbulence
            x0_air = air_data(body0, dist, ep.levels).x_wind
        obs = _observe(dist, x0_air, target, ep)
        state = EnvState(
            aircraft=body0,
            wind=x0_air,
            delta_rad=delta0,
            disturbance=dist,
            target_rad=target,
            step=jnp.zeros((), dtype=jnp.int32),
            potential=reward.state_potential(x0_air, target, params.reward),
            episode=ep,
            criterion_filter=jnp.concatenate(_criterion_sample(x0_air, target)) if turbulence else None,
        )
        return obs, state

    def reset(key: jax.Array, params: EnvParams) -> tuple[jnp.ndarray, EnvState]:
        """Start an episode: (obs [11], EnvState)."""
        return _reset_from_uniform(_uniform(key, n_reset_u, params), key, params)

    def reset_to(
        key: jax.Array, x_wind: jnp.ndarray, target_rad: jnp.ndarray, params: EnvParams
    ) -> tuple[jnp.ndarray, EnvState]:
        """Start an episode at a given wind-axis state [10] and target [3] (alpha_d, beta_d, mu_d, rad).

        Everything else (episode parameters, gust, noise) is drawn as in ``reset``; mu and chi are
        wrapped to (-pi, pi]. For evaluation from fixed initial conditions.
        """
        return _reset_from_uniform(_uniform(key, n_reset_u, params), key, params, x_wind, target_rad)

    def _step(key: jax.Array, state: EnvState, action: jnp.ndarray, params: EnvParams):
        ep = state.episode
        ac = ep.aircraft
        levels = ep.levels
        a = jnp.clip(action, -1.0, 1.0)
        cmd = action_to_command(a, ac.u_min_rad, ac.u_max_rad)
        dist = state.disturbance
        if turbulence:
            air = air_data(state.aircraft, dist, levels)
        else:  # the paper's env: the aircraft flies the gust, the env sees the inertial state
            air = AirData(state.wind, body_wind_fps(dist, levels), None)
        ps, dist = disturbed_plant_step(
            state.aircraft, state.delta_rad, dist, cmd, air, ac, levels, dt_s, key if dr else None
        )
        body, delta, x = ps
        if turbulence:
            x = air_data(body, dist, levels).x_wind
        finite = is_finite(body) & jnp.all(jnp.isfinite(x))
        flags = termination_flags(x, finite, params.envelope)
        terminated = flags.any
        t = state.step + 1
        truncated = (t >= config.episode_steps) & ~terminated
        filtered, inside = None, None
        if turbulence:  # the recovered reward judged as the Monte Carlo judges a run in turbulence
            crit = TurbulentCriterion(ep.turbulence)
            filtered = filter_step(
                state.criterion_filter, *_criterion_sample(x, state.target_rad), crit, dt_s
            )
            margin = margins(crit, h_ft(x), vt_fps(x)).astype(x.dtype)
            inside = inside_bands(filtered, params.reward.recovered_tol, margin)
        terms, pot_next = reward.reward_terms(
            x, state.target_rad, a, state.potential, terminated, params.reward, inside
        )
        obs = _observe(dist, x, state.target_rad, ep)
        new_state = state.replace(
            aircraft=body,
            wind=x,
            delta_rad=delta,
            disturbance=dist,
            criterion_filter=filtered,
            step=t,
            potential=pot_next,
        )
        info = {
            "reward_terms": terms._asdict(),
            "termination": flags._asdict(),
            "terminated": terminated,
            "truncation": truncated,
            "episode_step": t,
        }
        return obs, new_state, terms.total, terminated, truncated, info

    def step_no_reset(key: jax.Array, state: EnvState, action: jnp.ndarray, params: EnvParams):
        """One step without auto-reset.

        Returns:
            (obs [11], state, reward, terminated, truncated, info). On termination the returned state
            is the (possibly non-finite) state that left the envelope.
        """
        return _step(key, state, action, params)

    step = with_auto_reset(step_no_reset, reset)

    def batch_step(keys: jax.Array, states: EnvState, actions: jnp.ndarray, params: EnvParams):
        """``vmap(step)`` over a batch, computing the resets only when some env of the batch is done.

        Same outputs as ``jax.vmap(step, in_axes=(0, 0, 0, None))`` for the same keys. Under ``vmap``
        every env pays for a reset at every step (the auto-reset is a select); here the resets sit in a
        ``lax.cond`` on ``any(done)``, so steps on which no episode ends skip them. (Nested in a further
        ``vmap`` the cond becomes a select again: still correct, no saving.)

        Args:
            keys: [N] PRNG keys.
            states: EnvState batched over N.
            actions: [N, 3] normalized actions.
            params: EnvParams shared by the batch (unbatched).
        """
        split = jax.vmap(jax.random.split)(keys)
        k_step, k_reset = split[:, 0], split[:, 1]
        del keys, split
        obs, new_states, rew, terminated, truncated, info = jax.vmap(step_no_reset, in_axes=(0, 0, 0, None))(
            k_step, states, actions, params
        )
        done = terminated | truncated
        info["final_obs"] = obs
        info["final_state_wind"] = new_states.wind

        def with_resets(_):
            obs_reset, states_reset = jax.vmap(reset, in_axes=(0, None))(k_reset, params)

            def pick(r, s):
                return jnp.where(done.reshape(done.shape + (1,) * (s.ndim - 1)), r, s)

            return pick(obs_reset, obs), jax.tree.map(pick, states_reset, new_states)

        obs_out, states_out = jax.lax.cond(jnp.any(done), with_resets, lambda _: (obs, new_states), None)
        return obs_out, states_out, rew, done, info

    return Env(
        config=config,
        reset=reset,
        step=step,
        step_no_reset=step_no_reset,
        default_params=lambda: default_params(config),
        reset_to=reset_to,
        batch_step=batch_step,
        observation_size=OBSERVATION_SIZE,
    )
