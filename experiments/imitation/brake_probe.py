"""The SMC with an energy-braking alpha reference (alpha_brake while V > V_switch) on the Monte Carlo.

python experiments/imitation/brake_probe.py 256      # runs; Monte Carlo key 123, nominal aircraft
"""

import sys

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft.params import harv
from harv_jax.control.base import Controller
from harv_jax.control.registry import build_controller
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.spec import ALPHA_TARGET_RAD

N = int(sys.argv[1]) if len(sys.argv) > 1 else 256
#: Runs per compiled call: the chunk these results were made with (``--chunk 250``).
CHUNK = 250
smc = build_controller("smc")
nominal = harv()
inputs = sample_mc_inputs(jax.random.PRNGKey(123), N, nominal)
ref = jnp.array([ALPHA_TARGET_RAD, 0.0, 0.0])


def braking(alpha_brake, v_switch):
    def apply(cs, x, r, key):
        a = jnp.where(x[0] > v_switch, alpha_brake, r[0])
        return smc.apply(cs, x, r.at[0].set(a), key)

    return Controller(smc.init, apply)


def report(name, out, base=None):
    m = out.metrics
    t = np.where(m.recovered, m.t_recover_s, np.inf)
    tv = m.control_tv_rad.sum(-1)
    s = f"{name:24s} rec {m.recovered.mean() * 100:5.1f}% median {np.median(t):5.2f} "
    s += f"p95 {np.percentile(t, 95):5.2f} TV {np.mean(tv):5.2f}"
    if base is not None:
        s += f" ratio-of-medians {np.median(t) / np.median(base):.3f}"
    print(s, flush=True)
    return t


out, _ = run_mc(smc, inputs, ref, 6000, chunk_size=CHUNK)
t0 = report("smc", out)
for ab, vs in [(0.6, 600.0), (0.8, 600.0), (0.6, 400.0), (0.8, 400.0), (1.0, 500.0)]:
    out, _ = run_mc(braking(ab, vs), inputs, ref, 6000, chunk_size=CHUNK)
    report(f"brake a={ab} V>{vs}", out, t0)
