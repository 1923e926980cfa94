"""Stored outputs of the SMC step and the model (``tests/data/smc_reference.npz``) and their inputs.

``tests/test_smc_equivalence.py`` recomputes these outputs with the package and compares them with the
stored ones at tight tolerances: the SMC's Lie terms (float32 and float64), its guarded solve, its command
(the SMC law and the hybrid's feedback term) and a 16-run Monte Carlo (and, marked slow, the 256-run 60 s
one's per-run results). These outputs agree with the slower reference implementation of the same law and
model (Lie terms from one ``jax.linearize`` with 7 tangents, a LAPACK-SVD solve, its own aero lookup,
atmosphere and force build-up) to the tolerances listed in ``benchmarks/README.md``.

Regenerate them only when a change is meant to change these numbers (the model, the SMC law or its
defaults, the Monte Carlo's draws), after checking the change on its own, and say so in the commit:

    python tests/smc_reference_outputs.py          # writes tests/data/smc_reference.npz
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.aircraft import harv
from harv_jax.control.lie import smc_lie_terms
from harv_jax.control.smc import SMCConfig, default_gains, guarded_solve, make_smc, smc_command
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.evaluation.summary import summarize_controller

PATH = Path(__file__).resolve().parent / "data" / "smc_reference.npz"
REF = jnp.array([0.349, 0.0, 0.0])
#: Wide state box: deep stall, inverted, steep, fast and slow [V, alpha, beta, p, q, r, mu, gamma, chi, h].
LO = np.array([100.0, -0.5, -0.4, -2.0, -1.0, -1.0, -3.0, -1.4, -3.0, 5000.0])
HI = np.array([1500.0, 1.6, 0.4, 2.0, 1.0, 1.0, 3.0, 1.4, 3.0, 40000.0])
LIE_NAMES = ("y", "lf_y", "lf2_y", "lglf_y", "p_w", "lf_pw", "lg_pw")
N_LIE, N_SOLVE, N_COMMAND = 256, 1024, 512
#: (runs, steps) of the Monte Carlo whose records are stored, and of the slow one (per-run results only).
MC_SHORT, MC_LONG = (16, 1000), (256, 6000)


def states(n: int, seed: int) -> np.ndarray:
    """[n, 10] wind-axis states uniform in the box LO..HI."""
    return np.random.default_rng(seed).uniform(LO, HI, (n, 10))


def matrices(n: int, seed: int) -> np.ndarray:
    """3x3 matrices with condition numbers from 1 to 1e7, rank-deficient ones, zeros and NaN/inf entries."""
    rng = np.random.default_rng(seed)
    q1 = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    q2 = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    cond = 10.0 ** rng.uniform(0, 7, n)
    s = np.stack([np.ones(n), 10.0 ** rng.uniform(-1, 0, n) * np.ones(n), 1 / cond], 1)
    s = s * 10.0 ** rng.uniform(-3, 2, (n, 1))
    a = np.einsum("nij,nj,nkj->nik", q1, s, q2)
    a[:8] = 0.0
    a[8:16, 2] = a[8:16, 0] * 2.0  # rank 2
    a[16:24, 1, 1] = np.nan
    a[24:32, 0, 2] = np.inf
    return a


def lie_terms(dtype) -> dict[str, np.ndarray]:
    """The SMC's Lie terms on N_LIE states (call inside ``jax.enable_x64`` for float64)."""
    params = jax.tree.map(lambda a: jnp.asarray(a, dtype), harv())
    xs = jnp.asarray(states(N_LIE, 0), dtype)
    terms2, terms1 = jax.jit(jax.vmap(lambda x: smc_lie_terms(x, params)))(xs)
    return dict(zip(LIE_NAMES, map(np.asarray, (*terms2, *terms1)), strict=True))


def solve(dtype) -> dict[str, np.ndarray]:
    """The guarded solve on N_SOLVE matrices: u, rho2, cond, guard_active."""
    a = jnp.asarray(matrices(N_SOLVE, 1), dtype)
    b = jnp.asarray(np.random.default_rng(2).normal(size=(N_SOLVE, 3)), dtype)
    args = (jnp.asarray(1e3, dtype), jnp.asarray(1e-4, dtype))
    u, info = jax.jit(jax.vmap(lambda aa, bb: guarded_solve(aa, bb, *args)))(a, b)
    return {
        "u": np.asarray(u),
        "rho2": np.asarray(info.rho2),
        "cond": np.asarray(info.cond),
        "guard_active": np.asarray(info.guard_active),
    }


def command() -> dict[str, np.ndarray]:
    """The SMC command and the hybrid's feedback term (u_offset = u_RL) on N_COMMAND states, float32."""
    params, gains = harv(), default_gains()
    xs = jnp.asarray(states(N_COMMAND, 3), jnp.float32)
    ints = jnp.asarray(np.random.default_rng(4).uniform(-0.3, 0.3, (N_COMMAND, 3)), jnp.float32)
    u_rl = jnp.asarray(np.random.default_rng(5).uniform(-0.2, 0.2, (N_COMMAND, 3)), jnp.float32)

    def both(x, i, off):
        return tuple(smc_command(x, REF, i, params, gains, SMCConfig(), o) for o in (None, off))

    out = {}
    for name, (u, t) in zip(("smc", "offset"), jax.jit(jax.vmap(both))(xs, ints, u_rl), strict=True):
        out |= {
            f"{name}_u": np.asarray(u),
            f"{name}_s": np.asarray(t.s),
            f"{name}_guard_active": np.asarray(t.solve.guard_active),
            f"{name}_cond": np.asarray(t.solve.cond),
        }
    return out


def monte_carlo(n_runs: int, n_steps: int, history: bool) -> dict[str, np.ndarray]:
    """The SMC's Monte Carlo (seed 0): per-run results, summary numbers, and (``history``) the records."""
    inputs = sample_mc_inputs(jax.random.key(0), n_runs, harv())
    out, wall = run_mc(make_smc(), inputs, REF, n_steps, record_every=10, chunk_size=n_runs)
    summary = summarize_controller(out, wall, n_steps)
    res = {
        "outcome": np.asarray(out.metrics.outcome),
        "recovered": np.asarray(out.metrics.recovered),
        "t_recover_s": np.asarray(out.metrics.t_recover_s),
        "terminal_error_rad": np.asarray(out.terminal_error_rad),
        "recovery_rate": np.asarray(summary["recovery_rate"]),
        "control_tv_mean": np.asarray(summary["control_tv"]["mean"]),
    }
    if history:
        res["history"] = np.asarray(out.history)
    return res


def compute() -> dict[str, np.ndarray]:
    """Every stored output, by ``group/name``."""
    groups = {
        "lie32": lie_terms(jnp.float32),
        "solve32": solve(jnp.float32),
        "command": command(),
        "mc": monte_carlo(*MC_SHORT, history=True),
        "mc_long": monte_carlo(*MC_LONG, history=False),
    }
    with jax.enable_x64(True):
        groups |= {"lie64": lie_terms(jnp.float64), "solve64": solve(jnp.float64)}
    return {f"{g}/{k}": v for g, d in groups.items() for k, v in d.items()}


def load() -> dict[str, np.ndarray]:
    """The stored outputs."""
    with np.load(PATH, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def main() -> None:
    PATH.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(PATH, **compute())
    print(f"wrote {PATH} ({PATH.stat().st_size / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
