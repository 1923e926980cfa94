"""``harv-jax`` with three more hybrids: the ``simplex`` hand-over rule varied under disturbances.

The default hybrid loses disturbed runs the policy alone recovers, after a hand-over to its fallback SMC
(``README.md``, "Why the hybrid loses disturbed runs the policy recovers"). Each variant changes one part of
the hand-over and flies the policy behind the measurement path it carries, as ``hybrid`` does:

- ``hybrid-fbstiff``: the fallback SMC with the default SMC gains instead of the soft ones;
- ``hybrid-deadline15``: the deadline at 15 s instead of 10 s;
- ``hybrid-hold400``: the deadline waits below 400 ft/s instead of 250 ft/s (with the same rate bound).

    python experiments/robust_policy/hybrid_handover.py mc \\
        --controller hybrid,hybrid-fbstiff,hybrid-deadline15,hybrid-hold400 \\
        --policy POLICY --runs 1000 --seed 5501 --disturbances default --out OUT
    python experiments/robust_policy/hybrid_handover.py collect OUT.json OUT...   # one table of the summaries
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable
from pathlib import Path

import jax.numpy as jnp

from harv_jax.cli import main
from harv_jax.control.base import Controller
from harv_jax.control.hybrid.law import HybridConfig, default_hybrid_gains, make_hybrid
from harv_jax.control.hybrid.settings import HybridGains
from harv_jax.control.registry import ControllerOptions, policy_path, register, with_measurement_path
from harv_jax.control.smc import default_gains
from harv_jax.policy import resolve_policy


def _stiff(g: HybridGains) -> HybridGains:
    return g.replace(simplex=g.simplex.replace(fallback_smc=default_gains()))


def _deadline15(g: HybridGains) -> HybridGains:
    return g.replace(simplex=g.simplex.replace(deadline_s=jnp.asarray(15.0)))


def _hold400(g: HybridGains) -> HybridGains:
    return g.replace(simplex=g.simplex.replace(hold_speed_fps=jnp.asarray(400.0)))


VARIANTS: dict[str, tuple[Callable[[HybridGains], HybridGains], str]] = {
    "hybrid-fbstiff": (_stiff, "simplex hybrid, fallback SMC with the default gains"),
    "hybrid-deadline15": (_deadline15, "simplex hybrid, deadline 15 s"),
    "hybrid-hold400": (_hold400, "simplex hybrid, deadline hold below 400 ft/s"),
}


def builder(change: Callable[[HybridGains], HybridGains]) -> Callable[[ControllerOptions], Controller]:
    """A registry builder: the ``simplex`` hybrid with ``change`` applied to its gains, behind the policy's
    measurement path."""

    def build(opts: ControllerOptions) -> Controller:
        pol = resolve_policy(opts.policy)
        ctrl = make_hybrid(
            pol.deterministic, HybridConfig(schedule="simplex"), change(default_hybrid_gains())
        )
        path = policy_path(pol)
        return ctrl if path is None else with_measurement_path(ctrl, path)

    return build


def collect(out: Path, folders: list[Path]) -> None:
    """Per ``harv-jax mc`` folder: its command and, per controller, recovered, outcomes, mean recovery time
    (not recovered = run length) and control TV; written to ``out``."""
    rows = []
    for folder in folders:
        doc = json.loads((folder / "summary.json").read_text())
        ctrls = {
            name: {
                "recovery_rate": c["recovery_rate"],
                "outcomes": c["outcomes"],
                "t_recover_mean_nr_at_run_s": c["t_recover_mean_nr_at_run_s"],
                "control_tv_mean_rad": c["control_tv"]["mean"],
            }
            for name, c in doc["controllers"].items()
        }
        rows.append({"folder": folder.name, "command": doc["command"], "controllers": ctrls})
    out.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    if sys.argv[1:2] == ["collect"]:
        collect(Path(sys.argv[2]), [Path(f) for f in sys.argv[3:]])
        sys.exit(0)
    for name, (change, text) in VARIANTS.items():
        register(name, builder(change), options=("policy",), help=f"{text} (robust_policy)")
    main()
