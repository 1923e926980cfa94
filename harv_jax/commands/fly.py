"""`harv-jax fly`: closed-loop flight of a controller from a scenario; CSV, PNGs and metrics.json."""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from pathlib import Path

import numpy as np
import typer

from harv_jax.commands.options import policy_option, zeta_option
from harv_jax.errors import UsageError
from harv_jax.numfmt import write_json
from harv_jax.policies import DEFAULT_POLICY_SPEC

CONTROLLERS = ("smc", "rl", "hybrid")
SCENARIOS = ("spin", "random")
SWITCHING = ("sat", "sign")
DT_S = 0.01
MAX_DURATION_S = 600.0
#: Allowed target angles of attack, rad: the paper's observation range of alpha.
TARGET_ALPHA_RANGE_RAD = (-0.244, 1.571)
REQUIRED_STATE_NAMES = ("V", "alpha", "beta", "p", "q", "r", "mu", "gamma")
#: One flight: XLA compile time dominates the run time, so skip the backend's slow optimizations
#: (measured: ~30% less compile CPU for a ~30% slower 6000-step run of ~1 s).
FAST_COMPILE = {"xla_backend_optimization_level": 0}


def validate_options(
    controller: str, switching: str, target_alpha: float, duration: float, spin_s: float
) -> None:
    """Raise UsageError (one line naming the value and what is allowed) for a bad option."""
    if controller not in CONTROLLERS:
        raise UsageError(f"--controller {controller!r} is unknown; allowed: {', '.join(CONTROLLERS)}")
    if switching not in SWITCHING:
        raise UsageError(f"--switching {switching!r} is unknown; allowed: {', '.join(SWITCHING)}")
    lo, hi = TARGET_ALPHA_RANGE_RAD
    if not (math.isfinite(target_alpha) and lo <= target_alpha <= hi):
        raise UsageError(f"--target-alpha {target_alpha} rad is outside [{lo}, {hi}]")
    if not (math.isfinite(duration) and 0 < duration <= MAX_DURATION_S):
        raise UsageError(f"--duration {duration} must be in (0, {MAX_DURATION_S:g}] s")
    if round(duration / DT_S) < 2:
        raise UsageError(f"--duration {duration} s is shorter than two steps of {DT_S} s")
    if not (math.isfinite(spin_s) and 0 <= spin_s <= MAX_DURATION_S):
        raise UsageError(f"--spin-s {spin_s} must be in [0, {MAX_DURATION_S:g}] s")


def load_state_file(path: Path) -> dict[str, float]:
    """Initial wind state from a JSON object or a CSV with a header row (first data row is used).

    Required names: V, alpha, beta, p, q, r, mu, gamma (ft/s, rad, rad/s); optional chi (rad, 0) and
    h (ft, 25,000). Extra columns (e.g. t, de in a ``harv-jax simulate`` trajectory.csv) are ignored.
    """
    from harv_jax.commands.simulate import validate_state
    from harv_jax.task.spec import H0_FT as DEFAULT_H0_FT

    if not path.is_file():
        raise UsageError(
            f"--scenario {str(path)!r} is neither {' nor '.join(SCENARIOS)} nor an existing file"
        )
    text = path.read_text()
    if path.suffix.lower() == ".json":
        try:
            raw = json.loads(text)
        except json.JSONDecodeError as e:
            raise UsageError(f"state file {str(path)!r} is not valid JSON: {e.msg}") from None
        if not isinstance(raw, dict):
            raise UsageError(f"state file {str(path)!r} must hold a JSON object of name: value")
    elif path.suffix.lower() == ".csv":
        lines = [ln for ln in text.splitlines() if ln.strip()]
        if len(lines) < 2:
            raise UsageError(f"state file {str(path)!r} needs a header row and a data row")
        names = [s.strip() for s in lines[0].split(",")]
        values = [s.strip() for s in lines[1].split(",")]
        if len(values) != len(names):
            raise UsageError(f"state file {str(path)!r}: {len(names)} header names but {len(values)} values")
        raw = dict(zip(names, values, strict=True))
    else:
        raise UsageError(f"state file {str(path)!r} must end in .json or .csv")
    state = {"chi": 0.0, "h": DEFAULT_H0_FT}
    missing = [n for n in REQUIRED_STATE_NAMES if n not in raw]
    if missing:
        raise UsageError(
            f"state file {str(path)!r} lacks {', '.join(missing)}; needs {', '.join(REQUIRED_STATE_NAMES)}"
        )
    for name in (*REQUIRED_STATE_NAMES, "chi", "h"):
        if name not in raw:
            continue
        try:
            v = float(raw[name])
        except (TypeError, ValueError):
            raise UsageError(f"state file {str(path)!r}: {name}={raw[name]!r} is not a number") from None
        if not math.isfinite(v):
            raise UsageError(f"state file {str(path)!r}: {name}={v} is not finite")
        state[name] = v
    validate_state(state)
    if state["h"] <= 0:
        raise UsageError(f"state file {str(path)!r}: h={state['h']} ft must be > 0")
    return state


