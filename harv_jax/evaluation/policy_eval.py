"""Recovery evaluation of policies while they train: a fixed batch, the Monte Carlo's criterion, one jit.

The batch (common random numbers: drawn once from a fixed key, the same for every seed and period) holds
``n_upset`` states from the paper's reset bounds sampled as ``harv-jax mc`` does (mu = gamma = 0, alpha_d
= ``task.spec.ALPHA_TARGET_RAD``) and ``n_spin`` developed spins: the scenario's 30 s spin of the nominal
aircraft first, then entries of a spin bank drawn with another key than any training bank. Each run
starts at its deflections and flies ``duration_s`` (default 60 s, as ``harv-jax mc``) RL-only with the
deterministic policy, and is scored by ``compute_metrics`` (recovered = the criterion held over the last
10 s; recovery time).

``make_policy_eval(networks, batch, ...)`` returns ``evaluate(params, normalizer)`` for one seed; vmap it
over a leading seed axis ([`make_seed_eval`][] does, and jits).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from harv_jax.aircraft.params import AircraftParams
from harv_jax.aircraft.randomize import default_aircraft_randomization
from harv_jax.control.base import Controller
from harv_jax.control.rl import make_rl_controller
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.montecarlo.paired import times_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S
from harv_jax.task.spin_bank import make_spin_bank, nominal_spin

#: Key offsets of the evaluation batch (far from the training seeds and from the Monte Carlo's seed 0).
EVAL_KEY_SEED = 2_000_001


@struct.dataclass
class EvalBatch:
    """Initial conditions of the evaluation runs (leading axis: run).

    Attributes:
        x0_wind: [N, 10] initial wind states.
        delta0_rad: [N, 3] initial deflections.
        params: AircraftParams with [N]-batched leaves.
        is_spin: [N] the run starts in a developed spin.
    """

    x0_wind: jnp.ndarray
    delta0_rad: jnp.ndarray
    params: AircraftParams
    is_spin: jnp.ndarray


def make_eval_batch(
    n_upset: int, n_spin: int, nominal: AircraftParams, randomize: bool = False, seed: int = EVAL_KEY_SEED
) -> EvalBatch:
    """The fixed evaluation batch (see the module docstring)."""

    k_mc, k_bank = jax.random.split(jax.random.key(seed))
    mc = sample_mc_inputs(k_mc, n_upset, nominal, randomize=randomize) if n_upset else None
    xs, ds, ps = [], [], []
    if mc is not None:
        xs.append(mc.x0_wind)
        ds.append(jnp.zeros((n_upset, 3), mc.x0_wind.dtype))
        ps.append(mc.params)
    if n_spin:
        x_nom, d_nom = nominal_spin(nominal)
        xs.append(x_nom[None])
        ds.append(d_nom[None])
        ps.append(jax.tree.map(lambda a: jnp.asarray(a)[None], nominal))
        if n_spin > 1:
            bank = make_spin_bank(k_bank, n_spin - 1, nominal, default_aircraft_randomization(randomize))
            xs.append(bank.x_wind)
            ds.append(bank.delta_rad)
            ps.append(jax.tree.map(lambda a: jnp.broadcast_to(a, (n_spin - 1,) + jnp.shape(a)), nominal))
    if not xs:
        raise ValueError("the evaluation batch needs n_upset + n_spin >= 1")
    params = jax.tree.map(lambda *a: jnp.concatenate(a, axis=0), *ps)
    return EvalBatch(
        x0_wind=jnp.concatenate(xs),
        delta0_rad=jnp.concatenate(ds),
        params=params,
        is_spin=jnp.asarray(np.arange(n_upset + n_spin) >= n_upset),
    )


def make_policy_eval(
    act_fn: Callable[[object, object, jax.Array], jax.Array],
    batch: EvalBatch,
    duration_s: float = 60.0,
    dt_s: float = DT_S,
    alpha_d_rad: float = ALPHA_TARGET_RAD,
    make_controller: Callable[[Callable[[jax.Array], jax.Array]], Controller] = make_rl_controller,
) -> Callable[[object, object], dict[str, jax.Array]]:
    """``evaluate(params, normalizer) -> {"recovered": [N] bool, "t_recover_s": [N], "tv_rad": [N]}``.

    Args:
        act_fn: ``act_fn(params, normalizer, obs [11]) -> action [3]`` (the deterministic policy).
        batch: the runs.
        duration_s: length of each run, s (static).
        dt_s: step, s.
        alpha_d_rad: target alpha, rad (beta_d = mu_d = 0).
        make_controller: the controller the policy flies in, from its ``obs -> action`` function (default
            RL-only; e.g. ``lambda act: make_hybrid(act, cfg)`` for a policy trained in the hybrid's loop).
    """
    n_steps = int(round(duration_s / dt_s))
    reference = jnp.asarray([alpha_d_rad, 0.0, 0.0], batch.x0_wind.dtype)

    def evaluate(params, normalizer) -> dict[str, jax.Array]:
        controller = make_controller(lambda obs: act_fn(params, normalizer, obs))

        def one(p, x0, d0):
            res = closed_loop(controller, p, x0, reference, jax.random.key(0), n_steps, dt_s, d0)
            m, _ = score(res, reference, p, dt_s)
            return {
                "recovered": m.recovered,
                "t_recover_s": m.t_recover_s,
                "tv_rad": jnp.sum(m.control_tv_rad, axis=-1),
            }

        return jax.vmap(one)(batch.params, batch.x0_wind, batch.delta0_rad)

    return evaluate


def summarize_eval(
    out: dict[str, np.ndarray], is_spin: np.ndarray, duration_s: float | None = None
) -> dict[str, np.ndarray]:
    """Per-seed summary of ``[S, N]`` evaluation outputs: recovery fractions and recovery times.

    Returns:
        {"eval/recovered": [S], "eval/recovered_upset": [S], "eval/recovered_spin": [S],
        "eval/t_recover_median_s": [S] (over recovered runs; NaN if none), "eval/tv_median_rad": [S]}, and
        with ``duration_s`` "eval/t_recover_mean_s": [S], the mean with a run not recovered counted at
        ``duration_s`` (medians flatter a policy that is fast on easy runs and slow on hard ones).
    """
    rec = np.asarray(out["recovered"], bool)
    t = np.asarray(out["t_recover_s"], np.float64)
    spin = np.asarray(is_spin, bool)
    med = np.array([np.median(t[s][rec[s]]) if rec[s].any() else np.nan for s in range(rec.shape[0])])
    res = {
        "eval/recovered": rec.mean(axis=1),
        "eval/t_recover_median_s": med,
        "eval/tv_median_rad": np.median(np.asarray(out["tv_rad"], np.float64), axis=1),
    }
    if duration_s is not None:
        res["eval/t_recover_mean_s"] = times_nr_at_run_s(t, rec, duration_s).mean(axis=1)
    if (~spin).any():
        res["eval/recovered_upset"] = rec[:, ~spin].mean(axis=1)
    if spin.any():
        res["eval/recovered_spin"] = rec[:, spin].mean(axis=1)
    return res
