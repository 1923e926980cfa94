"""Fingerprints of what training computes: each shipped preset's state after its first periods.

``python tools/behaviour_fingerprint.py --out FILE [--presets a,b]`` builds every shipped preset as
``harv-jax train`` does (the preset's recipe, env, teacher and demonstrations), shortened so that a period
is one PPO update (2 seeds, 4 periods of 1 update each: the ``teacher`` preset's policy gradient joins at
the second), runs the periods and writes the SHA-256 of the parameters, optimizer state, observation
normalizer and every metric's values (as hexadecimal floats) after the first period and after the last.
Two commits compute the same training when their fingerprints are equal (on one machine: XLA's CPU code
may differ between CPUs). ``--compare BEFORE AFTER --out FILE`` writes which parts are equal.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path
from typing import Any

import jax
import numpy as np

from harv_jax.ppo import config as ppo_config
from harv_jax.training.presets import available_presets, load_spec
from harv_jax.training.start import build_training

PERIODS = 4


def digest(tree: Any) -> str:
    """SHA-256 of the leaves of a pytree (dtype, shape and bytes, in flattening order)."""
    h = hashlib.sha256()
    for leaf in jax.tree.leaves(tree):
        a = np.asarray(
            jax.random.key_data(leaf) if jax.dtypes.issubdtype(leaf.dtype, jax.dtypes.prng_key) else leaf
        )
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def fingerprint(preset: str) -> dict[str, Any]:
    spec = load_spec(preset)
    one_update = spec.ppo.num_envs * spec.ppo.unroll
    cfg = spec.ppo.replace(
        num_seeds=2, num_periods=PERIODS, total_steps=PERIODS * one_update, checkpoint_every=1
    )
    assert ppo_config.updates_per_period(cfg) == 1
    setup = build_training(spec.replace(ppo=cfg))
    trainer = setup.trainer
    keys = jax.vmap(lambda s: jax.random.fold_in(jax.random.key(cfg.seed), s))(np.arange(cfg.num_seeds))
    state = trainer.init(keys, setup.env_params)
    out: dict[str, Any] = {"init": digest((state.params, state.opt_state, state.normalizer))}
    for p in range(PERIODS):
        state, metrics = trainer.period(state, setup.env_params)
        metrics = {k: metrics[k] for k in sorted(metrics)}
        if p in (0, PERIODS - 1):
            name = "period1" if p == 0 else f"period{PERIODS}"
            out[name] = {
                "params": digest(state.params),
                "opt_state": digest(state.opt_state),
                "normalizer": digest(state.normalizer),
                "metrics": {k: [float(v).hex() for v in np.ravel(np.asarray(m))] for k, m in metrics.items()},
            }
    return out


def compare(before: dict[str, Any], after: dict[str, Any]) -> dict[str, Any]:
    """Per preset and stage: which of params, optimizer state, normalizer are equal; the metrics that
    differ, and those only one side has."""
    out: dict[str, Any] = {}
    for preset, stages in before.items():
        if preset not in after:
            out[preset] = "missing after"
            continue
        rows = {"init": stages["init"] == after[preset]["init"]}
        for stage in (k for k in stages if k != "init"):
            b, a = stages[stage], after[preset][stage]
            common = set(b["metrics"]) & set(a["metrics"])
            rows[stage] = {
                **{f: b[f] == a[f] for f in ("params", "opt_state", "normalizer")},
                "metrics_equal": len([m for m in common if b["metrics"][m] == a["metrics"][m]]),
                "metrics_differ": sorted(m for m in common if b["metrics"][m] != a["metrics"][m]),
                "metrics_only_before": sorted(set(b["metrics"]) - common),
                "metrics_only_after": sorted(set(a["metrics"]) - common),
            }
        out[preset] = rows
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--presets", default=",".join(available_presets()))
    parser.add_argument(
        "--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"), help="compare two files"
    )
    args = parser.parse_args()
    if args.compare:
        before, after = (json.loads(p.read_text()) for p in args.compare)
        args.out.write_text(json.dumps(compare(before, after), indent=1) + "\n")
        return
    result = {p: fingerprint(p) for p in args.presets.split(",")}
    args.out.write_text(json.dumps(result, indent=1) + "\n")
    for p, r in result.items():
        print(p, r["period1"]["params"][:16], r[f"period{PERIODS}"]["params"][:16])


if __name__ == "__main__":
    main()
