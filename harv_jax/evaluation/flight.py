"""One closed-loop flight of a registered controller from a scenario, as a typed [`FlightResult`][].

Scenarios: ``"spin"`` (the pro-spin open loop for ``spin_s``, then the controller engages), ``"random"``
(one state from the paper's reset bounds, drawn with the seed) or a wind state given as a dict of
``WIND_STATE_NAMES`` values (ft/s, rad, rad/s, ft). [`write_flight`][] writes a ``harv-jax fly`` folder.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from harv_jax import atomic
from harv_jax.aircraft.registry import resolve_aircraft
from harv_jax.control import default_gains
from harv_jax.control.hybrid.settings import DEFAULT_ZETA
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.dynamics import CONTROL_NAMES, WIND_STATE_NAMES, from_wind
from harv_jax.evaluation.certificate import empirical_certificate, unsaturated_steps
from harv_jax.evaluation.closed_loop import WIND_INFO_KEY, evaluate
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.evaluation.montecarlo.rollout import sample_mc_inputs
from harv_jax.evaluation.summary import flight_summary, metrics_to_dict
from harv_jax.numfmt import write_json
from harv_jax.task.scenarios import (
    SPIN_CONTROLS_RAD,
    open_loop,
    sample_table_states,
    spin_check,
    spin_controls_rad,
    spin_entry_state,
)
from harv_jax.task.spec import DT_S

if TYPE_CHECKING:
    from harv_jax.aircraft.params import AircraftParams

#: One flight: XLA compile time dominates the run time, so skip the backend's slow optimizations
#: (measured: ~30% less compile CPU for a ~30% slower 6000-step run of ~1 s).
FAST_COMPILE = {"xla_backend_optimization_level": 0}
#: Controller diagnostics of the hybrid kept per step (present when the controller reports them all).
HYBRID_INFO = ("zeta", "fallback", "u_rl_rad", "u_fb_rad")


@dataclasses.dataclass(frozen=True)
class FlightResult:
    """One flight on the host; time series cover the spin (if any) and the closed loop.

    Attributes:
        t_s: [T] time from the scenario's start, s.
        x_wind: [T, 10] wind states.
        delta_rad: [T, 3] surface deflections.
        u_cmd_rad: [T, 3] commands (the pro-spin command before engagement).
        s: [T, 3] sliding variables (NaN before engagement and for controllers without them).
        e: [T, 3] tracking errors (as ``s``).
        hybrid: zeta, fallback, u_rl_rad, u_fb_rad [T, ...] (controllers reporting them), else None.
        certificate: ``empirical_certificate`` over all and over unsaturated steps (controllers with
            sliding variables), else None.
        t_engage_s: engagement time, s.
        metrics: the closed loop's ``metrics_to_dict``.
        spin: the spin check of the open loop (spin scenario of >= 1 s), else None.
        x0: the scenario's initial wind state by name.
        wind_body_fps: [T, 3] body-axis velocity of the air mass (gust and turbulence), ft/s (NaN before
            engagement), with disturbances; else None.
    """

    t_s: np.ndarray
    x_wind: np.ndarray
    delta_rad: np.ndarray
    u_cmd_rad: np.ndarray
    s: np.ndarray
    e: np.ndarray
    hybrid: dict[str, np.ndarray] | None
    certificate: dict[str, Any] | None
    t_engage_s: float
    metrics: dict[str, Any]
    spin: dict[str, Any] | None
    x0: dict[str, float]
    wind_body_fps: np.ndarray | None = None


@functools.lru_cache(maxsize=8)
def _runner(controller_name: str, options: ControllerOptions, n_steps: int, max_delay_steps: int = 0):
    """Jitted closed-loop evaluation (cached per process so repeated calls reuse one compile)."""
    import jax

    controller = build_controller(controller_name, options)

    @functools.partial(jax.jit, compiler_options=FAST_COMPILE)
    def run(
        params, x0_body, delta0, reference, key, model_params=None, disturbance=None, disturbance_key=None
    ):
        return evaluate(
            controller,
            params,
            x0_body,
            reference,
            key,
            n_steps,
            DT_S,
            delta0,
            disturbance=disturbance,
            disturbance_key=disturbance_key,
            max_delay_steps=max_delay_steps,
            model_params=model_params,
        )

    return run


@functools.lru_cache(maxsize=4)
def _spin_runner(n_steps: int):
    import jax

    @functools.partial(jax.jit, compiler_options=FAST_COMPILE)
    def run(params, x0_wind):
        return open_loop(params, x0_wind, spin_controls_rad(x0_wind.dtype), n_steps, DT_S)

    return run


def _certificate(info: dict, traj: Any, params: Any, switching: str, n_run: int) -> dict[str, Any]:
    g = default_gains()
    z = info["zeta"] if "zeta" in info else np.ones(n_run)
    args = (info["s"], z, info["w_mu"], g.k_reach, g.eps_radps2, g.phi_radps, DT_S, switching)
    free = unsaturated_steps(
        np.asarray(traj.delta_rad),
        np.asarray(params.u_min_rad),
        np.asarray(params.u_max_rad),
        np.asarray(params.u_rate_max_radps) * DT_S,
    )
    return {
        "all_steps": empirical_certificate(*args),
        "unsaturated_steps": empirical_certificate(*args, valid=free),
    }


def fly(
    scenario: str | dict[str, float],
    target_alpha_rad: float,
    duration_s: float,
    seed: int,
    switching: str = "sat",
    spin_s: float = 30.0,
    controller: str = "smc",
    policy: str | None = None,
    zeta: str = DEFAULT_ZETA,
    disturbances: DisturbanceSpec | None = None,
    aircraft: str | AircraftParams | None = None,
) -> FlightResult:
    """Fly a registered controller from a scenario (no files).

    Args:
        scenario: ``"spin"``, ``"random"`` or a wind state by name (chi and h included).
        target_alpha_rad: alpha_d, rad (beta_d = mu_d = 0).
        duration_s: closed-loop time after engagement, s.
        seed: seed of the random scenario and of the controller key.
        switching, policy, zeta: the controller's options (``ControllerOptions``).
        spin_s: spin scenario: seconds held in the spin before engagement.
        controller: a name of ``harv_jax.control.registry.CONTROLLERS``.
        disturbances: noise, delay, gust, model error and lag after engagement (``disturbance_spec``; the
            draws of run 0 of a Monte Carlo with ``seed``; None: none).
        aircraft: the nominal aircraft, a name of ``harv_jax.aircraft.registry`` or ``AircraftParams``
            (None: the registry's default).
    """
    import jax
    import jax.numpy as jnp

    params = resolve_aircraft(aircraft)[1]
    key = jax.random.key(seed)
    key_state, key_ctrl = jax.random.split(key)
    del key
    n_steps = int(round(duration_s / DT_S))
    pre_x, pre_delta = np.zeros((0, 10)), np.zeros((0, 3))
    spin = None
    if scenario == "spin":
        x0 = spin_entry_state(dtype=jnp.float32)
        n_spin = int(round(spin_s / DT_S))
        if n_spin > 0:
            xs, deltas, body0, delta0 = _spin_runner(n_spin)(params, x0)
            pre_x, pre_delta = np.asarray(xs[:-1]), np.asarray(deltas)
            if n_spin * DT_S >= 1.0:
                sc = spin_check(xs, DT_S, min(20.0, n_spin * DT_S))
                spin = {f.name: np.asarray(getattr(sc, f.name)).item() for f in dataclasses.fields(sc)}
        else:
            body0, delta0 = from_wind(x0), jnp.zeros((3,), jnp.float32)
    else:
        if scenario == "random":
            x0 = sample_table_states(key_state, 1)[0]
        else:
            x0 = jnp.asarray([scenario[n] for n in WIND_STATE_NAMES], dtype=jnp.float32)
        body0, delta0 = from_wind(x0), jnp.zeros((3,), jnp.float32)
    x0_dict = {n: float(v) for n, v in zip(WIND_STATE_NAMES, np.asarray(x0), strict=True)}
    reference = jnp.asarray([target_alpha_rad, 0.0, 0.0], jnp.float32)
    options = ControllerOptions(policy=policy, zeta=zeta, switching=switching)

    spec = disturbances or DisturbanceSpec()
    extra = {}
    if spec.active:
        run0 = jax.tree.map(
            lambda a: a[0], sample_mc_inputs(jax.random.key(seed), 1, params, disturbances=spec)
        )
        params = run0.params
        extra = {
            "model_params": run0.model_params,
            "disturbance": run0.disturbance,
            "disturbance_key": run0.disturbance_keys,
        }
    runner = _runner(controller, options, n_steps, spec.delay_steps)
    m, traj = runner(params, body0, delta0, reference, key_ctrl, **extra)
    n_pre = pre_x.shape[0]
    nan3 = np.full((n_pre, 3), np.nan)
    info = {k: np.asarray(v) for k, v in traj.info.items()}
    n_run = traj.x_wind.shape[0]
    certificate = _certificate(info, traj, params, switching, n_run) if {"s", "w_mu"} <= info.keys() else None
    for k in ("s", "e"):
        info.setdefault(k, np.full((n_run, 3), np.nan))
    hybrid = None
    if set(HYBRID_INFO) <= info.keys():
        hybrid = {
            k: np.concatenate([np.full((n_pre,) + info[k].shape[1:], np.nan), info[k]]) for k in HYBRID_INFO
        }
    return FlightResult(
        t_s=np.arange(n_pre + n_steps) * DT_S,
        x_wind=np.concatenate([pre_x, np.asarray(traj.x_wind)]),
        delta_rad=np.concatenate([pre_delta, np.asarray(traj.delta_rad)]),
        u_cmd_rad=np.concatenate(
            [np.broadcast_to(np.asarray(SPIN_CONTROLS_RAD), (n_pre, 3)), np.asarray(traj.u_cmd_rad)]
        ),
        s=np.concatenate([nan3, info["s"]]),
        e=np.concatenate([nan3, info["e"]]),
        hybrid=hybrid,
        certificate=certificate,
        t_engage_s=n_pre * DT_S,
        metrics=metrics_to_dict(m),
        spin=spin,
        x0=x0_dict,
        wind_body_fps=None if WIND_INFO_KEY not in info else np.concatenate([nan3, info[WIND_INFO_KEY]]),
    )


def write_flight(out_dir: Path, res: FlightResult, settings: dict[str, Any]) -> None:
    """trajectory.csv, trajectory.png (paper layout), sliding.png, metrics.json (and hybrid.png) in
    ``out_dir``.

    ``settings``: ``harv_jax.evaluation.summary.flight_settings``.
    """
    from harv_jax.plots.flight import S_E_NAMES, plot_hybrid, plot_sliding
    from harv_jax.plots.time_histories import plot_time_histories

    t = res.t_s
    cmd_names = tuple(f"{n}_cmd" for n in CONTROL_NAMES)
    names = ("t", *WIND_STATE_NAMES, *CONTROL_NAMES, *cmd_names, *S_E_NAMES[0], *S_E_NAMES[1])
    cols_out = [t, res.x_wind, res.delta_rad, res.u_cmd_rad, res.s, res.e]
    hy = res.hybrid
    if hy is not None:
        names += ("zeta", "fallback", *(f"{n}_rl" for n in CONTROL_NAMES))
        names += tuple(f"{n}_fb" for n in CONTROL_NAMES)
        cols_out += [hy["zeta"], hy["fallback"], hy["u_rl_rad"], hy["u_fb_rad"]]
        plot_hybrid(t, hy, out_dir / "hybrid.png", res.t_engage_s, res.u_cmd_rad)
    if res.wind_body_fps is not None:
        names += ("wind_u_fps", "wind_v_fps", "wind_w_fps")
        cols_out.append(res.wind_body_fps)
    atomic.savetxt(
        out_dir / "trajectory.csv",
        np.column_stack(cols_out),
        delimiter=",",
        header=",".join(names),
        comments="",
        fmt="%.8g",
    )
    cols = {n: res.x_wind[:, i] for i, n in enumerate(WIND_STATE_NAMES)}
    cols.update({n: res.delta_rad[:, i] for i, n in enumerate(CONTROL_NAMES)})
    ref = settings["reference_rad"]
    t_marker = res.t_engage_s if res.t_engage_s > 0 else None
    plot_time_histories(
        t,
        {settings["controller"]: cols},
        out_dir / "trajectory.png",
        title=f"harv-jax fly: {settings['controller']} from {settings['scenario']} "
        f"(alpha_d = {np.degrees(ref[0]):.1f} deg)",
        references={"alpha": ref[0], "beta": ref[1], "mu": ref[2]},
        t_marker_s=t_marker,
    )
    plot_sliding(t, res.s, res.e, out_dir / "sliding.png", t_marker)
    doc = flight_summary(settings, res.t_engage_s, res.x0, res.spin, res.metrics, res.certificate)
    write_json(out_dir / "metrics.json", doc)