@functools.lru_cache(maxsize=8)
def _runner(controller_name: str, switching: str, n_steps: int, policy: str | None, zeta: str):
    """Jitted closed-loop evaluation (cached per process so repeated calls reuse one compile)."""
    import jax

    from harv_jax.commands.mc import build_controller
    from harv_jax.control import SMCConfig, make_smc
    from harv_jax.evaluation import evaluate

    if controller_name == "smc":
        controller = make_smc(SMCConfig(switching=switching))
    else:
        controller = build_controller(controller_name, policy, zeta)

    @functools.partial(jax.jit, compiler_options=FAST_COMPILE)
    def run(params, x0_body, delta0, reference, key):
        return evaluate(controller, params, x0_body, reference, key, n_steps, DT_S, delta0)

    return run


@functools.lru_cache(maxsize=4)
def _spin_runner(n_steps: int):
    import jax

    from harv_jax.task.scenarios import open_loop, spin_controls_rad

    @functools.partial(jax.jit, compiler_options=FAST_COMPILE)
    def run(params, x0_wind):
        return open_loop(params, x0_wind, spin_controls_rad(x0_wind.dtype), n_steps, DT_S)

    return run


def run_fly(
    scenario: str,
    target_alpha_rad: float,
    duration_s: float,
    seed: int,
    switching: str = "sat",
    spin_s: float = 30.0,
    controller: str = "smc",
    policy: str | None = None,
    zeta: str = "continuous",
) -> dict:
    """Fly a controller (smc, rl, hybrid) from a scenario; returns host arrays and metrics (no files).

    Returns:
        dict with t_s [T], x_wind [T, 10], delta_rad [T, 3], u_cmd_rad [T, 3], s [T, 3], e [T, 3]
        (NaN before engagement and for rl), hybrid (dict of zeta, fallback, u_rl_rad, u_fb_rad [T, ...],
        hybrid only), t_engage_s, metrics (dict), spin (dict or None), x0 (dict), certificate (smc and
        hybrid: ``harv_jax.evaluation.certificate.empirical_certificate``).
    """
    import jax
    import jax.numpy as jnp

    from harv_jax.aircraft import harv
    from harv_jax.dynamics import WIND_STATE_NAMES, from_wind
    from harv_jax.evaluation.metrics import metrics_to_dict
    from harv_jax.task.scenarios import sample_table_states, spin_check, spin_entry_state

    params = harv()
    key = jax.random.key(seed)
    key_state, key_ctrl = jax.random.split(key)
    del key
    n_steps = int(round(duration_s / DT_S))
    pre_x = np.zeros((0, 10))
    pre_delta = np.zeros((0, 3))
    spin = None
    if scenario == "spin":
        x_entry = spin_entry_state(dtype=jnp.float32)
        n_spin = int(round(spin_s / DT_S))
        if n_spin > 0:
            xs, deltas, body0, delta0 = _spin_runner(n_spin)(params, x_entry)
            pre_x, pre_delta = np.asarray(xs[:-1]), np.asarray(deltas)
            if n_spin * DT_S >= 1.0:
                win = min(20.0, n_spin * DT_S)
                sc = spin_check(xs, DT_S, win)
                spin = {f.name: np.asarray(getattr(sc, f.name)).item() for f in dataclasses.fields(sc)}
        else:
            body0, delta0 = from_wind(x_entry), jnp.zeros((3,), jnp.float32)
        x0_dict = {n: float(v) for n, v in zip(WIND_STATE_NAMES, np.asarray(x_entry), strict=True)}
    else:
        if scenario == "random":
            x0 = sample_table_states(key_state, 1)[0]
        else:
            s = load_state_file(Path(scenario))
            x0 = jnp.asarray([s[n] for n in WIND_STATE_NAMES], dtype=jnp.float32)
        body0, delta0 = from_wind(x0), jnp.zeros((3,), jnp.float32)
        x0_dict = {n: float(v) for n, v in zip(WIND_STATE_NAMES, np.asarray(x0), strict=True)}
    reference = jnp.asarray([target_alpha_rad, 0.0, 0.0], jnp.float32)
    m, traj = _runner(controller, switching, n_steps, policy, zeta)(
        params, body0, delta0, reference, key_ctrl
    )
    n_pre = pre_x.shape[0]
    nan3 = np.full((n_pre, 3), np.nan)
    t_engage = n_pre * DT_S
    info = {k: np.asarray(v) for k, v in traj.info.items()}
    n_run = traj.x_wind.shape[0]
    for k in ("s", "e"):
        info.setdefault(k, np.full((n_run, 3), np.nan))
    hybrid = None
    if controller == "hybrid":
        hybrid = {k: np.concatenate([np.full((n_pre,) + info[k].shape[1:], np.nan), info[k]])
                  for k in ("zeta", "fallback", "u_rl_rad", "u_fb_rad")}  # fmt: skip
    certificate = None
    if controller != "rl":
        from harv_jax.control import default_gains
        from harv_jax.evaluation.certificate import empirical_certificate, unsaturated_steps

        g = default_gains()
        z = info["zeta"] if controller == "hybrid" else np.ones(n_run)
        args = (info["s"], z, info["w_mu"], g.k_reach, g.eps_radps2, g.phi_radps, DT_S, switching)
        free = unsaturated_steps(
            np.asarray(traj.delta_rad), np.asarray(params.u_min_rad), np.asarray(params.u_max_rad),
            np.asarray(params.u_rate_max_radps) * DT_S,
        )  # fmt: skip
        certificate = {
            "all_steps": empirical_certificate(*args),
            "unsaturated_steps": empirical_certificate(*args, valid=free),
        }
    return {
        "t_s": np.arange(n_pre + n_steps) * DT_S,
        "x_wind": np.concatenate([pre_x, np.asarray(traj.x_wind)]),
        "delta_rad": np.concatenate([pre_delta, np.asarray(traj.delta_rad)]),
        "u_cmd_rad": np.concatenate(
            [np.broadcast_to(np.asarray(spin_entry_controls()), (n_pre, 3)), np.asarray(traj.u_cmd_rad)]
        ),
        "s": np.concatenate([nan3, info["s"]]),
        "e": np.concatenate([nan3, info["e"]]),
        "hybrid": hybrid,
        "certificate": certificate,
        "t_engage_s": t_engage,
        "metrics": metrics_to_dict(m),
        "spin": spin,
        "x0": x0_dict,
    }


