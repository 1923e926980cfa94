"""Monte Carlo inputs: the sampled initial states, aircraft and disturbances every controller shares.

``sample_mc_inputs`` draws them from one PRNG key (common random numbers: each controller of a Monte Carlo
flies the same runs); ``with_full_structure`` gives every optional part a zero level so that one compiled
rollout serves every level of a sweep.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.aircraft.randomize import (
    NUM_AIRCRAFT_UNIFORMS,
    SAMPLE_UNIFORMS,
    default_aircraft_randomization,
    sample_aircraft,
    uniform16,
)
from harv_jax.dynamics.disturbances import DEFAULT_GUST_TAU_S, DEFAULT_NOISE_STD_MAX, DisturbanceParams
from harv_jax.dynamics.state import WIND_INDEX
from harv_jax.dynamics.turbulence import INTENSITIES, TurbulenceParams, turbulence_params
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.task.disturbance_table import added_models
from harv_jax.task.scenarios import sample_table_states
from harv_jax.task.spec import H0_FT

#: State components the paper's Monte Carlo samples (the others start at 0 / h0).
MC_SAMPLED_STATES = ("V", "alpha", "beta", "p", "q", "r")
#: mu and gamma in the wind state (not sampled by default).
_MU_GAMMA = slice(WIND_INDEX["mu"], WIND_INDEX["gamma"] + 1)


class MCInputs(struct.PyTreeNode):
    """What every controller of one Monte Carlo shares (leading axis: run).

    Attributes:
        x0_wind: [N, 10] initial wind states.
        params: AircraftParams with [N]-batched leaves: the plant.
        keys: [N] PRNG keys for the controllers (stochastic policies).
        model_params: the aircraft the controllers are built on ([N]-batched; None: the plant's).
        disturbance: [N]-batched noise, delay and gust levels (None: no disturbance in the loop).
        disturbance_keys: [N] PRNG keys of the noise and gust draws (with ``disturbance``).
        max_delay_steps: static size of the command FIFO minus one.
    """

    x0_wind: jnp.ndarray
    params: AircraftParams
    keys: jax.Array
    model_params: AircraftParams | None = None
    disturbance: DisturbanceParams | None = None
    disturbance_keys: jax.Array | None = None
    max_delay_steps: int = struct.field(pytree_node=False, default=0)


#: fold_in tag of the disturbance keys (leaves the draws of the undisturbed Monte Carlo unchanged).
_DISTURBANCE_KEY_TAG = 0x6469_7374


def sample_mc_inputs(
    key: jax.Array,
    n_runs: int,
    nominal: AircraftParams,
    randomize: bool = False,
    sample_all_states: bool = False,
    h0_ft: float = H0_FT,
    disturbances: DisturbanceSpec | None = None,
) -> MCInputs:
    """Sample initial states (paper's reset bounds), aircraft and disturbances for ``n_runs`` runs.

    Args:
        key: PRNG key (split into aircraft, initial-state and controller keys; the disturbance keys are
            folded from it, so adding disturbances changes no other draw).
        n_runs: number of runs.
        nominal: nominal aircraft.
        randomize: draw mass, inertia and aero-table multipliers per run (``aircraft.randomize`` at its
            default ranges, the env's) and build the controllers on the nominal aircraft; the same as
            ``disturbances.model_error = 1`` (a spec's own level wins).
        sample_all_states: also sample mu and gamma (default: as the paper, only V, alpha, beta,
            p, q, r are sampled; mu = gamma = 0).
        h0_ft: initial altitude, ft.
        disturbances: noise, delay, gust, model error and actuator lag (``disturbance_spec``; None: none).
    """
    spec = disturbances or DisturbanceSpec()
    if randomize and spec.model_error == 0:
        spec = dataclasses.replace(spec, model_error=1.0)
    key_aircraft, key_init, key_ctrl = jax.random.split(key, 3)
    x0 = sample_table_states(key_init, n_runs, h0_ft=h0_ft)
    if not sample_all_states:
        x0 = x0.at[:, _MU_GAMMA].set(0.0)
    dtype = x0.dtype
    nominal_n = jax.tree.map(lambda a: jnp.broadcast_to(a, (n_runs,) + jnp.shape(a)), nominal)
    aircraft_keys = jax.random.split(key_aircraft, n_runs)
    if spec.model_error > 0:
        rand = _scaled_randomization(spec.model_error, dtype)
        params = jax.vmap(lambda k: sample_aircraft(k, nominal, rand))(aircraft_keys)
    else:
        params = nominal_n
    model_params = None
    if spec.actuator_lag_s > 0:
        params = params.replace(act_tau_s=jnp.full((n_runs,), spec.actuator_lag_s, dtype))
    if (spec.model_error > 0 or spec.actuator_lag_s > 0) and not spec.controller_knows_aircraft:
        model_params = nominal_n
    disturbance = disturbance_keys = None
    if spec.in_loop:
        # the gust's correlation time: the env's draw of the same per-run key (``aircraft.randomize``)
        u_tau = jax.vmap(lambda k: uniform16(k, SAMPLE_UNIFORMS, dtype)[NUM_AIRCRAFT_UNIFORMS + 2])(
            aircraft_keys
        )
        tau_lo, tau_hi = DEFAULT_GUST_TAU_S
        tau = (
            tau_lo + (tau_hi - tau_lo) * u_tau
            if spec.gust_tau_s is None
            else jnp.full((n_runs,), spec.gust_tau_s)
        )
        disturbance = DisturbanceParams(
            noise_std=jnp.broadcast_to(
                jnp.asarray(spec.noise_scale * DEFAULT_NOISE_STD_MAX, dtype), (n_runs, 8)
            ),
            delay_steps=jnp.full((n_runs,), spec.delay_steps, jnp.int32),
            gust_std_fps=jnp.full((n_runs,), spec.gust_fps, dtype),
            gust_tau_s=tau.astype(dtype),
            turbulence=_turbulence(spec.turbulence, params.b, n_runs, dtype),
            added_levels={name: jnp.full((n_runs,), level, dtype) for name, level in spec.added},
            added_models=added_models([name for name, _ in spec.added]),
        )
        disturbance_keys = jax.random.split(jax.random.fold_in(key, _DISTURBANCE_KEY_TAG), n_runs)
    return MCInputs(
        x0_wind=x0,
        params=params,
        keys=jax.random.split(key_ctrl, n_runs),
        model_params=model_params,
        disturbance=disturbance,
        disturbance_keys=disturbance_keys,
        max_delay_steps=spec.delay_steps,
    )


def _turbulence(level: str, span_ft: jnp.ndarray, n_runs: int, dtype) -> TurbulenceParams | None:
    """Per-run turbulence parameters of ``--turbulence`` (None: none), on each plant aircraft's span."""
    if level == "none":
        return None
    one = turbulence_params(level if level in INTENSITIES else float(level), 1.0, dtype)
    return TurbulenceParams(
        sigma_table_fps=jnp.broadcast_to(one.sigma_table_fps, (n_runs,) + one.sigma_table_fps.shape),
        wind_20ft_fps=jnp.full((n_runs,), one.wind_20ft_fps, dtype),
        span_ft=jnp.broadcast_to(jnp.asarray(span_ft, dtype), (n_runs,)),
    )


def with_full_structure(inputs: MCInputs, max_delay_steps: int) -> MCInputs:
    """``inputs`` with every optional part present (zero disturbance levels, the nominal model) and the
    command FIFO sized for ``max_delay_steps``: the same closed loop for every level of a sweep, so one
    compiled rollout serves them all (zero levels act as none: zero noise, zero gust, zero delay)."""
    n = int(inputs.x0_wind.shape[0])
    dtype = inputs.x0_wind.dtype
    if max_delay_steps < inputs.max_delay_steps:
        raise ValueError(f"max_delay_steps={max_delay_steps} < the inputs' {inputs.max_delay_steps}")
    model = inputs.params if inputs.model_params is None else inputs.model_params
    disturbance, dkeys = inputs.disturbance, inputs.disturbance_keys
    if disturbance is None:
        zero = jnp.zeros((n,), dtype)
        disturbance = DisturbanceParams(
            noise_std=jnp.zeros((n, 8), dtype),
            delay_steps=jnp.zeros((n,), jnp.int32),
            gust_std_fps=zero,
            gust_tau_s=jnp.ones((n,), dtype),
        )
        dkeys = jax.random.split(jax.random.key(0), n)
    return inputs.replace(
        model_params=model, disturbance=disturbance, disturbance_keys=dkeys, max_delay_steps=max_delay_steps
    )


def _scaled_randomization(scale: float, dtype):
    """The aircraft randomization at ``scale`` times its default ranges (scale 1: the defaults, exactly)."""
    rand = default_aircraft_randomization(enabled=True, dtype=dtype)
    if scale == 1.0:
        return rand
    fracs = (
        "mass_frac",
        "inertia_frac",
        "aero_damping_frac",
        "aero_control_frac",
        "aero_static_frac",
        "aero_basic_frac",
    )
    return rand.replace(**{f: getattr(rand, f) * scale for f in fracs})
