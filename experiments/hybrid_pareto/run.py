"""A fair comparison: SMC gain settings as a Pareto front, hybrids and RL-only as points.

Every controller flies the same Monte Carlo runs (``sample_mc_inputs`` with one seed: common random initial
states and aircraft), 60 s, alpha_d = 0.349 rad, the package's recovery criterion. Per controller: recovery
rate, median and p95 recovery time (over the recovered runs; also the p95 over all runs with an unrecovered
run counted as never, i.e. None once more than 5% fail), median control total variation (rad, summed over the
three surfaces) and median altitude loss (ft, h0 - min h over the run, every run).

The SMC sweep compiles once: the gains are an argument of the jitted function (``SMCGains`` is a traced
pytree), and the compiled executable is called for every setting (a shape or dtype change would fail, not
recompile). The hybrids with the same schedule and policy share one compile the same way (``HybridGains``).

Usage (from the repository root)::

    python experiments/hybrid_pareto/run.py --runs 1000 --seed 0            # nominal aircraft
    python experiments/hybrid_pareto/run.py --runs 1000 --seed 0 --randomize
    # add a point later (e.g. the in-loop-trained hybrid) without re-running the rest:
    python experiments/hybrid_pareto/run.py --runs 1000 --seed 0 --append \\
        --extra "in-loop hybrid=runs/inloop/policy.npz:gated"
    python experiments/hybrid_pareto/run.py --plot-only                     # redraw from the JSON

``--extra NAME=POLICY[:SCHEDULE]``: SCHEDULE is a ``ZETA_SCHEDULES`` name (hybrid with that schedule and the
CLI's default hybrid gains) or ``rl`` (RL-only); default ``gated``. POLICY is anything ``--policy`` takes.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

# ---- library names (one block: the package is being refactored; fix paths here) ----
from harv_jax.aircraft import harv
from harv_jax.control.hybrid.law import (
    PAPER_E_OFF_RAD,
    PAPER_E_ON_RAD,
    ZETA_SCHEDULES,
    HybridConfig,
    default_hybrid_gains,
    make_hybrid,
)
from harv_jax.control.rl import make_rl_controller
from harv_jax.control.smc import SMCConfig, SMCGains, default_gains, make_smc
from harv_jax.evaluation.closed_loop import closed_loop, score
from harv_jax.evaluation.montecarlo.rollout import MCInputs, sample_mc_inputs
from harv_jax.optimal.outputs import cpu_model
from harv_jax.policy import resolve_policy
from harv_jax.task.criteria import OUTCOME_NAMES
from harv_jax.task.spec import ALPHA_TARGET_RAD, BETA_TARGET_RAD, DT_S, H0_FT, MU_TARGET_RAD
from harv_jax.units import RAD_PER_DEG

# -------------------------------------------------------------------------------------

HERE = Path(__file__).resolve().parent
RESULTS_DIR = HERE / "results"
DURATION_S = 60.0
CHUNK = 250
#: Safety bar for the "fastest safe SMC setting": at least 99.9% of the runs recovered.
SAFE_RECOVERY_RATE = 0.999
DEFAULT_POLICY = "shipped:recovery"
IN_LOOP_SLOT = "hybrid, in-loop-trained"

# ------------------------------------------------------------------------------------------ evaluation


def make_eval(build: Callable[[Any], Any], n_steps: int) -> Callable[..., dict[str, jnp.ndarray]]:
    """jit(fn(gains, inputs [chunk], reference [3]) -> per-run metrics); ``build(gains)`` -> Controller."""

    def one(gains: Any, params: Any, x0: jnp.ndarray, key: jax.Array, ref: jnp.ndarray) -> dict:
        res = closed_loop(build(gains), params, x0, ref, key, n_steps, DT_S)
        m, _ = score(res, ref, params, DT_S)
        return {
            "outcome": m.outcome,
            "recovered": m.recovered,
            "t_recover_s": m.t_recover_s,
            "control_tv_rad": jnp.sum(m.control_tv_rad),
            "altitude_loss_ft": m.altitude_loss_ft,
        }

    def fn(gains: Any, inputs: MCInputs, ref: jnp.ndarray) -> dict:
        return jax.vmap(lambda p, x, k: one(gains, p, x, k, ref))(inputs.params, inputs.x0_wind, inputs.keys)

    return jax.jit(fn)


def chunks(inputs: MCInputs, size: int) -> list[MCInputs]:
    """Split the runs into equal chunks (the last padded with run 0; padding is cut off afterwards)."""
    n = int(inputs.x0_wind.shape[0])
    size = max(1, min(size, n))
    n_chunks = -(-n // size)
    pad = n_chunks * size - n
    padded = jax.tree.map(
        lambda a: jnp.concatenate([a, jnp.repeat(a[:1], pad, axis=0)]) if pad else a, inputs
    )
    return [jax.tree.map(lambda a, i=i: a[i * size : (i + 1) * size], padded) for i in range(n_chunks)]


class Runner:
    """One compiled executable per controller structure; ``__call__(gains)`` flies every run."""

    def __init__(self, build: Callable[[Any], Any], example_gains: Any, inputs: MCInputs, n_steps: int):
        self.n = int(inputs.x0_wind.shape[0])
        self.parts = chunks(inputs, CHUNK)
        self.ref = jnp.asarray([ALPHA_TARGET_RAD, BETA_TARGET_RAD, MU_TARGET_RAD], inputs.x0_wind.dtype)
        t0 = time.perf_counter()
        self.compiled = make_eval(build, n_steps).lower(example_gains, self.parts[0], self.ref).compile()
        self.compile_s = time.perf_counter() - t0

    def __call__(self, gains: Any) -> tuple[dict[str, np.ndarray], float]:
        t0 = time.perf_counter()
        outs = [jax.device_get(self.compiled(gains, part, self.ref)) for part in self.parts]
        out = {k: np.concatenate([o[k] for o in outs])[: self.n] for k in outs[0]}
        return out, time.perf_counter() - t0


def _pct(a: np.ndarray, q: float) -> float | None:
    return float(np.percentile(a, q)) if a.size else None


def stats(out: dict[str, np.ndarray]) -> dict[str, Any]:
    """Recovery rate, recovery-time percentiles (recovered runs; all runs, unrecovered = never), medians."""
    rec = np.asarray(out["recovered"], bool)
    t = np.asarray(out["t_recover_s"], np.float64)
    never = 1e9  # an unrecovered run: later than any recovery (inf would make the interpolation NaN)
    p95_all = float(np.percentile(np.where(rec, t, never), 95))
    outcome = np.asarray(out["outcome"])
    tv = np.asarray(out["control_tv_rad"], np.float64)
    alt = np.asarray(out["altitude_loss_ft"], np.float64)
    return {
        "recovery_rate": float(rec.mean()),
        "not_recovered": int((~rec).sum()),
        "outcomes": {name: int((outcome == code).sum()) for code, name in enumerate(OUTCOME_NAMES)},
        "t_recover_p50_s": _pct(t[rec], 50),
        "t_recover_p95_s": _pct(t[rec], 95),
        "t_recover_p95_all_runs_s": p95_all if p95_all < never else None,
        "control_tv_rad_p50": float(np.median(tv)),
        "control_tv_rad_mean": float(np.mean(tv)),
        "altitude_loss_ft_p50": float(np.median(alt)),
        "altitude_loss_ft_p95": float(np.percentile(alt, 95)),
    }


# ------------------------------------------------------------------------------------------ the sweep


def smc_settings() -> list[tuple[str, dict[str, float], SMCGains]]:
    """SMC gain settings: the default, one knob at a time (K, eps, phi, lambda1, lambda2), joint scalings of
    the reaching law and surface, and the tuning study's starting point (``experiments/smc_tuning.py``)."""
    g0 = default_gains()
    dtype = g0.k_reach.dtype
    knob = {
        "K": "k_reach", "eps": "eps_radps2", "phi": "phi_radps", "lambda1": "lambda1_ps",
        "lambda2": "lambda2_ps2",
    }  # fmt: skip
    base = {"K": 0.5, "eps": 0.2, "phi": 0.2, "lambda1": 2.0, "lambda2": 0.5}

    def make(name: str, **changes: float) -> tuple[str, dict[str, float], SMCGains]:
        band = changes.pop("gamma_band_deg", None)
        values = {**base, **changes}
        g = g0.replace(**{knob[k]: jnp.full((3,), v, dtype) for k, v in values.items()})
        if band is not None:
            g = g.replace(
                gamma_lo_rad=jnp.asarray(band[0] * RAD_PER_DEG, dtype),
                gamma_hi_rad=jnp.asarray(band[1] * RAD_PER_DEG, dtype),
            )
        values["gamma_band_deg"] = list(band) if band is not None else [45.0, 60.0]
        return name, values, g

    return [
        make("default"),
        make("K 0.25", K=0.25),
        make("K 1", K=1.0),
        make("K 2", K=2.0),
        make("K 4", K=4.0),
        make("eps 0.1", eps=0.1),
        make("eps 0.4", eps=0.4),
        make("eps 0.8", eps=0.8),
        make("phi 0.02", phi=0.02),
        make("phi 0.05", phi=0.05),
        make("phi 0.1", phi=0.1),
        make("phi 0.4", phi=0.4),
        make("lambda1 0.5", lambda1=0.5),
        make("lambda1 1", lambda1=1.0),
        make("lambda1 1.5", lambda1=1.5),
        make("lambda1 2.5", lambda1=2.5),
        make("lambda1 3", lambda1=3.0),
        make("lambda1 4", lambda1=4.0),
        make("lambda1 6", lambda1=6.0),
        make("lambda2 0", lambda2=0.0),
        make("lambda2 0.25", lambda2=0.25),
        make("lambda2 1", lambda2=1.0),
        make("reach x0.5 (K 0.25, eps 0.1)", K=0.25, eps=0.1),
        make("reach x2 (K 1, eps 0.4)", K=1.0, eps=0.4),
        make("reach x2, phi 0.4", K=1.0, eps=0.4, phi=0.4),
        make("lambda x1.5 (3, 0.75)", lambda1=3.0, lambda2=0.75),
        make("lambda1 3, phi 0.4", lambda1=3.0, phi=0.4),
        make("lambda1 3, K 1, phi 0.4", lambda1=3.0, K=1.0, phi=0.4),
        make("lambda1 1.5, K 1, eps 0.4", lambda1=1.5, K=1.0, eps=0.4),
        make("K 1, phi 0.1", K=1.0, phi=0.1),
        make("aggressive (lambda1 4, K 2, eps 0.4, phi 0.1)", lambda1=4.0, K=2.0, eps=0.4, phi=0.1),
        make("soft (lambda1 3, K 0.25, eps 0.1, phi 0.4)", lambda1=3.0, K=0.25, eps=0.1, phi=0.4),
        make("tuning start (K 1, phi 0.05, band 60-75)", K=1.0, phi=0.05, gamma_band_deg=(60.0, 75.0)),
    ]