def spin_entry_controls() -> tuple[float, float, float]:
    """Pro-spin command [de, da, dr], rad (for the CSV's command columns during the spin phase)."""
    from harv_jax.task.scenarios import SPIN_CONTROLS_RAD

    return SPIN_CONTROLS_RAD


def plot_hybrid(
    t: np.ndarray, hy: dict, path: Path, t_engage_s: float, u_cmd_rad: np.ndarray | None = None
) -> None:
    """hybrid.png: zeta and fallback, and per surface the commands as applied: the learned command u_RL,
    the command after the safety filter's position/rate box (u_cmd) and the feedback's applied share
    u_cmd - u_RL. The unsaturated zeta u_fb (which reaches thousands of degrees in a spin) is not drawn;
    its peak is given in the legend."""
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from harv_jax.aircraft.params import U_MAX_RAD, U_MIN_RAD
    from harv_jax.dynamics import CONTROL_NAMES
    from harv_jax.units import DEG_PER_RAD

    fig, axes = plt.subplots(4, 1, figsize=(10, 9.5), sharex=True)
    axes[0].plot(t, hy["zeta"], lw=1.2, label="zeta (authority of the feedback term)")
    axes[0].plot(t, hy["fallback"], lw=1.0, ls="--", label="fallback (1 = SMC-only)")
    axes[0].set_ylabel("zeta / fallback")
    axes[0].set_ylim(-0.05, 1.1)
    axes[0].legend(loc="center right", fontsize=8)
    zeta_fb = hy["zeta"][:, None] * hy["u_fb_rad"]
    for j, n in enumerate(CONTROL_NAMES):
        ax = axes[j + 1]
        u_rl = hy["u_rl_rad"][:, j] * DEG_PER_RAD
        if u_cmd_rad is not None:
            u_cmd = np.asarray(u_cmd_rad)[:, j] * DEG_PER_RAD
            ax.plot(t, u_cmd, color="k", lw=2.2, alpha=0.45, zorder=2)
            ax.plot(t, u_cmd - u_rl, color="C1", lw=1.0, ls="--", zorder=3)
        ax.plot(t, u_rl, color="C0", lw=1.2, zorder=4)
        lo, hi = U_MIN_RAD[j] * DEG_PER_RAD, U_MAX_RAD[j] * DEG_PER_RAD
        for y in (lo, hi):
            ax.axhline(y, color="grey", lw=0.7, ls="-.", zorder=1)
        fin = np.isfinite(zeta_fb[:, j])
        if fin.any():
            peak = np.max(np.abs(zeta_fb[fin, j])) * DEG_PER_RAD
            ax.set_title(f"{n}: the unsaturated feedback command |zeta u_fb| peaks at {peak:,.0f} deg "
                         "(not drawn; the filter limits it)", fontsize=8, loc="left")  # fmt: skip
        span = hi - lo
        ax.set_ylim(lo - 0.1 * span, hi + 0.1 * span)
        ax.set_ylabel(f"{n} [deg]")
    axes[-1].set_xlabel("t [s]")
    if t_engage_s > 0:
        axes[-1].set_xlim(max(t_engage_s - 2.0, t[0]), t[-1])  # the hybrid acts from engagement on
    for ax in axes:
        ax.grid(alpha=0.3)
        if t_engage_s > 0:
            ax.axvline(t_engage_s, color="grey", ls=":", lw=0.8)
    handles = [Line2D([], [], color="C0", lw=1.2, label="learned command u_RL")]
    if u_cmd_rad is not None:
        handles += [
            Line2D([], [], color="k", lw=2.2, alpha=0.45, label="applied command u_cmd (after the filter)"),
            Line2D([], [], color="C1", lw=1.0, ls="--", label="feedback share u_cmd - u_RL"),
        ]
    handles.append(Line2D([], [], color="grey", lw=0.7, ls="-.", label="position limits"))
    if t_engage_s > 0:
        handles.append(
            Line2D([], [], color="grey", ls=":", lw=0.8, label=f"engagement (t = {t_engage_s:g} s)")
        )
    fig.legend(
        handles=handles, loc="upper center", ncol=3, fontsize=8, frameon=False, bbox_to_anchor=(0.5, 0.965)
    )
    fig.suptitle("hybrid: authority factor and the applied command split", y=0.995)
    fig.tight_layout(rect=(0, 0, 1, 0.92))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def write_outputs(out_dir: Path, res: dict, meta: dict) -> None:
    """trajectory.csv, trajectory.png (paper layout), sliding.png and metrics.json in ``out_dir``."""
    import matplotlib.pyplot as plt

    from harv_jax.dynamics import CONTROL_NAMES, WIND_STATE_NAMES
    from harv_jax.plotting import plot_time_histories
    from harv_jax.units import DEG_PER_RAD

    t = res["t_s"]
    cmd_names = tuple(f"{n}_cmd" for n in CONTROL_NAMES)
    s_names = ("s_alpha", "s_beta", "s_mu")
    e_names = ("e_alpha", "e_beta", "e_mu")
    names = ("t", *WIND_STATE_NAMES, *CONTROL_NAMES, *cmd_names, *s_names, *e_names)
    cols_out = [t, res["x_wind"], res["delta_rad"], res["u_cmd_rad"], res["s"], res["e"]]
    hy = res.get("hybrid")
    if hy is not None:
        names += (
            "zeta",
            "fallback",
            *(f"{n}_rl" for n in CONTROL_NAMES),
            *(f"{n}_fb" for n in CONTROL_NAMES),
        )
        cols_out += [hy["zeta"], hy["fallback"], hy["u_rl_rad"], hy["u_fb_rad"]]
        plot_hybrid(t, hy, out_dir / "hybrid.png", res["t_engage_s"], res["u_cmd_rad"])
    table = np.column_stack(cols_out)
    np.savetxt(
        out_dir / "trajectory.csv", table, delimiter=",", header=",".join(names), comments="", fmt="%.8g"
    )
    cols = {n: res["x_wind"][:, i] for i, n in enumerate(WIND_STATE_NAMES)}
    cols.update({n: res["delta_rad"][:, i] for i, n in enumerate(CONTROL_NAMES)})
    ref = meta["reference_rad"]
    t_marker = res["t_engage_s"] if res["t_engage_s"] > 0 else None
    plot_time_histories(
        t,
        {meta["controller"]: cols},
        out_dir / "trajectory.png",
        title=f"harv-jax fly: {meta['controller']} from {meta['scenario']} "
        f"(alpha_d = {np.degrees(ref[0]):.1f} deg)",
        references={"alpha": ref[0], "beta": ref[1], "mu": ref[2]},
        t_marker_s=t_marker,
    )
    fig, axes = plt.subplots(2, 3, figsize=(12, 5.5), sharex=True)
    for j, (sn, en) in enumerate(zip(s_names, e_names, strict=True)):
        axes[0, j].plot(t, res["s"][:, j], lw=0.8)
        axes[0, j].set_ylabel(f"{sn} [rad/s]")
        axes[1, j].plot(t, res["e"][:, j] * DEG_PER_RAD, lw=0.8)
        axes[1, j].set_ylabel(f"{en} [deg]")
        axes[1, j].set_xlabel("t [s]")
        for ax in axes[:, j]:
            ax.grid(alpha=0.3)
            if t_marker is not None:
                ax.axvline(t_marker, color="grey", ls=":", lw=0.8)
    fig.suptitle("sliding variables and tracking errors")
    fig.tight_layout()
    fig.savefig(out_dir / "sliding.png", dpi=90)
    plt.close(fig)
    doc = {
        **meta,
        "t_engage_s": res["t_engage_s"],
        "initial_state": res["x0"],
        "spin_check": res["spin"],
        "metrics": res["metrics"],
        "certificate": res.get("certificate"),
    }
    write_json(out_dir / "metrics.json", doc)


