"""Where the simplex hybrid's control TV goes, and the deadline hold that cuts it.

    python experiments/hybrid_simplex/hold_study.py --out experiments/hybrid_simplex/results/hold_study.json

On Monte Carlo key 123 (the tuning key; 1000 runs, 60 s, nominal unless ``--randomize``) with ``--policy``
(default ``shipped:fast``):

1. ``decomposition``: the SMC, RL-only and the simplex hybrid without the hold on the
   same runs, their mean TV per class of run (no hand-over, box, deadline); for the deadline hand-overs the
   TV before and after the hand-over (all three controllers split at the hybrid's hand-over step) and the
   state at the hand-over (V, ||omega||, |errors|).
2. ``variants``: the hybrid with each hold setting of ``VARIANTS``: recovered, TV, recovery times, hand-overs.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft.params import harv
from harv_jax.control.hybrid.law import HybridConfig, default_hybrid_gains, make_hybrid
from harv_jax.control.hybrid.settings import HybridGains
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.dynamics.state import vt_fps
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs, simplex_summary
from harv_jax.policy import resolve_policy
from harv_jax.task.criteria import omega_norm_radps, tracking_errors
from harv_jax.task.spec import ALPHA_TARGET_RAD, DT_S

N_STEPS = 6000
#: Runs per compiled call: the chunk these results were made with (``--chunk 250``).
CHUNK = 250
#: hold settings: (speed ft/s, ||omega|| rad/s, until s); speed 0: no hold.
VARIANTS: dict[str, tuple[float, float, float]] = {
    "none (no hold)": (0.0, 0.0, 0.0),
    "200 ft/s, 0.5 rad/s, 30 s": (200.0, 0.5, 30.0),
    "200 ft/s, 0.5 rad/s, 25 s": (200.0, 0.5, 25.0),
    "250 ft/s, 0.5 rad/s, 30 s (the default)": (250.0, 0.5, 30.0),
    "300 ft/s, 0.3 rad/s, 30 s": (300.0, 0.3, 30.0),
    "300 ft/s, 0.5 rad/s, 30 s": (300.0, 0.5, 30.0),
    "300 ft/s, 1.0 rad/s, 30 s": (300.0, 1.0, 30.0),
    "300 ft/s, 0.5 rad/s, 35 s": (300.0, 0.5, 35.0),
    "400 ft/s, 0.5 rad/s, 30 s": (400.0, 0.5, 30.0),
}


def with_hold(speed_fps: float, rate_radps: float, until_s: float) -> HybridGains:
    """``default_hybrid_gains()`` with these hold settings."""
    g = default_hybrid_gains()
    s = g.simplex
    return g.replace(
        simplex=s.replace(
            hold_speed_fps=jnp.full_like(s.hold_speed_fps, speed_fps),
            hold_rate_radps=jnp.full_like(s.hold_rate_radps, rate_radps),
            hold_until_s=jnp.full_like(s.hold_until_s, until_s),
        )
    )


def _stats(out) -> dict:
    rec = np.asarray(out.metrics.recovered)
    tv = np.asarray(out.metrics.control_tv_rad, np.float64).sum(-1)
    t = np.asarray(out.metrics.t_recover_s, np.float64)[rec]
    res = {
        "recovered": float(rec.mean()), "lost_runs": int((~rec).sum()), "tv_mean_rad": float(tv.mean()),
        "tv_p50_rad": float(np.median(tv)), "t_rec_p50_s": float(np.median(t)),
        "t_rec_p95_s": float(np.percentile(t, 95)),
    }  # fmt: skip
    handed = simplex_summary(out.info_means).get("handover_run_fraction", {})
    res.update({f"handover_{r}_runs": handed[r] for r in ("box", "deadline") if r in handed})
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--policy", default="shipped:fast")
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=123)
    ap.add_argument("--randomize", action="store_true")
    ap.add_argument("--split-runs", type=int, default=200, help="deadline runs flown again for the split")
    a = ap.parse_args()
    inputs = sample_mc_inputs(jax.random.key(a.seed), a.runs, harv(), randomize=a.randomize)
    ref = jnp.array([ALPHA_TARGET_RAD, 0.0, 0.0])
    act = resolve_policy(a.policy).deterministic
    hybrid = make_hybrid(act, HybridConfig(schedule="simplex"), with_hold(*VARIANTS["none (no hold)"]))
    opts = ControllerOptions(policy=a.policy)
    ctrls = {"smc": build_controller("smc", opts), "rl": build_controller("rl", opts), "hybrid": hybrid}
    outs = {k: run_mc(c, inputs, ref, N_STEPS, chunk_size=CHUNK)[0] for k, c in ctrls.items()}
    tv = {k: np.asarray(o.metrics.control_tv_rad, np.float64).sum(-1) for k, o in outs.items()}
    info = outs["hybrid"].info_means
    box = np.asarray(info["handover_box"]) > 0
    late = np.asarray(info["handover_deadline"]) > 0
    classes = {"no hand-over": ~(box | late), "box hand-over": box, "deadline hand-over": late}
    decomposition = {
        name: {"runs": int(m.sum()), **{f"tv_mean_{k}_rad": float(v[m].mean()) for k, v in tv.items()}}
        for name, m in classes.items()
    }
    # the deadline runs again with their trajectories: TV before / after the hybrid's hand-over step
    idx = np.where(late)[0][: a.split_runs]
    sub = jax.tree.map(lambda v: v[idx], inputs)
    split = {}
    k_ho = None
    for name in ("hybrid", "smc", "rl"):  # the hybrid first: its hand-over step splits all three
        c = ctrls[name]
        fly = jax.jit(jax.vmap(lambda p, x, key, c=c: closed_loop(c, p, x, ref, key, N_STEPS, DT_S)))
        res = fly(sub.params, sub.x0_wind, sub.keys)
        if name == "hybrid":
            k_ho = np.argmax(np.asarray(res.traj.info["handover_deadline"]) > 0, axis=1)
            x = np.asarray(res.traj.x_wind)[np.arange(len(idx)), k_ho]
            err = np.abs(np.asarray(jax.vmap(tracking_errors, (0, None))(jnp.asarray(x), ref))) * 180 / np.pi
            at_handover = {
                "t_s_p10_p50_p90": np.percentile(k_ho * DT_S, [10, 50, 90]).tolist(),
                "V_fps_p10_p50_p90": np.percentile(vt_fps(x), [10, 50, 90]).tolist(),
                "omega_radps_p50_p90": np.percentile(omega_norm_radps(x), [50, 90]).tolist(),
                "abs_error_deg_p50": np.median(err, axis=0).tolist(),
                "abs_error_deg_p90": np.percentile(err, 90, axis=0).tolist(),
            }
        d = np.abs(np.diff(np.asarray(res.traj.delta_rad, np.float64), axis=1)).sum(-1)
        before = np.array([d[i, : k_ho[i]].sum() for i in range(len(idx))])
        split[name] = {
            "tv_before_rad": float(before.mean()),
            "tv_after_rad": float(d.sum(1).mean() - before.mean()),
        }
    variants = {}
    for name, hold in VARIANTS.items():
        out, _ = run_mc(
            make_hybrid(act, HybridConfig(schedule="simplex"), with_hold(*hold)), inputs, ref, N_STEPS,
            chunk_size=CHUNK,
        )  # fmt: skip
        variants[name] = {
            "hold_speed_fps": hold[0],
            "hold_rate_radps": hold[1],
            "hold_until_s": hold[2],
            **_stats(out),
        }
        print(name, variants[name], flush=True)
    result = {
        "policy": a.policy, "runs": a.runs, "seed": a.seed, "randomize": a.randomize,
        "duration_s": N_STEPS * DT_S,
        "controllers": {k: _stats(o) for k, o in outs.items()}, "decomposition": decomposition,
        "deadline_split": {"runs": int(len(idx)), "at_handover": at_handover, **split}, "variants": variants,
    }  # fmt: skip
    a.out.write_text(json.dumps(result, indent=1))
    print(json.dumps({k: result[k] for k in ("controllers", "decomposition", "deadline_split")}, indent=1))


if __name__ == "__main__":
    main()