def paper_hybrid_gains() -> Any:
    """The paper's tube (e_on 0.05 rad, e_off 0.02 rad on every channel) and zeta = 0 inside it (floor 0)."""
    g = default_hybrid_gains()
    dtype = g.e_on_rad.dtype
    return g.replace(
        e_on_rad=jnp.asarray(PAPER_E_ON_RAD, dtype),
        e_off_rad=jnp.asarray(PAPER_E_OFF_RAD, dtype),
        zeta_floor=jnp.asarray(0.0, dtype),
    )


def default_points() -> list[dict[str, Any]]:
    """The non-SMC controllers: (name, policy, loop, gains label). ``loop`` is ``rl`` or a zeta schedule."""
    return [
        {"name": "RL-only", "policy": DEFAULT_POLICY, "loop": "rl", "gains": "-"},
        {"name": "hybrid, paper (hysteresis, tube 0.05, floor 0)", "policy": DEFAULT_POLICY,
         "loop": "hysteresis", "gains": "paper"},
        {"name": "hybrid, hysteresis (CLI gains)", "policy": DEFAULT_POLICY, "loop": "hysteresis",
         "gains": "default"},
        {"name": "hybrid, continuous (CLI default)", "policy": DEFAULT_POLICY, "loop": "continuous",
         "gains": "default"},
        {"name": "hybrid, gated", "policy": DEFAULT_POLICY, "loop": "gated", "gains": "default"},
        {"name": "hybrid, gated, paper-partial policy", "policy": "shipped:paper-partial", "loop": "gated",
         "gains": "default"},
    ]  # fmt: skip


