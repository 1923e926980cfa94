"""Where the time of one plant step goes: the parts of ``actuator_step`` + ``rk4_body_step``, side by side.

Usage::

    python benchmarks/profile_dynamics.py [--batch 4096] [--steps 20] [--repeats 8]

Each part is jitted as in ``benchmarks/bench_dynamics.py`` (``vmap`` over the fleet of ``make_fleet`` of a
``lax.scan`` of ``--steps`` steps, one XLA device) and the parts are timed interleaved (``--repeats`` rounds,
all parts once per round), so that a busy machine slows them alike; the table gives ns per aircraft-step
(best and median) and each part's median as a share of the full step's. The parts: the full step; four
``body_derivatives`` (an RK4 step evaluates four); four ``forces_moments`` (atmosphere, table lookup,
coefficient build-up); four ``coefficients`` (lookup and build-up); four ``lookup``; four
``density_and_thrust_lapse``; four evaluations of the two ``arctan2`` and two ``sqrt`` of
``body_derivatives``; the carry alone. Each chains its evaluations through a tiny dependence so that XLA
keeps all four. ``fusions`` is the number of fusions in the compiled program (the full step's scan body is
most of it). Nothing is written; the numbers are for reading.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from benchmarks.bench_dynamics import DT_S, make_fleet  # noqa: E402
from benchmarks.common import cpu_model  # noqa: E402
from harv_jax.aircraft.aero import coefficients, lookup  # noqa: E402
from harv_jax.dynamics import actuator_step, rk4_body_step  # noqa: E402
from harv_jax.dynamics.atmosphere import density_and_thrust_lapse  # noqa: E402
from harv_jax.dynamics.eom import body_derivatives, forces_moments  # noqa: E402

EPS = 1e-9  # weight of the dependence that chains the evaluations of a part


def full_step(s, d, cmd, p):
    d = actuator_step(d, cmd, p, DT_S)
    return rk4_body_step(s, d, p, DT_S), d


def four_derivatives(s, d, cmd, p):
    for _ in range(4):
        k = body_derivatives(s, d, p)
        s = jax.tree.map(lambda a, b: a + 1e-3 * b, s, k)
    return s, d


def _air_angles(s):
    u = s.uvw_fps
    return jnp.sqrt(jnp.sum(u * u)), jnp.arctan2(u[2], u[0]), jnp.arctan2(u[1], jnp.hypot(u[0], u[2]))


def four_forces_moments(s, d, cmd, p):
    vt, alpha, beta = _air_angles(s)
    for _ in range(4):
        f = forces_moments(vt, alpha, beta, s.pqr_radps, s.pos_ft[2], d, p, alpha_in_range=True)
        alpha, beta, vt = alpha + EPS * f.L, beta + EPS * f.Y, vt + EPS * f.D
    return s.replace(uvw_fps=s.uvw_fps.at[0].add(EPS * (alpha + beta + vt))), d


def four_coefficients(s, d, cmd, p):
    vt, alpha, beta = _air_angles(s)
    for _ in range(4):
        c = coefficients(alpha, beta, s.pqr_radps, vt, d, p, alpha_in_range=True)
        alpha, beta = alpha + EPS * c.CL, beta + EPS * c.CY
    return s.replace(uvw_fps=s.uvw_fps.at[0].add(EPS * (alpha + beta))), d


def four_lookups(s, d, cmd, p):
    _, alpha, _ = _air_angles(s)
    total = 0.0
    for _ in range(4):
        row = lookup(alpha, p.aero_scale, in_range=True)
        alpha, total = alpha + EPS * row[0], total + jnp.sum(row)
    return s.replace(uvw_fps=s.uvw_fps.at[0].add(EPS * (alpha + total))), d


def four_atmospheres(s, d, cmd, p):
    h = s.pos_ft[2]
    for _ in range(4):
        rho, lapse = density_and_thrust_lapse(h)
        h = h + 1e-3 * (rho + lapse)
    return s.replace(pos_ft=s.pos_ft.at[2].set(h)), d


def four_angle_sets(s, d, cmd, p):
    u = s.uvw_fps
    for _ in range(4):  # body_derivatives: two sqrt (|u,w|, V) and two arctan2 (alpha, beta)
        uw = jnp.sqrt(u[0] * u[0] + u[2] * u[2])
        vt = jnp.sqrt(uw * uw + u[1] * u[1])
        u = u + 1e-6 * jnp.stack([jnp.arctan2(u[2], u[0]), jnp.arctan2(u[1], uw), vt])
    return s.replace(uvw_fps=u), d


def carry_only(s, d, cmd, p):
    return jax.tree.map(lambda x: x * 1.0000001, s), d


PARTS: dict[str, Callable] = {
    "full step": full_step,
    "4 x body_derivatives": four_derivatives,
    "4 x forces_moments": four_forces_moments,
    "4 x coefficients (+lookup)": four_coefficients,
    "4 x lookup": four_lookups,
    "4 x atmosphere": four_atmospheres,
    "4 x (2 arctan2 + 2 sqrt)": four_angle_sets,
    "carry only": carry_only,
}


def scanned(part: Callable, n_steps: int) -> Callable:
    """jit(vmap(scan of n_steps of ``part``)), as bench_dynamics.make_fly."""

    def fly_one(state, delta, cmd, params):
        def step(carry, _):
            return part(*carry, cmd, params), None

        return jax.lax.scan(step, (state, delta), None, length=n_steps)[0]

    return jax.jit(jax.vmap(fly_one))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--batch", type=int, default=4096)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=8)
    args = ap.parse_args()
    fleet = make_fleet(0, args.batch, jnp.float32)
    compiled = {}
    for name, part in PARTS.items():
        c = scanned(part, args.steps).lower(*fleet).compile()
        compiled[name] = (c, c.as_text().count(" fusion("))
        jax.block_until_ready(c(*fleet))
    times: dict[str, list[float]] = {name: [] for name in PARTS}
    for _ in range(args.repeats):
        for name, (c, _) in compiled.items():
            t0 = time.perf_counter()
            jax.block_until_ready(c(*fleet))
            times[name].append(time.perf_counter() - t0)
    n = args.batch * args.steps
    full = float(np.median(times["full step"]))
    print(f"{cpu_model()}, jax {jax.__version__}, batch {args.batch}, {args.steps} steps, one device, "
          f"load {os.getloadavg()[0]:.1f}")  # fmt: skip
    print(f"{'part':28s} {'best ns':>8s} {'median ns':>10s} {'% of step':>10s} {'fusions':>8s}")
    for name, t in times.items():
        print(f"{name:28s} {1e9 * min(t) / n:8.1f} {1e9 * np.median(t) / n:10.1f} "
              f"{100 * np.median(t) / full:10.1f} {compiled[name][1]:8d}")  # fmt: skip


if __name__ == "__main__":
    main()
