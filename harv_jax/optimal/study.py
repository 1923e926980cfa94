"""The optimal-recovery study: baselines, warm start, search, acceptance, on the Monte Carlo or one scenario.

[`optimal_study`][] flies the registry's controllers (`BASELINES`) on every run (the standard
closed loop and scoring, the Monte Carlo's common random numbers: ``sample_mc_inputs`` with the same seed
gives ``harv-jax mc``'s runs), warm-starts the search of ``search`` on each run from the better of ``smc``
and ``smc-brake`` (knots 0: that controller exactly), and reports as ``optimal`` per run the re-simulated
searched control if it recovers strictly faster than the best controller on that run, else that
controller's own result (named in ``source``). No surrogate value is reported as a recovery time.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft.params import AircraftParams
from harv_jax.aircraft.registry import resolve_aircraft
from harv_jax.control.base import Controller
from harv_jax.dynamics.state import TRACKED_INDEX, BodyState, from_wind, to_wind
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.montecarlo.paired import times_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import TERMINAL_WINDOW_S, MCRunOutput, sample_mc_inputs
from harv_jax.optimal.schedule import BRAKE_SWITCH_FPS, NO_BRAKE_SWITCH_FPS
from harv_jax.optimal.search import SearchConfig, SearchInputs, SearchResult, search
from harv_jax.task.criteria import tracking_errors
from harv_jax.task.spec import DT_S

#: The registry's controllers every run is compared with (the policy ones fly the default shipped policy).
BASELINES = ("smc", "smc-brake", "rl", "hybrid")
#: Name of the optimum among the controllers of runs.csv and summary.json.
OPTIMAL = "optimal"
#: Decimation of the stored alpha/beta/mu histories (the Monte Carlo's).
RECORD_EVERY = 10


@dataclasses.dataclass(frozen=True)
class Scenario:
    """The runs of a study (leading axis: run; numpy or jax arrays).

    Attributes:
        name: ``"mc"``, ``"spin"`` or ``"file"``.
        x0_wind: [N, 10] wind state at engagement.
        body0: BodyState [N] at engagement.
        delta0_rad: [N, 3] deflections at engagement.
        params: AircraftParams, [N]-batched.
        keys: [N] controller keys.
    """

    name: str
    x0_wind: Any
    body0: Any
    delta0_rad: Any
    params: Any
    keys: Any


def mc_scenario(seed: int, runs: int, aircraft: str | AircraftParams | None = None) -> Scenario:
    """The standard Monte Carlo draw (``sample_mc_inputs``, nominal aircraft, as ``harv-jax mc``);
    ``aircraft``: a registry name or ``AircraftParams`` (None: the registry's default)."""
    inp = sample_mc_inputs(jax.random.key(seed), runs, resolve_aircraft(aircraft)[1])
    body0 = jax.vmap(from_wind)(inp.x0_wind)
    return Scenario("mc", inp.x0_wind, body0, jnp.zeros((runs, 3), inp.x0_wind.dtype), inp.params, inp.keys)


def single_scenario(
    name: str,
    body0: BodyState,
    delta0_rad: jnp.ndarray,
    seed: int,
    aircraft: str | AircraftParams | None = None,
) -> Scenario:
    """One run from a body state and deflections at engagement (nominal ``aircraft``: a registry name or
    ``AircraftParams``; None: the registry's default)."""
    params = jax.tree.map(lambda a: jnp.asarray(a)[None], resolve_aircraft(aircraft)[1])
    body = jax.tree.map(lambda a: jnp.asarray(a)[None], body0)
    key_ctrl = jax.random.split(jax.random.key(seed))[1]
    x0 = jax.vmap(to_wind)(body)
    return Scenario(name, x0, body, jnp.asarray(delta0_rad, x0.dtype)[None], params, key_ctrl[None])


def spin_scenario(spin_s: float, seed: int, aircraft: str | AircraftParams | None = None) -> Scenario:
    """The developed spin (``task.scenarios``: pro-spin controls for ``spin_s``), engaged at its end."""
    from harv_jax.task.scenarios import developed_spin_state

    params = resolve_aircraft(aircraft)[1]
    body, delta = jax.jit(developed_spin_state, static_argnums=1)(params, spin_s)
    return single_scenario("spin", body, delta, seed, params)


def state_scenario(
    state: dict[str, float], seed: int, aircraft: str | AircraftParams | None = None
) -> Scenario:
    """One run from a wind state given by name (``WIND_STATE_NAMES``), deflections 0 (``aircraft`` as in
    [`single_scenario`][])."""
    from harv_jax.dynamics import WIND_STATE_NAMES

    x0 = jnp.asarray([state[n] for n in WIND_STATE_NAMES], jnp.float32)
    return single_scenario("file", from_wind(x0), jnp.zeros(3, jnp.float32), seed, aircraft)


def run_output(
    controller: Controller, params, body0, delta0, key, reference_rad, n_steps: int
) -> tuple[MCRunOutput, tuple[jnp.ndarray, jnp.ndarray]]:
    """One run as the Monte Carlo records it (metrics, terminal error, decimated history), plus (x_all,
    u_cmd) at full rate. Jit/vmap it."""
    res = closed_loop(
        controller=controller,
        params=params,
        x0=body0,
        reference_rad=reference_rad,
        key=key,
        n_steps=n_steps,
        dt_s=DT_S,
        delta0_rad=delta0,
    )
    m, x_all = score(res, reference_rad, params, DT_S)
    n_term = max(1, int(round(TERMINAL_WINDOW_S / DT_S)))
    term = jnp.mean(tracking_errors(x_all[-n_term:], reference_rad), axis=0)
    hist = x_all[:-1:RECORD_EVERY][:, jnp.array(TRACKED_INDEX)]
    out = MCRunOutput(metrics=m, terminal_error_rad=term, history=hist, info_means={})
    return out, (x_all, res.traj.u_cmd_rad)


@functools.lru_cache(maxsize=8)
def _baseline_fn(name: str, n_steps: int):
    from harv_jax.control.registry import build_controller

    ctrl = build_controller(name)

    def run(sc_params, body0, delta0, keys, reference_rad):
        return jax.vmap(lambda p, b, d, k: run_output(ctrl, p, b, d, k, reference_rad, n_steps)[0])(
            sc_params, body0, delta0, keys
        )

    return jax.jit(run)


def fly_baselines(
    scenario: Scenario, reference_rad: jnp.ndarray, n_steps: int, say: Callable[[str], None]
) -> dict[str, MCRunOutput]:
    """Every controller of `BASELINES` on every run (numpy leaves)."""
    outs = {}
    for name in BASELINES:
        say(f"[optimal] {name}: {scenario.x0_wind.shape[0]} runs x {n_steps} steps ...")
        fn = _baseline_fn(name, n_steps)
        outs[name] = jax.device_get(
            fn(scenario.params, scenario.body0, scenario.delta0_rad, scenario.keys, reference_rad)
        )
    return outs


def best_controller(outs: dict[str, MCRunOutput], run_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Per run: (index into ``outs`` of the fastest controller, its time with not-recovered at ``run_s``)."""
    t = np.stack(
        [times_nr_at_run_s(o.metrics.t_recover_s, o.metrics.recovered, run_s) for o in outs.values()]
    )
    i = np.argmin(t, axis=0)
    return i, t[i, np.arange(t.shape[1])]


@dataclasses.dataclass(frozen=True)
class OptimalStudy:
    """What [`optimal_study`][] returns.

    Attributes:
        scenario: the runs.
        outputs: controller -> MCRunOutput (numpy leaves): the baselines and ``optimal``.
        source: [N] per run, where ``optimal``'s result comes from: ``optimal`` (the searched control) or the
            name of the best controller on that run.
        best: [N] name of the best controller on each run.
        search: the search's SearchResult (knots, true times per round, surrogate per iteration).
        v_switch_fps: [N] the warm start's braking choice per run.
        trajectories: (x_all [N, T + 1, 10], u_cmd [N, T, 3]) of the searched control's best knots.
        wall_s: seconds per phase.
    """

    scenario: Scenario
    outputs: dict[str, MCRunOutput]
    source: np.ndarray
    best: np.ndarray
    search: SearchResult
    v_switch_fps: np.ndarray
    trajectories: tuple[np.ndarray, np.ndarray]
    wall_s: dict[str, float]


@functools.lru_cache(maxsize=4)
def _searched_fn(knot_dt_s: float, n_steps: int):
    from harv_jax.optimal.schedule import make_scheduled_smc

    def run(z, v_switch, params, body0, delta0, keys, reference_rad):
        def one(zz, vs, p, b, d, k):
            return run_output(make_scheduled_smc(zz, vs, knot_dt_s), p, b, d, k, reference_rad, n_steps)

        return jax.vmap(one)(z, v_switch, params, body0, delta0, keys)

    return jax.jit(run)


def _pick(take: np.ndarray, a: MCRunOutput, b: MCRunOutput) -> MCRunOutput:
    """Per run: a where ``take`` else b."""
    return jax.tree.map(lambda x, y: np.where(take.reshape((-1,) + (1,) * (x.ndim - 1)), x, y), a, b)


def optimal_study(
    scenario: Scenario,
    target_alpha_rad: float,
    cfg: SearchConfig,
    progress: Callable[[str], None] | None = None,
) -> OptimalStudy:
    """Baselines, warm start, search, re-simulation and acceptance on every run of ``scenario`` (no files)."""
    import time

    say = progress or (lambda _m: None)
    n = int(scenario.x0_wind.shape[0])
    n_steps = int(round(cfg.run_s / DT_S))
    reference = jnp.asarray([target_alpha_rad, 0.0, 0.0], scenario.x0_wind.dtype)
    wall = {}
    t0 = time.perf_counter()
    outs = fly_baselines(scenario, reference, n_steps, say)
    wall["baselines"] = time.perf_counter() - t0
    t_run = {
        k: times_nr_at_run_s(o.metrics.t_recover_s, o.metrics.recovered, cfg.run_s) for k, o in outs.items()
    }
    brake = t_run["smc-brake"] <= t_run["smc"]
    v_switch = np.where(brake, BRAKE_SWITCH_FPS, NO_BRAKE_SWITCH_FPS).astype(np.asarray(reference).dtype)
    inputs = SearchInputs(
        params=scenario.params,
        body0=scenario.body0,
        delta0_rad=jnp.asarray(scenario.delta0_rad),
        v_switch_fps=jnp.asarray(v_switch),
    )
    say(
        f"[optimal] search: {n} runs, {cfg.iterations} gradient steps in {cfg.rounds} rounds, "
        f"horizon {cfg.horizon_s:g} s, {cfg.n_knots} knots every {cfg.knot_dt_s:g} s ..."
    )
    t0 = time.perf_counter()
    res = search(inputs, reference, cfg, progress=say)
    wall["search"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    fn = _searched_fn(cfg.knot_dt_s, n_steps)
    searched, traj = jax.device_get(
        fn(
            jnp.asarray(res.z),
            inputs.v_switch_fps,
            scenario.params,
            scenario.body0,
            inputs.delta0_rad,
            scenario.keys,
            reference,
        )
    )
    wall["resimulate"] = time.perf_counter() - t0
    names = list(outs)
    i_best, t_best = best_controller(outs, cfg.run_s)
    m = searched.metrics
    take = np.asarray(m.recovered) & np.isfinite(m.t_recover_s) & (np.asarray(m.t_recover_s) < t_best)
    best_out = jax.tree.map(
        lambda *xs: np.stack(xs)[i_best, np.arange(n)], *[outs[k] for k in names]
    )  # per run: the best controller's row
    optimal = _pick(take, searched, best_out)
    best = np.asarray([names[i] for i in i_best])
    source = np.where(take, OPTIMAL, best)
    say(f"[optimal] searched control faster than the best controller on {int(take.sum())} of {n} runs")
    return OptimalStudy(
        scenario=scenario,
        outputs={**outs, OPTIMAL: optimal},
        source=source,
        best=best,
        search=res,
        v_switch_fps=v_switch,
        trajectories=traj,
        wall_s=wall,
    )