def parse_extra(text: str) -> dict[str, Any]:
    """``NAME=POLICY[:SCHEDULE]`` -> point dict (SCHEDULE in ZETA_SCHEDULES or ``rl``; default ``gated``)."""
    name, sep, rest = text.partition("=")
    if not sep or not name or not rest:
        raise SystemExit(f"--extra {text!r}: expected NAME=POLICY[:SCHEDULE]")
    policy, _, loop = rest.rpartition(":")
    if loop not in (*ZETA_SCHEDULES, "rl"):
        policy, loop = rest, "gated"
    return {"name": name, "policy": policy, "loop": loop, "gains": "default", "extra": True}


def point_builder(policy: str, loop: str) -> tuple[Callable[[Any], Any], Any]:
    """(build(gains) -> Controller, example gains) for RL-only or a hybrid schedule with ``policy``."""
    act = resolve_policy(policy).deterministic
    if loop == "rl":
        return (lambda _g: make_rl_controller(act)), jnp.zeros((), jnp.float32)
    cfg = HybridConfig(schedule=loop)
    return (lambda g: make_hybrid(act, cfg, g)), default_hybrid_gains()


# ------------------------------------------------------------------------------------------ front + plot


def front(xs: list[float], ys: list[float]) -> list[int]:
    """Indices of the non-dominated points (minimize both), sorted by x."""
    idx = []
    for i, (x, y) in enumerate(zip(xs, ys, strict=True)):
        dominated = any(
            (xs[j] <= x and ys[j] <= y) and (xs[j] < x or ys[j] < y) for j in range(len(xs)) if j != i
        )
        if not dominated:
            idx.append(i)
    return sorted(idx, key=lambda i: (xs[i], ys[i]))