def register(app: typer.Typer) -> None:
    @app.command()
    def fly(
        controller: str = typer.Option("smc", help="Controller: smc, rl (policy only) or hybrid."),
        policy: str = policy_option(),
        zeta: str = zeta_option(),
        scenario: str = typer.Option(
            "spin",
            help="spin (30 s pro-spin open loop, then the controller), random (one state from the "
            "paper's reset bounds, drawn with --seed) or a .json/.csv state file (V, alpha, beta, p, q, "
            "r, mu, gamma; optional chi, h).",
        ),
        target_alpha: float = typer.Option(
            0.349, help="Target angle of attack alpha_d, rad (beta_d = mu_d = 0)."
        ),
        duration: float = typer.Option(60.0, help="Closed-loop flight time after engagement, s."),
        seed: int = typer.Option(0, help="Seed of the random scenario and of the controller key."),
        out: Path = typer.Option(Path("runs/fly"), help="Output directory."),
        force: bool = typer.Option(False, help="Replace an existing non-empty output directory."),
        switching: str = typer.Option("sat", help="SMC switching: sat (boundary layer) or sign (paper)."),
        spin_s: float = typer.Option(30.0, help="Spin scenario: seconds held in the spin before engagement."),
    ) -> None:
        """Fly a controller closed loop: trajectory.csv, trajectory.png, sliding.png, metrics.json (and
        hybrid.png for the hybrid)."""
        from harv_jax.guards import check_seed
        from harv_jax.outdir import prepare_out_dir

        validate_options(controller, switching, target_alpha, duration, spin_s)
        check_seed(seed)
        if scenario not in SCENARIOS:
            load_state_file(Path(scenario))  # validate before creating the output directory
        if controller != "smc":
            from harv_jax.commands.mc import build_controller

            build_controller(controller, policy, zeta)  # validate policy and zeta first
        out_dir = prepare_out_dir(out, force)
        res = run_fly(scenario, target_alpha, duration, seed, switching, spin_s, controller, policy, zeta)
        meta = {
            "controller": controller,
            "policy": (policy or DEFAULT_POLICY_SPEC) if controller != "smc" else None,
            "zeta_schedule": zeta if controller == "hybrid" else None,
            "switching": switching,
            "scenario": scenario,
            "seed": seed,
            "duration_s": duration,
            "dt_s": DT_S,
            "reference_rad": [target_alpha, 0.0, 0.0],
            "spin_s": spin_s if scenario == "spin" else None,
        }
        write_outputs(out_dir, res, meta)
        m = res["metrics"]
        t_rec = m["t_recover_s"]
        typer.echo(
            f"wrote {out_dir}/trajectory.csv, trajectory.png, sliding.png, metrics.json: outcome "
            f"{m['outcome_name']}"
            + (f", recovered {t_rec:.2f} s after engagement" if t_rec is not None else "")
        )
