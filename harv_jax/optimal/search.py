"""The vmapped search: gradient steps on every run's knots at once, re-simulated, kept only when better.

One compiled function runs ``iterations / rounds`` steps (``lax.scan``) on the surrogate
(``objective.surrogate``) of every run (``vmap``; the runs are sharded over the local devices). After each
round the current knots are re-simulated with the standard closed loop for the full run length and scored
by the standard criterion (``evaluation.closed_loop.closed_loop`` + ``score``); a run keeps the new knots
only if that true recovery time is shorter than the best it had (the warm start's first). A run whose
gradient is not finite gets a zero step for that iteration (its knots stay where they were).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import struct
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from harv_jax.aircraft.params import AircraftParams
from harv_jax.dynamics.state import BodyState
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.metrics import RunMetrics
from harv_jax.optimal.objective import SurrogateConfig, surrogate
from harv_jax.optimal.schedule import make_scheduled_smc
from harv_jax.task.spec import DT_S

#: Momentum of the normalized gradient descent.
MOMENTUM = 0.7


@dataclasses.dataclass(frozen=True)
class SearchConfig:
    """Static settings of the search (validated by [`check_search_config`][]).

    Attributes:
        horizon_s: optimization horizon, s (the surrogate's rollout).
        knot_dt_s: knot spacing, s.
        iterations: gradient steps in all.
        rounds: re-simulations (and acceptances) spread over the iterations.
        learning_rate: length of each step in the raw knots (the gradient is normalized per run).
        run_s: run length of the re-simulation and of the scoring, s (the Monte Carlo's).
        chunk_steps: steps per rematerialized chunk of the rollout.
        hold_weight: the surrogate's extra weight of its final hold window.
        hold_s: the surrogate's final hold window, s (the scoring's stays the criterion's 10 s).
    """

    horizon_s: float = 15.0
    knot_dt_s: float = 1.0
    iterations: int = 12
    rounds: int = 6
    learning_rate: float = 0.3
    run_s: float = 60.0
    chunk_steps: int = 100
    hold_weight: float = 2.0
    hold_s: float = 5.0

    @property
    def n_knots(self) -> int:
        """Knots over [0, horizon - hold): the reference is the target in the surrogate's hold window."""
        return max(1, int(round((self.horizon_s - self.hold_s) / self.knot_dt_s)))

    def surrogate(self) -> SurrogateConfig:
        """The surrogate's settings (horizon rounded to whole chunks)."""
        n = int(round(self.horizon_s / DT_S))
        n = max(self.chunk_steps, n - n % self.chunk_steps)
        return SurrogateConfig(
            n_steps=n, chunk_steps=self.chunk_steps, hold_s=self.hold_s, hold_weight=self.hold_weight
        )


def check_search_config(cfg: SearchConfig) -> None:
    """ValueError naming the first bad field and what is allowed."""
    if not (np.isfinite(cfg.horizon_s) and cfg.hold_s < cfg.horizon_s <= cfg.run_s):
        raise ValueError(f"horizon {cfg.horizon_s} s must be in ({cfg.hold_s:g}, {cfg.run_s:g}] s")
    span_s = cfg.horizon_s - cfg.hold_s
    if not (np.isfinite(cfg.knot_dt_s) and DT_S <= cfg.knot_dt_s <= span_s):
        raise ValueError(f"knot spacing {cfg.knot_dt_s} s must be in [{DT_S}, {span_s:g}] s (horizon - hold)")
    if cfg.iterations < 1:
        raise ValueError(f"iterations {cfg.iterations} must be >= 1")
    if not (1 <= cfg.rounds <= cfg.iterations and cfg.iterations % cfg.rounds == 0):
        raise ValueError(f"rounds {cfg.rounds} must divide the iterations ({cfg.iterations})")
    if not (np.isfinite(cfg.learning_rate) and cfg.learning_rate > 0):
        raise ValueError(f"learning rate {cfg.learning_rate} must be > 0")


class SearchInputs(struct.PyTreeNode):
    """The runs of a search (leading axis: run).

    Attributes:
        params: AircraftParams with [N]-batched leaves.
        body0: BodyState [N] at engagement.
        delta0_rad: [N, 3] deflections at engagement.
        v_switch_fps: [N] the braking schedule's switch speed of each run (the warm start's choice).
    """

    params: AircraftParams
    body0: BodyState
    delta0_rad: jnp.ndarray
    v_switch_fps: jnp.ndarray


class SearchResult(struct.PyTreeNode):
    """What [`search`][] returns (numpy leaves).

    Attributes:
        z: [N, n_knots, 3] best raw knots of each run (by true recovery time).
        metrics: RunMetrics [N] of the re-simulated best knots.
        objective: [iterations, N] surrogate per iteration and run.
        round_t_recover_s: [rounds + 1, N] true recovery time of the current knots at the warm start and
            after each round (NaN: not recovered).
        wall_s: {"compile": s, "run": s}.
    """

    z: np.ndarray
    metrics: RunMetrics
    objective: np.ndarray
    round_t_recover_s: np.ndarray
    wall_s: dict = struct.field(pytree_node=False)


def _better(t_new: np.ndarray, rec_new: np.ndarray, t_old: np.ndarray, rec_old: np.ndarray) -> np.ndarray:
    """Per run: the new result recovers and is strictly faster than the old (a non-recovered old loses)."""
    old = np.where(rec_old & np.isfinite(t_old), t_old, np.inf)
    return rec_new & np.isfinite(t_new) & (t_new < old)


def _where_runs(take: np.ndarray, a, b):
    """Per run (leading axis): a's leaves where ``take``, else b's."""
    return jax.tree.map(lambda x, y: np.where(take.reshape((-1,) + (1,) * (np.ndim(x) - 1)), x, y), a, b)


def _shard(tree, n_dev: int):
    if n_dev <= 1:
        return tree
    mesh = Mesh(np.array(jax.local_devices()[:n_dev]), ("runs",))
    return jax.device_put(tree, NamedSharding(mesh, PartitionSpec("runs")))


def rounds_for(iterations: int, most: int = 8) -> int:
    """The largest number of rounds <= ``most`` that divides ``iterations`` (1 for a prime count)."""
    return max(d for d in range(1, most + 1) if iterations % d == 0)


def make_search_fns(
    cfg: SearchConfig, reference_rad: jnp.ndarray
) -> tuple[Callable, Callable, Callable, optax.GradientTransformation]:
    """(round_fn, resim_fn, trajectory_fn, optimizer); the functions jitted and vmapped over runs.

    round_fn(z, opt_state, inputs) -> (z, opt_state, objective [k, N]): k = iterations / rounds steps.
    resim_fn(z, inputs) -> RunMetrics [N] (standard closed loop over run_s, standard scoring).
    trajectory_fn(z, inputs) -> (RunMetrics [N], x_all [N, T + 1, 10], u_cmd [N, T, 3], delta [N, T, 3]).
    """
    scfg = cfg.surrogate()
    n_run = int(round(cfg.run_s / DT_S))
    opt = optax.sgd(cfg.learning_rate, momentum=MOMENTUM)
    k_round = cfg.iterations // cfg.rounds

    def objective(z, params, body0, delta0, v_switch):
        ctrl = make_scheduled_smc(z, v_switch, cfg.knot_dt_s)
        return surrogate(ctrl, params, body0, delta0, reference_rad, scfg)

    value_grad = jax.vmap(jax.value_and_grad(objective))

    def round_fn(z, opt_state, inputs: SearchInputs):
        def it(carry, _):
            z, st = carry
            j, g = value_grad(z, inputs.params, inputs.body0, inputs.delta0_rad, inputs.v_switch_fps)
            ok = jnp.all(jnp.isfinite(g), axis=(1, 2)) & jnp.isfinite(j)
            norm = jnp.sqrt(jnp.sum(g * g, axis=(1, 2), keepdims=True))
            g = jnp.where(ok[:, None, None], g / jnp.maximum(norm, 1e-12), 0.0)
            upd, st = opt.update(g, st, z)
            return (optax.apply_updates(z, upd), st), j

        (z, opt_state), js = jax.lax.scan(it, (z, opt_state), None, length=k_round)
        return z, opt_state, js

    def resim_one(z, params, body0, delta0, v_switch):
        ctrl = make_scheduled_smc(z, v_switch, cfg.knot_dt_s)
        res = closed_loop(
            controller=ctrl,
            params=params,
            x0=body0,
            reference_rad=reference_rad,
            key=jax.random.key(0),
            n_steps=n_run,
            dt_s=DT_S,
            delta0_rad=delta0,
        )
        m, x_all = score(res, reference_rad, params, DT_S)
        return m, x_all, res.traj.u_cmd_rad, res.traj.delta_rad

    def trajectory_fn(z, inputs: SearchInputs):
        return jax.vmap(resim_one)(z, inputs.params, inputs.body0, inputs.delta0_rad, inputs.v_switch_fps)

    def resim_fn(z, inputs: SearchInputs):
        return trajectory_fn(z, inputs)[0]

    return jax.jit(round_fn), jax.jit(resim_fn), jax.jit(trajectory_fn), opt


def search(
    inputs: SearchInputs,
    reference_rad: jnp.ndarray,
    cfg: SearchConfig,
    z0: jnp.ndarray | None = None,
    progress: Callable[[str], None] | None = None,
) -> SearchResult:
    """Optimize every run's knots from ``z0`` (default 0: the warm start); keep the best by true score.

    Args:
        inputs: SearchInputs (N runs).
        reference_rad: [3] target [alpha_d, beta_d, mu_d], rad.
        cfg: SearchConfig.
        z0: [N, n_knots, 3] initial raw knots (default zeros).
        progress: called with one line per round.

    Returns:
        SearchResult.
    """
    check_search_config(cfg)
    say = progress or (lambda _m: None)
    n = int(inputs.delta0_rad.shape[0])
    n_dev = jax.local_device_count()
    n_dev = n_dev if n >= n_dev else 1
    pad = (-n) % n_dev
    padded = jax.tree.map(
        lambda a: jnp.concatenate([a, jnp.repeat(a[:1], pad, axis=0)]) if pad else a, inputs
    )
    dtype = inputs.delta0_rad.dtype
    reference_rad = jnp.asarray(reference_rad, dtype)
    round_fn, resim_fn, _, opt = make_search_fns(cfg, reference_rad)
    z = jnp.zeros((n + pad, cfg.n_knots, 3), dtype) if z0 is None else jnp.asarray(z0, dtype)
    if z.shape[0] == n and pad:
        z = jnp.concatenate([z, jnp.repeat(z[:1], pad, axis=0)])
    padded, z = _shard(padded, n_dev), _shard(z, n_dev)
    opt_state = opt.init(z)

    t0 = time.perf_counter()
    m0 = jax.device_get(resim_fn(z, padded))
    t_resim = time.perf_counter() - t0
    best_z, best_m = np.asarray(z), m0
    hist_t = [np.where(m0.recovered, m0.t_recover_s, np.nan)]
    objective = []
    t_compile = 0.0
    t0 = time.perf_counter()
    for r in range(cfg.rounds):
        t1 = time.perf_counter()
        z, opt_state, js = round_fn(z, opt_state, padded)
        js = np.asarray(jax.device_get(js))
        if r == 0:
            t_compile = time.perf_counter() - t1  # first call: compile + run
        objective.append(js)
        m = jax.device_get(resim_fn(z, padded))
        take = _better(m.t_recover_s, m.recovered, best_m.t_recover_s, best_m.recovered)
        best_z = np.where(take[:, None, None], np.asarray(z), best_z)
        best_m = _where_runs(take, m, best_m)
        hist_t.append(np.where(m.recovered, m.t_recover_s, np.nan))
        say(
            f"[optimal] round {r + 1}/{cfg.rounds}: surrogate {np.mean(js[-1][:n]):.4g} (mean), improved "
            f"{int(np.sum(take[:n]))} runs, best median {np.nanmedian(best_m.t_recover_s[:n]):.3g} s"
        )
    wall = {"compile": t_compile, "run": time.perf_counter() - t0, "resim": t_resim}
    return SearchResult(
        z=best_z[:n],
        metrics=jax.tree.map(lambda a: a[:n], best_m),
        objective=np.concatenate(objective, axis=0)[:, :n],
        round_t_recover_s=np.stack(hist_t)[:, :n],
        wall_s=wall,
    )