def plot(result: dict[str, Any], path: Path) -> None:
    """2x2: median (top) / p95 (bottom) recovery time vs median control TV (left) / altitude loss (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    smc = result["smc_settings"]
    points = [p for p in result["points"] if p.get("stats")]
    fig, axes = plt.subplots(2, 2, figsize=(13, 10))
    markers = ["o", "s", "D", "^", "v", "P", "X", "*", "h", "<", ">"]
    for row, tkey in enumerate(("t_recover_p50_s", "t_recover_p95_s")):
        for col, xkey in enumerate(("control_tv_rad_p50", "altitude_loss_ft_p50")):
            ax = axes[row, col]
            safe = [s for s in smc if s["stats"]["recovery_rate"] >= SAFE_RECOVERY_RATE and s["stats"][tkey]]
            unsafe = [s for s in smc if s not in safe and s["stats"][tkey]]
            xs = [s["stats"][xkey] for s in safe]
            ys = [s["stats"][tkey] for s in safe]
            ax.scatter(xs, ys, c="0.55", s=22, label=f"SMC setting, recovery >= {SAFE_RECOVERY_RATE:.1%}")
            if unsafe:
                ax.scatter(
                    [s["stats"][xkey] for s in unsafe], [s["stats"][tkey] for s in unsafe], s=22,
                    facecolors="none", edgecolors="0.55", label="SMC setting, recovery below that",
                )  # fmt: skip
                for s in unsafe:
                    ax.annotate(
                        f"{s['stats']['recovery_rate']:.1%}", (s["stats"][xkey], s["stats"][tkey]),
                        fontsize=6, color="0.4", xytext=(3, -8), textcoords="offset points",
                    )  # fmt: skip
            f = front(xs, ys)
            fx, fy = [xs[i] for i in f], [ys[i] for i in f]
            ax.plot(fx, fy, "-", c="k", lw=1.2, label="SMC front (non-dominated)")
            for i in f:
                ax.annotate(safe[i]["name"], (xs[i], ys[i]), fontsize=6.5, xytext=(4, 3),
                            textcoords="offset points")  # fmt: skip
            for d in [s for s in smc if s["name"] == "default"]:
                ax.scatter([d["stats"][xkey]], [d["stats"][tkey]], marker="o", s=70, facecolors="none",
                           edgecolors="k", lw=1.5, label="SMC default gains")  # fmt: skip
            for k, p in enumerate(points):
                st = p["stats"]
                if st[tkey] is None:
                    continue
                lbl = f"{p['name']} ({st['recovery_rate']:.1%})"
                ax.scatter([st[xkey]], [st[tkey]], marker=markers[k % len(markers)], s=70, color=f"C{k}",
                           edgecolors="k", lw=0.5, label=lbl, zorder=5)  # fmt: skip
            # axes span the safe settings and the points; settings outside that box are listed, not drawn
            bx = xs + [p["stats"][xkey] for p in points if p["stats"][tkey] is not None]
            by = ys + [p["stats"][tkey] for p in points if p["stats"][tkey] is not None]
            (x0, x1), (y0, y1) = (min(bx), max(bx)), (min(by), max(by))
            ax.set_xlim(x0 - 0.08 * (x1 - x0), x1 + 0.08 * (x1 - x0))
            ax.set_ylim(y0 - 0.08 * (y1 - y0), y1 + 0.08 * (y1 - y0))
            off = [s for s in unsafe if not (x0 <= s["stats"][xkey] <= x1 and y0 <= s["stats"][tkey] <= y1)]
            if off:
                txt = "off the axes:\n" + "\n".join(
                    f"{s['name']}: {s['stats']['recovery_rate']:.1%}, ({s['stats'][xkey]:.3g}, "
                    f"{s['stats'][tkey]:.3g})"
                    for s in off
                )
                ax.text(0.99, 0.99, txt, transform=ax.transAxes, ha="right", va="top", fontsize=6.5, c="0.35")
            ax.set_xlabel("median control TV per run [rad]" if col == 0 else "median altitude loss [ft]")
            ax.set_ylabel(("median" if row == 0 else "p95") + " recovery time, recovered runs [s]")
            ax.grid(alpha=0.3)
    h, lab = axes[0, 0].get_legend_handles_labels()
    missing = [p["name"] for p in result["points"] if not p.get("stats")]
    fig.legend(h, lab, loc="lower center", ncol=3, fontsize=8, frameon=False)
    cond = "randomized aircraft" if result["randomize"] else "nominal aircraft"
    title = (
        f"Recovery time vs control activity and altitude loss: {result['runs']} runs, "
        f"seed {result['seed']}, {cond}, {result['duration_s']:.0f} s, "
        f"alpha_d {result['target_alpha_rad']} rad"
    )
    if missing:
        title += "\nnot yet measured: " + ", ".join(missing)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0.1, 1, 0.97))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def table(result: dict[str, Any]) -> str:
    """Markdown table of every SMC setting and point (front members and the fastest safe setting marked)."""
    front_names = set(result.get("smc_front_t50_vs_control_tv_rad_p50", []))
    front_alt = set(result.get("smc_front_t50_vs_altitude_loss_ft_p50", []))
    fastest = result.get("fastest_safe_smc", {}).get("name")
    lines = [
        "| controller | recovered | t_rec p50 s | t_rec p95 s | p95 all runs s | TV p50 rad "
        "| alt. loss p50 ft | front |",
        "|---|---:|---:|---:|---:|---:|---:|---|",
    ]

    def num(v: float | None, fmt: str) -> str:
        return "–" if v is None else format(v, fmt)

    def line(name: str, st: dict[str, Any], mark: str) -> str:
        return (
            f"| {name} | {st['recovery_rate']:.1%} | {num(st['t_recover_p50_s'], '.1f')} | "
            f"{num(st['t_recover_p95_s'], '.1f')} | {num(st['t_recover_p95_all_runs_s'], '.1f')} | "
            f"{st['control_tv_rad_p50']:.2f} | {st['altitude_loss_ft_p50']:.0f} | {mark} |"
        )

    for p in result["points"]:
        if p.get("stats"):
            lines.append(line(f"**{p['name']}** ({p['policy']})", p["stats"], ""))
        else:
            lines.append(f"| **{p['name']}** | not yet measured | | | | | | |")
    for s in result["smc_settings"]:
        marks = [m for m, on in (("TV", s["name"] in front_names), ("alt", s["name"] in front_alt),
                                 ("fastest safe", s["name"] == fastest)) if on]  # fmt: skip
        lines.append(line(f"SMC {s['name']}", s["stats"], ", ".join(marks)))
    return "\n".join(lines)


# ------------------------------------------------------------------------------------------ main


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0, help="Monte Carlo seed (not a tuning seed: those were 1).")
    ap.add_argument("--randomize", action="store_true", help="Randomized aircraft (the env's ranges).")
    ap.add_argument("--duration", type=float, default=DURATION_S, help="Run length, s.")
    ap.add_argument("--extra", action="append", default=[], help="NAME=POLICY[:SCHEDULE] (repeatable).")
    ap.add_argument("--append", action="store_true", help="Only fly --extra points; merge into the JSON.")
    ap.add_argument("--no-points", action="store_true", help="Skip the default non-SMC points.")
    ap.add_argument("--no-smc", action="store_true", help="Skip the SMC sweep.")
    ap.add_argument("--plot-only", action="store_true", help="Redraw the PNG from the JSON.")
    ap.add_argument("--table", action="store_true", help="Print the JSON as a markdown table.")
    ap.add_argument("--out", type=Path, default=None, help="JSON path (default results/pareto*.json).")
    args = ap.parse_args()
    suffix = "_randomized" if args.randomize else ""
    tag = "" if args.runs == 1000 else f"_n{args.runs}"
    out_json = args.out or RESULTS_DIR / f"pareto{suffix}{tag}.json"
    out_png = out_json.with_suffix(".png")
    out_json.parent.mkdir(parents=True, exist_ok=True)
    if args.table:
        print(table(json.loads(out_json.read_text())))
        return
    if args.plot_only:
        plot(json.loads(out_json.read_text()), out_png)
        print(f"wrote {out_png}")
        return

    n_steps = int(round(args.duration / DT_S))
    inputs = sample_mc_inputs(
        jax.random.key(args.seed), args.runs, harv(), randomize=args.randomize, h0_ft=H0_FT
    )
    command = "python " + " ".join(shlex.quote(a) for a in sys.argv)
    if args.append and out_json.exists():
        result = json.loads(out_json.read_text())
        if (result["runs"], result["seed"], result["randomize"]) != (args.runs, args.seed, args.randomize):
            raise SystemExit(f"{out_json} was made with other runs/seed/randomize")
        result["commands"].append(command)
    else:
        result = {
            "runs": args.runs, "seed": args.seed, "randomize": args.randomize, "duration_s": n_steps * DT_S,
            "dt_s": DT_S, "h0_ft": H0_FT, "target_alpha_rad": ALPHA_TARGET_RAD,
            "criterion": "package default: |e_alpha| < 2 deg, |e_beta| < 1 deg, |e_mu| < 2 deg, ||omega|| < "
            "0.17 rad/s at every sample of the last 10 s; t_rec = time from which it holds to the end",
            "unrecovered_runs": "t_recover_p50_s / t_recover_p95_s are over the recovered runs only; "
            "t_recover_p95_all_runs_s counts an unrecovered run as never recovered (None if > 5% fail); "
            "control TV and altitude loss are over all runs",
            "control_tv": "total variation of the deflections over the run, summed over the 3 surfaces, rad",
            "altitude_loss": "h(0) - min h over the run, ft",
            "safe_recovery_rate": SAFE_RECOVERY_RATE,
            "cpu_model": cpu_model(), "cpu_count": os.cpu_count(), "jax_version": jax.__version__,
            "backend": jax.default_backend(), "commands": [command],
            "smc_settings": [], "points": [],
        }  # fmt: skip

    todo = [] if (args.append or args.no_points) else default_points()
    todo += [parse_extra(e) for e in args.extra]
    if not args.append and not any(p["name"] == IN_LOOP_SLOT for p in todo):
        result["points"].append({"name": IN_LOOP_SLOT, "policy": None, "loop": "gated", "stats": None,
                                 "note": "slot: not trained yet; add it with --append --extra "
                                 f"'{IN_LOOP_SLOT}=POLICY:SCHEDULE'"})  # fmt: skip
    runners: dict[tuple[str, str], Runner] = {}
    for p in todo:
        key = (p["policy"], p["loop"])
        if key not in runners:
            build, example = point_builder(*key)
            runners[key] = Runner(build, example, inputs, n_steps)
            print(f"[pts] compiled {key} in {runners[key].compile_s:.1f} s", flush=True)
        gains = {"paper": paper_hybrid_gains, "default": default_hybrid_gains}.get(p["gains"])
        out, wall = runners[key](gains() if gains and p["loop"] != "rl" else jnp.zeros((), jnp.float32))
        st = stats(out)
        entry = {**p, "stats": st, "run_s": wall, "compile_s": runners[key].compile_s}
        result["points"] = [q for q in result["points"] if q["name"] != p["name"]] + [entry]
        t50 = st["t_recover_p50_s"]
        t50_txt = "-" if t50 is None else f"{t50:.1f}"
        print(
            f"[pts] {p['name']:44s} rec {st['recovery_rate']:.3f} t50 {t50_txt} "
            f"tv {st['control_tv_rad_p50']:.2f} alt {st['altitude_loss_ft_p50']:.0f} ({wall:.0f} s)",
            flush=True,
        )
        write(result, out_json)

    if not args.append and not args.no_smc:
        _, _, g_example = smc_settings()[0]
        runner = Runner(lambda g: make_smc(SMCConfig(), g), g_example, inputs, n_steps)
        print(f"[smc] compiled once in {runner.compile_s:.1f} s", flush=True)
        result["smc_compile_s"] = runner.compile_s
        for name, values, g in smc_settings():
            out, wall = runner(g)
            st = stats(out)
            result["smc_settings"].append({"name": name, "gains": values, "stats": st, "run_s": wall})
            print(f"[smc] {name:44s} rec {st['recovery_rate']:.3f} t50 {st['t_recover_p50_s'] or 0:.1f} "
                  f"t95 {st['t_recover_p95_s'] or 0:.1f} tv {st['control_tv_rad_p50']:.2f} "
                  f"alt {st['altitude_loss_ft_p50']:.0f} ({wall:.0f} s)", flush=True)  # fmt: skip
            write(result, out_json)

    write(result, out_json)
    if result["smc_settings"]:
        plot(result, out_png)
        print(f"wrote {out_json}, {out_png}")


def write(result: dict[str, Any], path: Path) -> None:
    """Write the JSON (summary of the SMC front and the fastest safe setting included)."""
    smc = result["smc_settings"]
    safe = [
        s for s in smc if s["stats"]["recovery_rate"] >= SAFE_RECOVERY_RATE and s["stats"]["t_recover_p50_s"]
    ]
    if safe:
        fastest = min(safe, key=lambda s: s["stats"]["t_recover_p50_s"])
        result["fastest_safe_smc"] = {"by": "t_recover_p50_s", "name": fastest["name"]}
        for xkey in ("control_tv_rad_p50", "altitude_loss_ft_p50"):
            xs = [s["stats"][xkey] for s in safe]
            ys = [s["stats"]["t_recover_p50_s"] for s in safe]
            result[f"smc_front_t50_vs_{xkey}"] = [safe[i]["name"] for i in front(xs, ys)]
    path.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
