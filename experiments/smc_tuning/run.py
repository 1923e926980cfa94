"""Short SMC gain study and the 256-run / spin evaluation behind ``experiments/smc_tuning/README.md``.

Parts (``--part``):
  tune     one-at-a-time sweep of every gain around the defaults on a *tuning* set of reset-bound
           states (seed 1). Gains are a traced pytree: one compile serves every gain set.
  ablate   structural options (static SMCConfig): sign vs boundary layer, no near-vertical mu
           handling, no conditional integration -- one compile each, same tuning set.
  eval     the defaults on the *evaluation* set: 256 reset-bound states (seed 0), alpha_d = 0.349 rad;
           outcome counts, recovery-time distribution, failures and envelope departures.
  spin     open-loop 30 s spin (figure) and the spin scenario (30 s spin, then 60 s of SMC).

Run: ``python experiments/smc_tuning/run.py --part all`` (CPU: a few minutes on 2 cores).
Writes ``smc_tuning_results.json`` and the PNGs in ``experiments/smc_tuning/results/``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control import SMCConfig, SMCGains, default_gains, make_smc
from harv_jax.dynamics import CONTROL_NAMES, WIND_STATE_NAMES
from harv_jax.evaluation import evaluate, summarize
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.metrics import compute_metrics
from harv_jax.evaluation.summary import metrics_to_dict
from harv_jax.task.scenarios import (
    SPIN_DURATION_S,
    open_loop_spin,
    sample_table_states,
    spin_check,
)
from harv_jax.task.spec import ALPHA_TARGET_RAD as DEFAULT_ALPHA_TARGET_RAD
from harv_jax.units import RAD_PER_DEG

HERE = Path(__file__).resolve().parent
FIG_DIR = HERE / "results"
RESULTS = HERE / "results" / "smc_tuning_results.json"
DT_S = 0.01
N_STEPS = 6000  # 60 s
REFERENCE = (DEFAULT_ALPHA_TARGET_RAD, 0.0, 0.0)


def make_batch_fn(cfg: SMCConfig, n_steps: int = N_STEPS, batched_params: bool = False):
    """jit(vmap) of a closed-loop run scored by the metrics, plus per-run controller diagnostics.

    Returns fn(gains, x0 [B, 10]) -> (RunMetrics [B], diag dict [B]); gains traced (no recompile).
    With ``batched_params`` the signature is fn(gains, x0 [B, 10], params [B]).
    """
    ref = jnp.asarray(REFERENCE)

    def one(gains: SMCGains, x0: jnp.ndarray, params=None):
        params = harv() if params is None else params
        ctrl = make_smc(cfg, gains)
        res = closed_loop(ctrl, params, x0, ref, jax.random.key(0), n_steps, DT_S)
        x_all = jnp.concatenate([res.traj.x_wind, res.x_final_wind[None]], axis=0)
        m = compute_metrics(x_all, res.traj.delta_rad, ref, params, DT_S, res.nonfinite)
        info = res.traj.info
        diag = {
            "guard_fraction": jnp.mean(info["guard_active"]),
            "mu_blend_fraction": jnp.mean(info["w_mu"] < 1.0),
            "max_cond": jnp.max(info["cond"]),
            "cmd_saturated_fraction": jnp.mean(info["saturated"]),
            "min_V_fps": jnp.min(x_all[:, 0]),
            "min_alpha_rad": jnp.min(x_all[:, 1]),
            "max_alpha_rad": jnp.max(x_all[:, 1]),
        }
        return m, diag

    if batched_params:
        return jax.jit(jax.vmap(one, in_axes=(None, 0, 0)))
    return jax.jit(jax.vmap(one, in_axes=(None, 0)))


def perturbed_aircraft(key: jax.Array, n: int):
    """A rough robustness set (not the project's domain randomization): every aero-table column
    scaled by U(0.9, 1.1), mass by U(0.95, 1.05), each inertia by U(0.9, 1.1)."""
    nominal = harv()
    k_aero, k_mass, k_inertia = jax.random.split(key, 3)
    aero = jax.random.uniform(k_aero, (n, nominal.aero_scale.shape[0]), minval=0.9, maxval=1.1)
    mass = jax.random.uniform(k_mass, (n,), minval=0.95, maxval=1.05)
    inertia = jax.random.uniform(k_inertia, (n, 4), minval=0.9, maxval=1.1)
    batch = jax.tree.map(lambda a: jnp.broadcast_to(a, (n, *jnp.shape(a))), nominal)
    return batch.replace(
        aero_scale=aero,
        mass_slug=batch.mass_slug * mass,
        Ixx=batch.Ixx * inertia[:, 0],
        Iyy=batch.Iyy * inertia[:, 1],
        Izz=batch.Izz * inertia[:, 2],
        Ixz=batch.Ixz * inertia[:, 3],
    )


def combined_variants() -> list[tuple[str, SMCGains]]:
    """Round 2: combinations of the softer settings that round 1 found equally reliable.

    "phi=0.2,K=0.5,gamma_band=45-60" is the chosen default (``harv_jax.control.default_gains``).
    """
    g0 = start_gains()

    def pc(v):
        return jnp.full((3,), v, dtype=jnp.float32)

    band_45_60 = {
        "gamma_lo_rad": jnp.asarray(45.0 * RAD_PER_DEG),
        "gamma_hi_rad": jnp.asarray(60.0 * RAD_PER_DEG),
    }
    return [
        ("start", g0),
        ("phi=0.2,K=0.5", g0.replace(phi_radps=pc(0.2), k_reach=pc(0.5))),
        ("phi=0.1,K=0.5", g0.replace(phi_radps=pc(0.1), k_reach=pc(0.5))),
        ("phi=0.2,K=0.5,eps=0.1", g0.replace(phi_radps=pc(0.2), k_reach=pc(0.5), eps_radps2=pc(0.1))),
        ("gamma_band=45-60", g0.replace(**band_45_60)),
        ("phi=0.1,K=0.5,gamma_band=45-60", g0.replace(phi_radps=pc(0.1), k_reach=pc(0.5), **band_45_60)),
        ("phi=0.2,K=0.5,gamma_band=45-60", g0.replace(phi_radps=pc(0.2), k_reach=pc(0.5), **band_45_60)),
    ]


def part_tune2(n: int, seed: int) -> list[dict]:
    x0 = sample_table_states(jax.random.key(seed), n)
    fn_nom = make_batch_fn(SMCConfig())
    fn_pert = make_batch_fn(SMCConfig(), batched_params=True)
    params = perturbed_aircraft(jax.random.key(seed + 100), n)
    rows = []
    for name, g in combined_variants():
        t0 = time.time()
        m, diag = jax.block_until_ready(fn_nom(g, x0))
        r = row(name, m, diag, time.time() - t0)
        m_p, diag_p = jax.block_until_ready(fn_pert(g, x0, params))
        r_p = row(name, m_p, diag_p, 0.0)
        r["perturbed"] = {
            k: r_p[k] for k in ("recovery_rate", "t_recover_median_s", "control_tv_rad_mean", "outcomes")
        }
        rows.append(r)
        print(
            f"tune2 {name:34s} rec {r['recovery_rate']:.3f} pert {r_p['recovery_rate']:.3f} "
            f"t50 {r['t_recover_median_s']} tv {r['control_tv_rad_mean']:.1f}",
            flush=True,
        )
    return rows


def start_gains() -> SMCGains:
    """Round-1 starting point: the untuned gains (lambda1 2, lambda2 0.5, K 1, eps 0.2, phi 0.05) with a
    60-75 deg mu/p_w blend band."""
    g = default_gains()

    def pc(v):
        return jnp.full((3,), v, dtype=jnp.float32)

    return g.replace(
        lambda1_ps=pc(2.0),
        lambda2_ps2=pc(0.5),
        k_reach=pc(1.0),
        eps_radps2=pc(0.2),
        phi_radps=pc(0.05),
        gamma_lo_rad=jnp.asarray(60.0 * RAD_PER_DEG, jnp.float32),
        gamma_hi_rad=jnp.asarray(75.0 * RAD_PER_DEG, jnp.float32),
    )


def gain_variants() -> list[tuple[str, SMCGains]]:
    """Round 1: one-at-a-time variations around the starting point."""
    g0 = start_gains()
    out = [("start", g0)]

    def per_channel(v):
        return jnp.full((3,), v, dtype=jnp.float32)

    for v in (1.0, 4.0):
        out.append((f"lambda1={v}", g0.replace(lambda1_ps=per_channel(v))))
    for v in (0.25, 1.0):
        out.append((f"lambda2={v}", g0.replace(lambda2_ps2=per_channel(v))))
    out.append(("lambda2=0 (no integral)", g0.replace(lambda2_ps2=per_channel(0.0))))
    for v in (0.5, 2.0, 4.0):
        out.append((f"K={v}", g0.replace(k_reach=per_channel(v))))
    for v in (0.05, 0.5):
        out.append((f"eps={v}", g0.replace(eps_radps2=per_channel(v))))
    for v in (0.02, 0.1, 0.2):
        out.append((f"phi={v}", g0.replace(phi_radps=per_channel(v))))
    for v in (2.0, 10.0):
        out.append((f"int_band={v}deg", g0.replace(int_band_rad=per_channel(v * RAD_PER_DEG))))
    for lo, hi in ((45.0, 60.0), (70.0, 85.0), (80.0, 89.0)):
        out.append(
            (
                f"gamma_band={lo:g}-{hi:g}deg",
                g0.replace(
                    gamma_lo_rad=jnp.asarray(lo * RAD_PER_DEG), gamma_hi_rad=jnp.asarray(hi * RAD_PER_DEG)
                ),
            )
        )
    for v in (0.5, 2.0):
        out.append((f"k_pw={v}", g0.replace(k_pw_ps=jnp.asarray(v))))
    for v in (1e2, 1e4):
        out.append((f"cond_max={v:g}", g0.replace(cond_max=jnp.asarray(v))))
    return out


def row(name: str, m, diag, seconds: float) -> dict:
    """One table row: recovery statistics and control-activity means."""
    s = summarize(m)
    rec = np.asarray(m.recovered)
    t_rec = np.asarray(m.t_recover_s)[rec]
    return {
        "name": name,
        "recovery_rate": s["recovery_rate"],
        "recovered_in_envelope_fraction": s["recovered_and_in_envelope_fraction"],
        "outcomes": s["outcome_counts"],
        "t_recover_median_s": float(np.median(t_rec)) if t_rec.size else None,
        "t_recover_p95_s": float(np.percentile(t_rec, 95)) if t_rec.size else None,
        "control_tv_rad_mean": float(np.asarray(m.control_tv_rad).sum(-1).mean()),
        "chatter_rad2_mean": float(np.asarray(m.chatter_index_rad2).sum(-1).mean()),
        "sat_position_mean": float(np.asarray(m.sat_position_fraction).max(-1).mean()),
        "altitude_loss_ft_median": float(np.median(np.asarray(m.altitude_loss_ft))),
        "guard_fraction_mean": float(np.asarray(diag["guard_fraction"]).mean()),
        "seconds": seconds,
    }


def part_tune(n: int, seed: int) -> list[dict]:
    x0 = sample_table_states(jax.random.key(seed), n)
    fn = make_batch_fn(SMCConfig())
    rows = []
    for name, g in gain_variants():
        t0 = time.time()
        m, diag = jax.block_until_ready(fn(g, x0))
        rows.append(row(name, m, diag, time.time() - t0))
        print(
            f"tune {name:28s} rec {rows[-1]['recovery_rate']:.3f} "
            f"t50 {rows[-1]['t_recover_median_s']} ({rows[-1]['seconds']:.1f} s)",
            flush=True,
        )
    return rows


def part_ablate(n: int, seed: int) -> list[dict]:
    x0 = sample_table_states(jax.random.key(seed), n)
    rows = []
    for name, cfg in (
        ("switching=sign (paper)", SMCConfig(switching="sign")),
        ("no near-vertical mu handling", SMCConfig(vertical_mu_handling=False)),
        ("no conditional integration", SMCConfig(freeze_integral_when_saturated=False)),
    ):
        t0 = time.time()
        m, diag = jax.block_until_ready(make_batch_fn(cfg)(default_gains(), x0))
        rows.append(row(name, m, diag, time.time() - t0))
        print(
            f"ablate {name:30s} rec {rows[-1]['recovery_rate']:.3f} ({rows[-1]['seconds']:.1f} s)",
            flush=True,
        )
    return rows


def part_eval(n: int, seed: int) -> dict:
    x0 = sample_table_states(jax.random.key(seed), n)
    t0 = time.time()
    m, diag = jax.block_until_ready(make_batch_fn(SMCConfig())(default_gains(), x0))
    seconds = time.time() - t0
    x0n = np.asarray(x0)
    rec = np.asarray(m.recovered)
    left = np.asarray(m.left_envelope)
    t_rec = np.asarray(m.t_recover_s)
    bins = [100, 400, 700, 1000, 1500]
    by_v = []
    for lo, hi in zip(bins[:-1], bins[1:], strict=True):
        sel = (x0n[:, 0] >= lo) & (x0n[:, 0] < hi)
        by_v.append(
            {
                "V0_fps": [lo, hi],
                "n": int(sel.sum()),
                "recovered": float(rec[sel].mean()),
                "t_recover_median_s": float(np.median(t_rec[sel & rec])) if (sel & rec).any() else None,
                "left_envelope": float(left[sel].mean()),
            }
        )

    def run_detail(i):
        return {
            "index": int(i),
            "x0": {k: float(v) for k, v in zip(WIND_STATE_NAMES, x0n[i], strict=True)},
            "metrics": metrics_to_dict(jax.tree.map(lambda a: a[i], m)),
            "diag": {k: float(np.asarray(v)[i]) for k, v in diag.items()},
        }

    failures = [run_detail(i) for i in np.flatnonzero(~rec)]
    departures = [run_detail(i) for i in np.flatnonzero(left)]
    hist_path = FIG_DIR / "smc_recovery_time_hist.png"
    _plot_hist(t_rec[rec], x0n[rec, 0], hist_path)
    worst = int(np.nanargmax(np.where(rec, t_rec, -1)))
    traj_path = FIG_DIR / "smc_slowest_recovery.png"
    _plot_run(x0[worst], traj_path, f"SMC, slowest recovery of the 256 (run {worst})")
    return {
        "n": n,
        "seed": seed,
        "seconds": seconds,
        "summary": dict(summarize(m)),
        "by_V0": by_v,
        "failures": failures,
        "departures": departures,
        "hist_png": str(hist_path.relative_to(HERE)),
        "slowest_png": str(traj_path.relative_to(HERE)),
        "departure_reasons": {
            "alpha_below_min": int((np.asarray(diag["min_alpha_rad"]) < -0.244).sum()),
            "alpha_above_max": int((np.asarray(diag["max_alpha_rad"]) > 1.571).sum()),
            "min_V_below_100fps": int((np.asarray(diag["min_V_fps"]) < 100).sum()),
        },
        "mean_guard_fraction": float(np.asarray(diag["guard_fraction"]).mean()),
        "mean_mu_blend_fraction": float(np.asarray(diag["mu_blend_fraction"]).mean()),
    }


def _cols(x: np.ndarray, d: np.ndarray) -> dict[str, np.ndarray]:
    c = {n: x[:, i] for i, n in enumerate(WIND_STATE_NAMES)}
    c.update({n: d[:, i] for i, n in enumerate(CONTROL_NAMES)})
    return c


def _plot_run(x0: jnp.ndarray, path: Path, title: str, every: int = 10) -> None:
    from harv_jax.plots.time_histories import plot_time_histories

    params = harv()
    res = jax.jit(
        lambda x: closed_loop(
            make_smc(),
            params,
            x,
            jnp.asarray(REFERENCE),
            jax.random.key(0),
            N_STEPS,
            DT_S,
            record_every=every,
        )
    )(x0)
    x = np.asarray(res.traj.x_wind)
    plot_time_histories(
        np.asarray(res.traj.t_s),
        {"SMC": _cols(x, np.asarray(res.traj.delta_rad))},
        path,
        title=title,
        references=dict(zip(("alpha", "beta", "mu"), REFERENCE, strict=True)),
    )


def _plot_hist(t_rec: np.ndarray, v0: np.ndarray, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    ax[0].hist(t_rec, bins=25, color="C0")
    ax[0].set_xlabel("recovery time t_rec [s]")
    ax[0].set_ylabel("runs")
    ax[1].scatter(v0, t_rec, s=6)
    ax[1].set_xlabel("V0 [ft/s]")
    ax[1].set_ylabel("t_rec [s]")
    for a in ax:
        a.grid(alpha=0.3)
    fig.suptitle("SMC recovery time, 256 reset-bound states, alpha_d = 0.349 rad")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def part_spin() -> dict:
    from harv_jax.plots.time_histories import plot_time_histories

    params = harv()
    n_spin = int(round(SPIN_DURATION_S / DT_S))
    xs, deltas, body, delta = jax.jit(lambda p: open_loop_spin(p, SPIN_DURATION_S, DT_S))(params)
    chk = spin_check(xs, DT_S)
    xs_n, d_n = np.asarray(xs), np.asarray(deltas)
    every = 10
    t_open = np.arange(n_spin + 1)[::every] * DT_S
    d_full = np.concatenate([d_n, d_n[-1:]], axis=0)
    open_path = FIG_DIR / "spin_open_loop.png"
    plot_time_histories(
        t_open,
        {"open loop, pro-spin controls": _cols(xs_n[::every], d_full[::every])},
        open_path,
        title="Open-loop spin: entry V 300 ft/s, alpha 0.9 rad, p = r = -0.5 rad/s; "
        "de -0.436, da +0.436, dr +0.524 rad",
    )
    ref = jnp.asarray(REFERENCE)
    m, traj = jax.jit(
        lambda b, d: evaluate(
            make_smc(), params, b, ref, jax.random.key(0), N_STEPS, DT_S, d, record_every=every
        )
    )(body, delta)
    t_all = np.concatenate([t_open[:-1], SPIN_DURATION_S + np.asarray(traj.t_s)])
    x_all = np.concatenate([xs_n[::every][:-1], np.asarray(traj.x_wind)])
    d_all = np.concatenate([d_full[::every][:-1], np.asarray(traj.delta_rad)])
    rec_path = FIG_DIR / "spin_smc_recovery.png"
    plot_time_histories(
        t_all,
        {"SMC": _cols(x_all, d_all)},
        rec_path,
        title="Spin scenario: 30 s pro-spin, then SMC (alpha_d = 0.349 rad)",
        references=dict(zip(("alpha", "beta", "mu"), REFERENCE, strict=True)),
        t_marker_s=SPIN_DURATION_S,
    )
    spin = {f.name: float(np.asarray(getattr(chk, f.name))) for f in dataclasses.fields(chk)}
    return {
        "spin_check_last_20s": spin,
        "state_at_engagement": {k: float(v) for k, v in zip(WIND_STATE_NAMES, xs_n[-1], strict=True)},
        "smc_metrics": metrics_to_dict(m),
        "open_loop_png": str(open_path.relative_to(HERE)),
        "recovery_png": str(rec_path.relative_to(HERE)),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--part", choices=("tune", "tune2", "ablate", "eval", "spin", "all"), default="all")
    ap.add_argument("--n-tune", type=int, default=64)
    ap.add_argument("--seed-tune", type=int, default=1)
    ap.add_argument("--n-tune2", type=int, default=128)
    ap.add_argument("--n-eval", type=int, default=256)
    ap.add_argument("--seed-eval", type=int, default=0)
    args = ap.parse_args()
    FIG_DIR.mkdir(exist_ok=True)
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    parts = ("tune", "tune2", "ablate", "eval", "spin") if args.part == "all" else (args.part,)
    for part in parts:
        if part == "tune":
            results["tune"] = {
                "n": args.n_tune,
                "seed": args.seed_tune,
                "rows": part_tune(args.n_tune, args.seed_tune),
            }
        elif part == "tune2":
            results["tune2"] = {
                "n": args.n_tune2,
                "seed": args.seed_tune,
                "rows": part_tune2(args.n_tune2, args.seed_tune),
            }
        elif part == "ablate":
            results["ablate"] = {
                "n": args.n_tune,
                "seed": args.seed_tune,
                "rows": part_ablate(args.n_tune, args.seed_tune),
            }
        elif part == "eval":
            results[f"eval_n{args.n_eval}_seed{args.seed_eval}"] = part_eval(args.n_eval, args.seed_eval)
        elif part == "spin":
            results["spin"] = part_spin()
        RESULTS.write_text(json.dumps(results, indent=1) + "\n")
    print(f"wrote {RESULTS}")
    for key, val in results.items():
        if key.startswith("eval"):
            s = val["summary"]
            print(
                key,
                "recovered",
                s["recovery_rate"],
                s["outcome_counts"],
                "t_rec",
                s["t_recover_s_percentiles"],
            )
    if "spin" in results:
        print(
            "spin",
            results["spin"]["smc_metrics"]["outcome_name"],
            results["spin"]["smc_metrics"]["t_recover_s"],
        )


if __name__ == "__main__":
    main()
