"""In a disturbed world the env flies the Monte Carlo's trajectories step for step.

The env with turbulence (``EnvConfig.turbulence``) set to a Monte Carlo run's conditions (its initial
state, aircraft, disturbance levels: noise, delay, actuator lag and moderate turbulence; its initial
disturbance state and its per-step disturbance keys) and flown with the SMC on the env's own measurement
(the air data plus the noise it carries) follows the closed loop's air-relative states to float rounding,
and the env's wind-axis state is the Monte Carlo's scored state. Both call
``dynamics.disturbed_step.disturbed_plant_step``; ``experiments/turbulence/env_vs_mc.py`` does the same on
1000 runs and counts the runs the env ends at its envelope.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft.registry import resolve_aircraft
from harv_jax.control.registry import build_controller
from harv_jax.dynamics.disturbances import step_normals
from harv_jax.dynamics.disturbed_step import air_data, disturbance_init, initial_heading, measured
from harv_jax.dynamics.state import WIND_INDEX, from_wind
from harv_jax.env.config import EnvConfig
from harv_jax.env.randomize import EpisodeParams
from harv_jax.env.recovery import make_env
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.montecarlo.disturbances import parse_disturbances
from harv_jax.evaluation.montecarlo.inputs import sample_mc_inputs
from harv_jax.task.spaces import command_to_action
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S, H0_FT, RATE_MAX_RADPS, V_MAX_FPS

RUNS = np.array([0, 3])
N_STEPS = 300
SCALE = np.array(
    [V_MAX_FPS / 2, 1.0, 1.0, RATE_MAX_RADPS, RATE_MAX_RADPS, RATE_MAX_RADPS, 1.0, 1.0, 1.0, H0_FT]
)
#: Float32 rounding amplified by the flight (as in ``test_env_mc_agreement``: the command's round trip
#: through the action, the two compiled loops); measured 5e-7 over these 3 s.
TOL = 1e-5


def _flights():
    _, nominal = resolve_aircraft(None)
    spec = parse_disturbances("default")
    inputs = sample_mc_inputs(jax.random.key(11), 4, nominal, h0_ft=H0_FT, disturbances=spec)
    assert inputs.disturbance.turbulence is not None and inputs.model_params is not None
    take = lambda tree: jax.tree.map(lambda a: a[RUNS], tree)  # noqa: E731
    x0, keys, plant, model = (
        inputs.x0_wind[RUNS],
        inputs.keys[RUNS],
        take(inputs.params),
        take(inputs.model_params),
    )
    levels, dkeys = take(inputs.disturbance), inputs.disturbance_keys[RUNS]
    max_delay = inputs.max_delay_steps
    reference = jnp.array([ALPHA_TARGET_RAD, 0.0, 0.0], x0.dtype)
    env = make_env(
        EnvConfig(
            domain_randomization=True, turbulence=True, episode_steps=N_STEPS, max_delay_steps=max_delay
        )
    )
    env_params = env.default_params()
    smc = build_controller("smc")

    def one(x0_i, key_i, plant_i, model_i, levels_i, dkey_i):
        _, state0 = env.reset_to(jax.random.key(0), x0_i, reference, env_params)
        body0 = from_wind(x0_i)
        step_keys = jax.random.split(dkey_i, N_STEPS + 1)
        delta0 = jnp.zeros((3,), x0_i.dtype)
        dist0 = disturbance_init(
            step_normals(step_keys[0], x0_i.dtype),
            levels_i,
            delta0,
            initial_heading(body0),
            max_delay,
            step_keys[0],
        )
        episode = EpisodeParams(
            plant_i,
            levels_i.delay_steps,
            levels_i.gust_std_fps,
            levels_i.gust_tau_s,
            levels_i.noise_std,
            levels_i.turbulence,
        )
        x_air0 = air_data(body0, dist0, levels_i).x_wind
        state0 = state0.replace(aircraft=body0, wind=x_air0, disturbance=dist0, episode=episode)
        c0 = smc.init(model_i).replace(u_prev_rad=delta0)

        def step(carry, keys_k):
            state, cstate = carry
            key_k, dkey_k = keys_k
            u, cstate, _ = smc.apply(
                cstate, measured(state.wind, state.disturbance, state.episode.levels), reference, key_k
            )
            ac = state.episode.aircraft
            action = jnp.clip(command_to_action(u, ac.u_min_rad, ac.u_max_rad), -1.0, 1.0)
            _, state, _, terminated, _, _ = env.step_no_reset(dkey_k, state, action, env_params)
            return (state, cstate), (state.wind, terminated)

        xs = (jax.random.split(key_i, N_STEPS), step_keys[1:])
        _, (x_env, term) = jax.lax.scan(step, (state0, c0), xs)
        x_env = jnp.concatenate([state0.wind[None], x_env])
        res = closed_loop(
            smc,
            plant_i,
            x0_i,
            reference,
            key_i,
            N_STEPS,
            DT_S,
            disturbance=levels_i,
            disturbance_key=dkey_i,
            max_delay_steps=max_delay,
            model_params=model_i,
        )
        x_mc = jnp.concatenate([res.traj.x_wind, res.x_final_wind[None]])
        return x_env, term, x_mc

    return jax.jit(jax.vmap(one))(x0, keys, plant, model, levels, dkeys)


def test_env_flies_the_monte_carlos_disturbed_trajectories():
    x_env, term, x_mc = (np.asarray(a) for a in _flights())
    assert not term.any()  # these runs stay inside the envelope
    d = x_env - x_mc
    for i in (WIND_INDEX["mu"], WIND_INDEX["chi"]):
        d[..., i] = np.remainder(d[..., i] + np.pi, 2 * np.pi) - np.pi
    rel = np.abs(d) / SCALE
    assert rel.max() < TOL, rel.max()
    # the disturbances act: the air-relative alpha moves by more than the rounding between steps
    assert np.abs(np.diff(x_mc[:, :, WIND_INDEX["beta"]], axis=1)).max() > 1e-4
