"""The policy's forward pass and its parts at 1,000 aircraft on one core, against a large matmul's rate.

Usage::

    taskset -c 0 python benchmarks/bench_policy_forward.py [--policy shipped:fast] [--batch 1000]

What is timed (one XLA device, ``jit(lax.scan)`` of ``--steps`` passes whose input depends on the previous
output, interleaved, best of ``--repeats``): the policy's deterministic forward pass on ``--batch``
observations (normalization, hidden layers with tanh, output layer, clip), each hidden layer's matmul alone
(``h @ W``, its GFLOP/s), ``tanh`` over one hidden activation (ns per element), an elementwise add over the
same array (the memory floor), and a 1024 x 1024 matmul (the rate a large matmul reaches on the same device
in the same run). It answers whether the forward pass, the part of a hybrid step the SMC does not have
(``bench_step.py``'s ``policy_forward``), runs at the core's limits. Pin the process to one core
(``taskset -c 0``) for a per-core figure. Results go to ``benchmarks/results/policy_forward_<machine>.json``.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root, for benchmarks.*
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=1")

from benchmarks.common import (  # noqa: E402
    best_us_per_step,
    cpu_cores,
    load_average_1min,
    machine_name,
    result_header,
    write_json,
)
from harv_jax.policies import DEFAULT_POLICY_SPEC  # noqa: E402

SQUARE_N = 1024
SQUARE_PASSES = 10  # 1024^3 multiply-adds per pass: 10 passes per call are enough


def build(policy_spec: str, batch: int, n_steps: int, seed: int) -> tuple[dict, list[list[int]]]:
    """Compiled loops of the forward pass and its parts (each with its argument, passes per call and work per
    pass), and the network's layer shapes."""
    import jax
    import jax.numpy as jnp

    from harv_jax.policy import resolve_policy

    pol = resolve_policy(policy_spec)
    mlp = pol.params.policy["params"]["mlp"]
    hidden = [mlp[f"hidden_{i}"] for i in range(sum(1 for k in mlp if k.startswith("hidden_")))]
    k_obs, k_h, k_sq = jax.random.split(jax.random.key(seed), 3)
    obs = jax.random.normal(k_obs, (batch, hidden[0]["kernel"].shape[0]))
    square_w = jax.random.orthogonal(k_sq, SQUARE_N)  # orthogonal: the iterates keep their size

    def loop(f, n=n_steps):
        def body(x, _):
            return f(x), None

        return jax.jit(lambda x: jax.lax.scan(body, x, None, length=n)[0])

    def forward(o):  # the carry moves by 1e-6 x the action: every pass depends on the previous one
        a = pol.deterministic(o)
        return o + 1e-6 * jnp.mean(a, axis=-1, keepdims=True)

    width = hidden[-1]["kernel"].shape[1]
    h = jnp.tanh(jax.random.normal(k_h, (batch, width)))
    parts = {"forward": (loop(forward), obs, n_steps, None)}
    for i, layer in enumerate(hidden[1:], start=1):  # square hidden layers: h @ W maps h to its own shape
        w = layer["kernel"]
        if w.shape[0] == w.shape[1]:
            w = w / jnp.linalg.norm(w, 2)  # spectral norm 1: the iterates cannot grow over the passes
            x = jax.random.normal(k_h, (batch, w.shape[0]))
            parts[f"matmul_hidden_{i}"] = (loop(lambda x, w=w: x @ w), x, n_steps, 2.0 * batch * w.size)
    parts["tanh_hidden"] = (loop(jnp.tanh), h, n_steps, float(h.size))
    parts["add_hidden"] = (loop(lambda x: x + 1e-3), h, n_steps, float(h.size))
    square = loop(lambda s: s @ square_w, SQUARE_PASSES)
    parts["matmul_square"] = (square, square_w, SQUARE_PASSES, 2.0 * SQUARE_N**3)
    built = {
        name: {"compiled": f.lower(arg).compile(), "args": (arg,), "passes": passes, "work": work}
        for name, (f, arg, passes, work) in parts.items()
    }
    shapes = [list(v["kernel"].shape) for v in hidden] + [list(mlp["out"]["kernel"].shape)]
    return built, shapes


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--policy", default=DEFAULT_POLICY_SPEC, help="policy spec (default: the shipped policy)")
    ap.add_argument("--batch", type=int, default=1000, help="observations per pass")
    ap.add_argument("--steps", type=int, default=100, help="passes per timed call")
    ap.add_argument("--repeats", type=int, default=15, help="interleaved timed calls per part (best is used)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--machine", default=None)
    ap.add_argument("--note", default="", help="free text stored in the JSON")
    ap.add_argument("--out-dir", type=Path, default=Path(__file__).resolve().parent / "results")
    args = ap.parse_args(argv)
    for flag in ("batch", "steps", "repeats"):
        if getattr(args, flag) < 1:
            ap.error(f"--{flag} {getattr(args, flag)}: allowed: an integer >= 1")

    load_before = load_average_1min()
    built, layer_shapes = build(args.policy, args.batch, args.steps, args.seed)
    per_call = best_us_per_step(built, args.repeats, 1)  # all parts interleaved; then per pass
    us = {name: per_call[name] / b["passes"] for name, b in built.items()}
    parts = {}
    for name, b in built.items():
        row = {"us_per_pass": us[name]}
        if name.startswith("matmul"):
            row["gflop_per_s"] = b["work"] / us[name] / 1e3
        elif b["work"] is not None:
            row["ns_per_element"] = 1e3 * us[name] / b["work"]
        parts[name] = row
        detail = ", ".join(f"{k} {v:.2f}" for k, v in row.items() if k != "us_per_pass")
        print(f"{name:>16}: {us[name]:8.1f} us per pass{'  (' + detail + ')' if detail else ''}", flush=True)
    result = {
        **result_header("policy_forward", machine_name(args.machine), args.note, load_before),
        "cpu_affinity": cpu_cores(),
        "config": {
            "policy": args.policy,
            "layer_shapes": layer_shapes,
            "batch": args.batch,
            "passes_per_call": args.steps,
            "repeats": args.repeats,
            "square_matmul_n": SQUARE_N,
            "dtype": "float32",
        },
        "method": "interleaved best-of-repeats of jit(scan) of dependent passes, one XLA device",
        "parts": parts,
    }
    path = write_json(args.out_dir, f"policy_forward_{result['machine']}.json", result)
    print(f"wrote {path}")
    return result


if __name__ == "__main__":
    main()
