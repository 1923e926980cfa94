"""The env flown with the SMC is the Monte Carlo's closed loop, and it ends where the Monte Carlo leaves the
envelope.

Runs 0, 1, 2 and 5 of ``harv-jax mc --runs 8 --seed 0`` (nominal aircraft, no disturbance), 4.5 s each:
run 1 leaves the envelope with alpha below its minimum at step 213, run 5 with alpha above its maximum at
step 428, runs 0 and 2 stay inside. The env (``EnvConfig(domain_randomization=False)``, ``reset_to`` at
the run's x0 and target) is flown with the SMC's command as its action (``command_to_action``, clipped to
[-1, 1]) and without reset (``step_no_reset``), the controller started as ``closed_loop`` starts it.
``experiments/robustness/env_vs_mc.py`` does the same on 1000 runs of 60 s.

The two rules on one state: the env terminates exactly where ``within_envelope`` fails (V, alpha, rates),
and also below the altitude floor (the Monte Carlo's ``GROUND_HIT``), at |gamma| above its bound and on a
non-finite state; at V = v_min = 0 exactly the env terminates while ``within_envelope`` still holds.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.aircraft.registry import resolve_aircraft
from harv_jax.control.registry import build_controller
from harv_jax.dynamics.state import WIND_INDEX
from harv_jax.env.config import EnvConfig
from harv_jax.env.recovery import make_env
from harv_jax.env.termination import termination_flags
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.montecarlo.inputs import sample_mc_inputs
from harv_jax.task.criteria import default_envelope, within_envelope
from harv_jax.task.spaces import command_to_action
from harv_jax.task.spec import (
    ALPHA_MAX_RAD,
    ALPHA_MIN_RAD,
    ALPHA_TARGET_RAD,
    DT_S,
    GAMMA_MAX_RAD,
    H0_FT,
    H_FLOOR_FT,
    RATE_MAX_RADPS,
    V_MAX_FPS,
    V_MIN_FPS,
)

RUNS = np.array([0, 1, 2, 5])
#: The runs' first step outside the envelope (-1: none within N_STEPS); measured, see the module docstring.
FIRST_OUTSIDE = np.array([-1, 213, -1, 428])
N_STEPS = 450
#: Scale of each wind-state component for the trajectory difference (V and rates: the envelope's
#: half-width; angles: 1 rad; h: the initial altitude).
SCALE = np.array(
    [V_MAX_FPS / 2, 1.0, 1.0, RATE_MAX_RADPS, RATE_MAX_RADPS, RATE_MAX_RADPS, 1.0, 1.0, 1.0, H0_FT]
)
#: Trajectory tolerance, relative to SCALE. The two loops fly the same model and controller; they differ
#: by float32 rounding only: the env's first state is x0 itself, the closed loop's to_wind(from_wind(x0))
#: (one round trip, ~1e-7); the command passes through command_to_action / action_to_command (a few ulp);
#: the two compiled loops round some operations differently. The flight amplifies these: on 1000 runs of
#: Monte Carlo seed 2027 (experiments/robustness/env_vs_mc.py) the difference first exceeds 1e-6 at 1.7 s
#: and 1e-4 at 6.1 s and reaches 8e-4 up to a termination. These four runs stay <= 5e-7 over 4.5 s.
TOL = 1e-5


def _flights():
    """Per run: the env's states [N_STEPS + 1, 10], its ``terminated`` [N_STEPS] (entry k: the flag of the
    state after step k + 1), the closed loop's states [N_STEPS + 1, 10] and which of them lie outside the
    Monte Carlo's envelope [N_STEPS + 1]."""
    _, nominal = resolve_aircraft(None)
    inputs = sample_mc_inputs(jax.random.key(0), 8, nominal, h0_ft=H0_FT)
    x0, keys = inputs.x0_wind[RUNS], inputs.keys[RUNS]
    reference = jnp.array([ALPHA_TARGET_RAD, 0.0, 0.0], x0.dtype)
    env = make_env(EnvConfig(domain_randomization=False, episode_steps=N_STEPS))
    env_params = env.default_params()
    smc = build_controller("smc")
    ac = env_params.aircraft

    def one(x0_i, key_i):
        _, state0 = env.reset_to(jax.random.key(0), x0_i, reference, env_params)
        c0 = smc.init(nominal)
        # as closed_loop: the controller's last command starts at the initial deflections (the env's: 0)
        c0 = c0.replace(u_prev_rad=state0.delta_rad.astype(c0.u_prev_rad.dtype))

        def step(carry, key_k):
            state, cstate = carry
            u, cstate, _ = smc.apply(cstate, state.wind, reference, key_k)
            action = jnp.clip(command_to_action(u, ac.u_min_rad, ac.u_max_rad), -1.0, 1.0)
            _, state, _, terminated, _, _ = env.step_no_reset(key_k, state, action, env_params)
            return (state, cstate), (state.wind, terminated)

        _, (x_env, term) = jax.lax.scan(step, (state0, c0), jax.random.split(key_i, N_STEPS))
        x_env = jnp.concatenate([state0.wind[None], x_env])
        res = closed_loop(smc, nominal, x0_i, reference, key_i, N_STEPS, DT_S)
        x_mc = jnp.concatenate([res.traj.x_wind, res.x_final_wind[None]])
        return x_env, term, x_mc, ~within_envelope(x_mc, env_params.envelope)

    return jax.jit(jax.vmap(one))(x0, keys)


