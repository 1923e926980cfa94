"""Which states does the SMC recover from? The evidence for the ``simplex`` box (``DEFAULT_SIMPLEX_BOX_*``).

    python experiments/hybrid_simplex/box_probe.py --out experiments/hybrid_simplex/results/box_probe.json

Flies the SMC with its default gains and with the simplex fallback's (``simplex_fallback_gains``) for 60 s
from ``--runs`` states drawn uniformly from a box wider than the simplex box (``PROBE_LOW``/``PROBE_HIGH``:
V, alpha, beta, p, q, r, mu, gamma; h0 25,000 ft, zero initial deflections), nominal and randomized aircraft
(the Monte Carlo's ``--randomize`` ranges), and writes the recovery rate overall, inside the simplex box and
per bin of each state (the Monte Carlo's criterion).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft.params import harv
from harv_jax.control.hybrid.law import DEFAULT_SIMPLEX_BOX_HIGH, DEFAULT_SIMPLEX_BOX_LOW
from harv_jax.control.hybrid.zeta import simplex_fallback_gains
from harv_jax.control.smc import SMCConfig, default_gains, make_smc
from harv_jax.evaluation.montecarlo.rollout import MCInputs, run_mc, sample_mc_inputs
from harv_jax.task.scenarios import ResetBounds, sample_table_states
from harv_jax.task.spec import ALPHA_TARGET_RAD

NAMES = ("V", "alpha", "beta", "p", "q", "r", "mu", "gamma")
PROBE_LOW = (100.0, -0.5, -0.8, -5.0, -3.5, -3.0, -3.142, -1.047)
PROBE_HIGH = (1500.0, 1.8, 0.8, 5.0, 3.5, 3.0, 3.142, 1.047)
BINS = 6
#: Runs per compiled call: the chunk these results were made with (``--chunk 250``).
CHUNK = 250


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--runs", type=int, default=4000)
    a = ap.parse_args()
    lo, hi = jnp.asarray(PROBE_LOW), jnp.asarray(PROBE_HIGH)
    x0 = sample_table_states(jax.random.PRNGKey(8), a.runs, ResetBounds(lo, hi))
    x = np.asarray(x0)
    in_box = np.all((x[:, :6] >= DEFAULT_SIMPLEX_BOX_LOW) & (x[:, :6] <= DEFAULT_SIMPLEX_BOX_HIGH), axis=1)
    ref = jnp.array([ALPHA_TARGET_RAD, 0.0, 0.0])
    result = {
        "runs": a.runs, "probe_low": PROBE_LOW, "probe_high": PROBE_HIGH, "state_names": NAMES,
        "simplex_box_low": DEFAULT_SIMPLEX_BOX_LOW, "simplex_box_high": DEFAULT_SIMPLEX_BOX_HIGH,
        "states_in_simplex_box": int(in_box.sum()), "duration_s": 60.0, "state_key": 8, "aircraft_key": 7,
        "results": {},
    }  # fmt: skip
    for gains_name, gains in (("default", default_gains()), ("simplex_fallback", simplex_fallback_gains())):
        for cond in ("nominal", "randomized"):
            base = sample_mc_inputs(jax.random.PRNGKey(7), a.runs, harv(), randomize=cond == "randomized")
            inputs = MCInputs(x0_wind=x0, params=base.params, keys=base.keys)
            out, _ = run_mc(make_smc(SMCConfig(), gains), inputs, ref, 6000, chunk_size=CHUNK)
            rec = np.asarray(out.metrics.recovered)
            per_state = {}
            for j, n in enumerate(NAMES):
                edges = np.linspace(PROBE_LOW[j], PROBE_HIGH[j], BINS + 1)
                b = np.clip(np.digitize(x[:, j], edges[1:-1]), 0, BINS - 1)
                per_state[n] = {"bin_low": edges[:-1].round(3).tolist(),
                                "recovered": [float(rec[b == k].mean()) for k in range(BINS)]}  # fmt: skip
            result["results"][f"{gains_name}/{cond}"] = {
                "recovered": float(rec.mean()),
                "recovered_in_simplex_box": float(rec[in_box].mean()),
                "failed_runs": int((~rec).sum()),
                "failed_below_600_fps": int((~rec & (x[:, 0] < 600.0)).sum()),
                "per_state_bin": per_state,
            }
            print(gains_name, cond, result["results"][f"{gains_name}/{cond}"]["recovered"], flush=True)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
