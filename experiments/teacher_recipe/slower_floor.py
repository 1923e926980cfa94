"""How often a controller that is the SMC up to a small gain change recovers > 1 s after the SMC.

The "slower than the SMC by > 1 s" share is paired run by run. This script measures how much of it a
controller pays for not being the SMC exactly: the default SMC with one gain scaled (every channel) flies the
same 1000 Monte Carlo runs as the default SMC, and the script reports the paired shares of runs slower and
faster by more than 1 s and the mean-time ratio, over all runs and by the airspeed at engagement.

    python experiments/teacher_recipe/slower_floor.py --mc-seed 2027 \\
        --out experiments/teacher_recipe/results/slower_floor_mc2027.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.smc import SMCConfig, default_gains, make_smc
from harv_jax.evaluation.montecarlo.paired import paired_vs_reference, times_nr_at_run_s
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD

REF = jnp.asarray([ALPHA_TARGET_RAD, 0.0, 0.0])
N_STEPS, DURATION_S = 6000, 60.0
BANDS_FPS = ((0, 600), (600, 1000), (1000, 2000))
GAINS = ("lambda1_ps", "lambda2_ps2", "k_reach", "phi_radps")


def times_s(ctrl, inputs) -> np.ndarray:
    """Per-run recovery time, s, with a run not recovered at the run length."""
    m = run_mc(ctrl, inputs, REF, N_STEPS)[0].metrics
    return times_nr_at_run_s(m.t_recover_s, m.recovered, DURATION_S)


def paired(t: np.ndarray, t_smc: np.ndarray) -> dict[str, float]:
    """Shares of runs slower / faster than the SMC by more than 1 s, and the mean-time ratio
    (``paired_vs_reference`` on times that already count a not-recovered run at the run length)."""
    vs = paired_vs_reference(t, np.ones(t.shape, bool), t_smc, np.ones(t_smc.shape, bool), DURATION_S)
    return {
        "runs": vs["runs"],
        "slower": vs["slower_fraction"],
        "faster": vs["faster_fraction"],
        "mean_ratio": vs["mean_ratio"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mc-seed", type=int, default=11)
    ap.add_argument("--n", type=int, default=1000, help="Monte Carlo runs")
    ap.add_argument("--scales", default="1.01,1.05,1.25", help="comma list of gain factors")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    scales = [float(s) for s in a.scales.split(",")]
    inputs = sample_mc_inputs(jax.random.key(a.mc_seed), a.n, harv())
    v0 = np.asarray(inputs.x0_wind[:, 0], np.float64)
    t_smc = times_s(make_smc(SMCConfig()), inputs)
    g0 = default_gains()
    rows = []
    for name in GAINS:
        for s in scales:
            gains = dataclasses.replace(g0, **{name: getattr(g0, name) * s})
            t = times_s(make_smc(SMCConfig(), gains), inputs)
            row = {"gain": name, "scale": s, "all": paired(t, t_smc)}
            for lo, hi in BANDS_FPS:
                sel = (v0 > lo) & (v0 <= hi)
                row[f"v0_{lo}_{hi}_fps"] = paired(t[sel], t_smc[sel])
            rows.append(row)
            by_band = [row[f"v0_{lo}_{hi}_fps"] for lo, hi in BANDS_FPS]
            bands = "  ".join(
                f"{lo}-{hi}: {b['slower']:.1%} / {b['faster']:.1%}"
                for (lo, hi), b in zip(BANDS_FPS, by_band, strict=True)
            )
            r = row["all"]
            print(
                f"{name} x{s}: slower {r['slower']:.1%} faster {r['faster']:.1%} mean {r['mean_ratio']:.3f}  "
                f"by V0 (slower / faster) {bands}",
                flush=True,
            )
    doc = {"mc_seed": a.mc_seed, "runs": a.n, "smc_mean_s": float(t_smc.mean()), "variants": rows}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