def _first(flags: np.ndarray) -> np.ndarray:
    """Index of the first True per row, -1 if none."""
    return np.where(flags.any(axis=1), flags.argmax(axis=1), -1)


@pytest.mark.slow  # 35-55 s on the 2-core CPU: the SMC's loop compiled twice (env and closed_loop)
def test_env_is_the_closed_loop_and_ends_where_the_mc_leaves_the_envelope():
    x_env, term, x_mc, outside = (np.asarray(a) for a in _flights())
    # env step k (1-based) produces the state at t = k dt: termination step k <-> MC sample k
    k_term = np.where(term.any(axis=1), term.argmax(axis=1) + 1, -1)
    k_out = _first(outside)
    np.testing.assert_array_equal(k_out, FIRST_OUTSIDE)  # the runs do what the docstring says
    alpha = WIND_INDEX["alpha"]
    assert x_mc[1, 213, alpha] < ALPHA_MIN_RAD and x_mc[3, 428, alpha] > ALPHA_MAX_RAD
    np.testing.assert_array_equal(k_term, k_out)
    d = x_env - x_mc
    for i in (WIND_INDEX["mu"], WIND_INDEX["chi"]):
        d[..., i] = np.remainder(d[..., i] + np.pi, 2 * np.pi) - np.pi
    rel = np.abs(d) / SCALE
    upto = np.where(k_term >= 0, k_term, N_STEPS)
    for run, k in enumerate(upto):
        assert rel[run, : k + 1].max() < TOL, (RUNS[run], rel[run, : k + 1].max())


def test_env_termination_is_the_mc_envelope_plus_ground_gamma_and_nonfinite():
    env = default_envelope()
    rng = np.random.default_rng(0)
    # states around every bound of the envelope: V, alpha, p, q, r, gamma and h near, at and past them
    x = np.zeros((4000, 10), np.float32)
    x[:, 0] = rng.choice([V_MIN_FPS, 1.0, 300.0, V_MAX_FPS, V_MAX_FPS + 1, -1.0], 4000)
    x[:, 1] = rng.choice(
        [ALPHA_MIN_RAD, ALPHA_MIN_RAD - 1e-3, 0.3, ALPHA_MAX_RAD, ALPHA_MAX_RAD + 1e-3], 4000
    )
    for i in (3, 4, 5):
        x[:, i] = rng.choice([0.0, RATE_MAX_RADPS, -RATE_MAX_RADPS, 1.001 * RATE_MAX_RADPS], 4000)
    x[:, 7] = rng.choice([0.0, 1.5, -1.5], 4000)
    x[:, 9] = rng.choice([H0_FT, H_FLOOR_FT, H_FLOOR_FT - 1.0], 4000)
    x[0, 0] = np.nan  # a non-finite state

    @jax.jit
    def rules(x):
        finite = jnp.all(jnp.isfinite(x), axis=-1)
        return jax.vmap(lambda s, f: termination_flags(s, f, env))(x, finite), within_envelope(x, env)

    flags, inside = jax.tree.map(np.asarray, rules(jnp.asarray(x)))
    assert flags.nonfinite[0] and flags.any[0] and not inside[0]  # NaN: outside for both, the env's nonfinite
    assert not np.any(flags.nonfinite[1:])
    flags, inside, x = jax.tree.map(lambda a: a[1:], flags), inside[1:], x[1:]
    envelope_flags = flags.speed | flags.alpha | flags.rates
    v_at_min = x[:, 0] == V_MIN_FPS
    # the same rule on V, alpha and the rates, except V = v_min exactly (the env: V in (0, 2000])
    np.testing.assert_array_equal(envelope_flags[~v_at_min], ~inside[~v_at_min])
    assert np.all(envelope_flags[v_at_min]) and np.any(inside[v_at_min])
    # the altitude floor is the env's extra termination (the Monte Carlo's GROUND_HIT); gamma cannot bind
    np.testing.assert_array_equal(flags.altitude, x[:, 9] < H_FLOOR_FT)
    assert not np.any(flags.gamma) and GAMMA_MAX_RAD > np.pi / 2
