"""Cost of one closed-loop step: plant vs SMC vs hybrid, side by side.

Usage::

    python benchmarks/bench_step.py [--batch 1000] [--steps 100] [--repeats 11] [--copies 1] [--quick]

What is timed (one XLA device, ``jit(vmap(lax.scan of --steps steps))`` over ``--batch`` aircraft from the
Monte Carlo's reset bounds): a *plant step* (``to_wind``, actuator, RK4, the non-finite guard; the command is
held) and a *closed-loop step* of the SMC and of the hybrid (the same plus ``controller.apply``), as
``closed_loop`` runs them; and the policy's observation and forward pass alone (``policy_forward``, what the
policy adds to a hybrid step; ``zero_policy_plus_forward_over_smc`` is the simplex hybrid's cost if its own
logic and the policy ran one after another). The variants run interleaved, ``--repeats`` times each, and the
best time is used, so the ratios hold on a busy machine. ``--copies N`` builds the current steps N times and
uses the median of each build's best time (on a shared virtual machine two executables of the same code
differed by up to ~10%; each build's times are kept under ``us_per_step_each_copy``). XLA's cost analysis of
one step of one aircraft (FLOPs, transcendentals) and the compile times are recorded.
Results go to ``benchmarks/results/step_<machine>.json``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the repository root, for benchmarks.*
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=1")

from benchmarks.common import (  # noqa: E402
    best_us_per_step,
    cpu_model,
    load_average_1min,
    machine_name,
    result_header,
    write_json,
)
from harv_jax.policies import DEFAULT_POLICY_SPEC  # noqa: E402

DT_S = 0.01
#: Targets: SMC step <= 4 x plant step, hybrid step <= 1.3 x SMC step.
TARGETS = {
    "smc_over_plant": 4.0,
    "hybrid_over_smc": 1.3,
    "hybrid_gated_over_smc": 1.3,
    "hybrid_simplex_over_smc": 1.3,
}
#: The gated set's variants reported as a ratio to the SMC step (besides the continuous hybrid).
OVER_SMC = ("hybrid_gated", "hybrid_simplex", "hybrid_simplex_zero_policy", "rl", "policy_forward")


def build(
    batch: int,
    n_steps: int,
    policy: str | None,
    seed: int,
    gated: bool = False,
    controllers: tuple[str, ...] = ("smc", "hybrid"),
) -> dict:
    """Compiled plant / smc / hybrid step loops with their arguments, compile times and per-step costs.

    ``controllers``: the continuous-schedule controllers to build (``smc``, ``hybrid``); ``gated`` adds
    ``hybrid_gated``, ``hybrid_simplex``, ``hybrid_simplex_zero_policy`` (the simplex hybrid with a policy
    that costs nothing: the hybrid's own logic), ``rl`` (the policy flying alone) and ``policy_forward`` (the
    wind view, observation and forward pass of the policy, no plant: what the policy adds to a hybrid step).
    """
    import jax
    import jax.numpy as jnp

    from harv_jax.aircraft import harv
    from harv_jax.control.registry import ControllerOptions, build_controller
    from harv_jax.dynamics.actuators import actuator_step
    from harv_jax.dynamics.integrate import rk4_body_step
    from harv_jax.dynamics.state import from_wind, is_finite, to_wind
    from harv_jax.evaluation.montecarlo.rollout import sample_mc_inputs

    reference = jnp.array([0.349, 0.0, 0.0])
    inputs = sample_mc_inputs(jax.random.key(seed), batch, harv())
    params = inputs.params
    body0 = jax.vmap(from_wind)(inputs.x0_wind)
    delta0 = jnp.zeros((batch, 3))
    hold = jnp.full((batch, 3), 0.01)

    def plant_step(state, delta, cmd, prm):
        x = to_wind(state)
        delta = actuator_step(delta, cmd + 0.0 * x[:3], prm, DT_S)
        new = rk4_body_step(state, delta, prm, DT_S)
        ok = is_finite(new)
        return jax.tree.map(lambda a, b: jnp.where(ok, a, b), new, state), delta

    def closed_step(ctrl):
        def step(state, delta, cstate, prm):
            x = to_wind(state)
            u, cstate, _ = ctrl.apply(cstate, x, reference, jax.random.key(0))
            u = jnp.where(jnp.all(jnp.isfinite(u)), u, delta)
            delta = actuator_step(delta, u, prm, DT_S)
            new = rk4_body_step(state, delta, prm, DT_S)
            ok = is_finite(new)
            return jax.tree.map(lambda a, b: jnp.where(ok, a, b), new, state), delta, cstate

        return step

    def loop(step, n_carry):
        def one(*args):
            carry, const = args[:n_carry], args[n_carry:]

            def body(c, _):
                return step(*c, *const), None

            return jax.lax.scan(body, carry, None, length=n_steps)[0]

        return jax.jit(jax.vmap(one))

    out = {}
    variants = {"plant": (plant_step, 2, (body0, delta0, hold, params))}
    kinds = {name: (name, "continuous") for name in controllers}
    if gated:  # the gated/simplex schedules and the policy alone
        kinds["hybrid_gated"] = ("hybrid", "gated")
        kinds["hybrid_simplex"] = ("hybrid", "simplex")
        kinds["rl"] = ("rl", "continuous")
    ctrls = {n: build_controller(k, ControllerOptions(policy=policy, zeta=z)) for n, (k, z) in kinds.items()}
    if gated:  # the simplex hybrid with a policy that costs nothing: what the hybrid's own logic costs
        from harv_jax.control.hybrid.law import HybridConfig, make_hybrid

        def zero_policy(obs):
            return jnp.zeros(obs.shape[:-1] + (3,), obs.dtype)

        ctrls["hybrid_simplex_zero_policy"] = make_hybrid(zero_policy, HybridConfig(schedule="simplex"))
    for name, ctrl in ctrls.items():
        cstate0 = jax.vmap(ctrl.init)(params)
        variants[name] = (closed_step(ctrl), 3, (body0, delta0, cstate0, params))
    if gated:  # the policy's observation and forward pass alone, no plant: what the hybrid adds to its logic
        from harv_jax.policy import resolve_policy
        from harv_jax.task.spaces import observation

        act = resolve_policy(policy or DEFAULT_POLICY_SPEC).deterministic

        def policy_step(state, delta, prm):  # the observation reads the carry: no pass is loop-invariant
            a = jnp.clip(act(observation(to_wind(state), reference + 1e-6 * delta)), -1.0, 1.0)
            return state, delta + 1e-9 * a

        variants["policy_forward"] = (policy_step, 2, (body0, delta0, params))
    for name, (step, n_carry, args) in variants.items():
        t0 = time.perf_counter()
        compiled = loop(step, n_carry).lower(*args).compile()
        compile_s = time.perf_counter() - t0
        one = jax.tree.map(lambda a: a[0], args)
        cost = jax.jit(step).lower(*one).compile().cost_analysis()
        cost = cost[0] if isinstance(cost, list | tuple) else cost
        out[name] = {
            "compiled": compiled,
            "args": args,
            "compile_s": compile_s,
            "step_cost": {k: float(cost[k]) for k in ("flops", "transcendentals") if k in cost},
        }
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--batch", type=int, default=1000, help="aircraft per call")
    ap.add_argument("--steps", type=int, default=100, help="steps per timed call")
    ap.add_argument(
        "--repeats", type=int, default=11, help="interleaved timed calls per variant (best is used)"
    )
    ap.add_argument("--copies", type=int, default=1, help="builds of the current steps (median of bests)")
    ap.add_argument("--policy", default=None, help="the hybrid's policy (default: the shipped policy)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="50 steps, 5 repeats")
    ap.add_argument("--machine", default=None)
    ap.add_argument("--note", default="", help="free text stored in the JSON (e.g. 'machine shared')")
    ap.add_argument("--out-dir", type=Path, default=Path(__file__).resolve().parent / "results")
    args = ap.parse_args(argv)
    if args.quick:
        args.steps, args.repeats = 50, 5
    if args.copies < 1:
        ap.error(f"--copies {args.copies}: allowed: an integer >= 1")

    import jax

    dev = jax.devices()[0]
    machine = machine_name(args.machine)
    load_before = load_average_1min()
    print(f"device {dev.platform}:{dev.device_kind}  jax {jax.__version__}  cpu {cpu_model()}", flush=True)
    copies = {c: build(args.batch, args.steps, args.policy, args.seed, True) for c in range(args.copies)}
    sets = {"current": copies[0]}
    timed = {("current", c): b for c, b in copies.items()}
    calls = {(s, c, k): b for (s, c), built in timed.items() for k, b in built.items()}
    best_us = best_us_per_step(calls, args.repeats, args.steps)
    rows = {}
    for s, built in sets.items():
        n_copies = args.copies if s == "current" else 1
        each = {k: [best_us[(s, c, k)] for c in range(n_copies)] for k in built}
        us = {k: float(statistics.median(each[k])) for k in built}
        rows[s] = {
            k: {
                "us_per_step": us[k],
                "aircraft_steps_per_s": args.batch * 1e6 / us[k],
                "compile_s": built[k]["compile_s"],
                "step_cost_one_aircraft": built[k]["step_cost"],
                **({"us_per_step_each_copy": each[k]} if n_copies > 1 else {}),
            }
            for k in built
        }
        rows[s]["ratios"] = {
            "smc_over_plant": us["smc"] / us["plant"],
            "hybrid_over_smc": us["hybrid"] / us["smc"],
        }
        for k in OVER_SMC:
            if k in us:
                rows[s]["ratios"][f"{k}_over_smc"] = us[k] / us["smc"]
        if "policy_forward" in us:  # the simplex hybrid's cost if its logic and the policy ran in sequence
            rows[s]["ratios"]["zero_policy_plus_forward_over_smc"] = (
                us["hybrid_simplex_zero_policy"] + us["policy_forward"]
            ) / us["smc"]
        print(
            f"{s:>9}: plant {us['plant']:.0f} us/step, smc {us['smc']:.0f}, hybrid {us['hybrid']:.0f} "
            f"(batch {args.batch}): smc/plant {us['smc'] / us['plant']:.2f}, hybrid/smc "
            f"{us['hybrid'] / us['smc']:.2f}; compile plant {built['plant']['compile_s']:.1f} s, "
            f"smc {built['smc']['compile_s']:.1f} s, hybrid {built['hybrid']['compile_s']:.1f} s",
            flush=True,
        )
    for k in OVER_SMC:
        if f"{k}_over_smc" in rows["current"]["ratios"]:
            print(f"{k} / smc: {rows['current']['ratios'][f'{k}_over_smc']:.2f}", flush=True)
    if "zero_policy_plus_forward_over_smc" in rows["current"]["ratios"]:
        r = rows["current"]["ratios"]["zero_policy_plus_forward_over_smc"]
        print(f"(zero-policy hybrid + policy forward) / smc: {r:.2f}", flush=True)
    ratios = rows["current"]["ratios"]
    result = {
        **result_header("step", machine, args.note, load_before),
        "config": {
            "batch": args.batch,
            "steps_per_call": args.steps,
            "repeats": args.repeats,
            "copies": args.copies,
            "dt_s": DT_S,
            "policy": args.policy or DEFAULT_POLICY_SPEC,
            "seed": args.seed,
            "dtype": "float32",
            "devices_used": 1,
        },  # fmt: skip
        "method": "interleaved best-of-repeats of jit(vmap(scan)) per variant and build; median of --copies",
        "results": rows,
        "targets": {k: {"target": v, "value": ratios[k], "met": ratios[k] <= v} for k, v in TARGETS.items()},
    }
    name = f"step_{machine}_quick.json" if args.quick else f"step_{machine}.json"
    path = write_json(args.out_dir, name, result)
    print(f"wrote {path}")
    return result


if __name__ == "__main__":
    main()
