"""Which condition of the recovery criterion a gust breaks, and whether a stiffer β loop rejects it.

    python experiments/robustness/gust_channels.py --runs 256 --seed 11 \
        --out experiments/robustness/results/gust_channels.json

Each controller flies the Monte Carlo's runs (nominal aircraft, 60 s) under the body-axis gust at each level
(``DisturbanceSpec(gust_fps=G)``, correlation time drawn per run in [1, 10] s as in the env). Over the last
10 s of every run (the criterion's hold window) it reports, per channel, the RMS error and the share of
samples outside the criterion's band (|e_α| < 2°, |e_β| < 1°, |e_μ| < 2°, ‖ω‖ < 0.17 rad/s), and the share of
runs recovered when the criterion is applied to the raw samples and to their moving averages over 1, 2 and
4 s. ``smc-beta<L>`` is the SMC with the β channel's λ1 set to L 1/s (λ2 = L²/8; the default is λ1 = 2).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.base import Controller
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.control.smc import default_gains, make_smc
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec
from harv_jax.evaluation.montecarlo.inputs import sample_mc_inputs
from harv_jax.optimal.outputs import cpu_model
from harv_jax.task.criteria import RECOVERED_TOL, omega_norm_radps, tracking_errors
from harv_jax.task.spec import ALPHA_TARGET_RAD, RECOVERY_HOLD_S

N_STEPS = 6000
RECORD_EVERY = 5  # 20 Hz samples
DT_REC_S = 0.01 * RECORD_EVERY
REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
WINDOWS_S = (1.0, 2.0, 4.0)
CHANNELS = ("alpha", "beta", "mu", "omega")


def controller(name: str) -> Controller:
    if name.startswith("smc-beta"):
        lam = float(name.removeprefix("smc-beta"))
        g = default_gains()
        return make_smc(
            None,
            g.replace(
                lambda1_ps=g.lambda1_ps.at[1].set(lam), lambda2_ps2=g.lambda2_ps2.at[1].set(lam**2 / 8)
            ),
        )
    return build_controller(name, ControllerOptions())


def fly(name: str, n_runs: int, seed: int, gust_fps: float) -> np.ndarray:
    """[runs, samples, 4]: e_alpha, e_beta, e_mu (rad, signed) and ||omega|| (rad/s) at 20 Hz."""
    inputs = sample_mc_inputs(
        jax.random.key(seed), n_runs, harv(), disturbances=DisturbanceSpec(gust_fps=gust_fps)
    )
    ctrl = controller(name)

    def one(run: Any) -> jnp.ndarray:
        res = closed_loop(
            ctrl, run.params, run.x0_wind, REF, run.keys, N_STEPS, disturbance=run.disturbance,
            disturbance_key=run.disturbance_keys, max_delay_steps=run.max_delay_steps,
            model_params=run.model_params, record_every=RECORD_EVERY,
        )  # fmt: skip
        x = res.traj.x_wind
        return jnp.concatenate([tracking_errors(x, REF), omega_norm_radps(x)[..., None]], axis=-1)

    return np.asarray(jax.jit(jax.vmap(one))(inputs), np.float64)


def moving_average(sig: np.ndarray, window_s: float) -> np.ndarray:
    k = max(1, int(round(window_s / DT_REC_S)))
    c = np.cumsum(np.concatenate([np.zeros_like(sig[:, :1]), sig], axis=1), axis=1)
    return (c[:, k:] - c[:, :-k]) / k


def recovered_share(sig: np.ndarray) -> float:
    hold = int(round(RECOVERY_HOLD_S / DT_REC_S))
    ok = np.all(np.abs(sig[:, -hold:]) < RECOVERED_TOL, axis=-1)
    return float(np.mean(np.all(ok, axis=1)))


def analyse(sig: np.ndarray) -> dict[str, Any]:
    hold = int(round(RECOVERY_HOLD_S / DT_REC_S))
    last = np.abs(sig[:, -hold:])
    out: dict[str, Any] = {"recovered": recovered_share(sig)}
    for i, ch in enumerate(CHANNELS):
        scale = 1.0 if ch == "omega" else 180.0 / np.pi
        out[f"{ch}_rms"] = float(np.sqrt(np.mean(last[..., i] ** 2)) * scale)
        out[f"{ch}_outside_band"] = float(np.mean(last[..., i] >= RECOVERED_TOL[i]))
    for w in WINDOWS_S:
        out[f"recovered_moving_average_{w:g}s"] = recovered_share(moving_average(sig, w))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--controllers", default="smc,rl,smc-beta4,smc-beta8")
    ap.add_argument("--gust-fps", default="2.5,10")
    ap.add_argument("--runs", type=int, default=256)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args()
    rows = []
    for g in (float(v) for v in args.gust_fps.split(",")):
        for name in args.controllers.split(","):
            row = {"controller": name, "gust_fps": g, **analyse(fly(name, args.runs, args.seed, g))}
            rows.append(row)
            print(
                f"| {name} | {g:g} | {100 * row['recovered']:.1f}% | "
                + " | ".join(
                    f"{row[f'{c}_rms']:.2f}, {100 * row[f'{c}_outside_band']:.1f}%" for c in CHANNELS
                )
                + " | "
                + " / ".join(f"{100 * row[f'recovered_moving_average_{w:g}s']:.1f}" for w in WINDOWS_S)
                + "% |",
                flush=True,
            )
    meta = {"runs": args.runs, "seed": args.seed, "cpu": cpu_model(), "jax": jax.__version__}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"meta": meta, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
