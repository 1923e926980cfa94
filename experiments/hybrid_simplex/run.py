"""The ``simplex`` hybrid study (``experiments/hybrid_simplex/README.md``): Monte Carlo and spin per policy.

    python experiments/hybrid_simplex/run.py --out experiments/hybrid_simplex/results \\
        --policy recovery=shipped:recovery --policy partial=shipped:paper-partial --fixtures [--runs 1000]

Writes into ``<out>/summaries.json`` (``experiments/results_bundle.py``) the entries
``mc_<zeta>_<policy>_<condition>.json`` (``harv-jax mc`` summaries of the hybrid with ``--zeta``, RL-only
for trained policies, the SMC with the first policy; all on the same runs) and
``spin_<controller>_<policy>.json`` (``harv-jax fly --scenario spin`` metrics).
``--fixtures`` adds the zero, random and bang-bang test fixtures (``tests/policy_fixtures.py``; not shipped).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "experiments"))

import results_bundle  # noqa: E402


def _cli(*args: str) -> None:
    cmd = [sys.executable, "-m", "harv_jax.cli", *args]
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--policy", action="append", default=[], help="NAME=SPEC (a policy file or shipped:NAME)")
    ap.add_argument("--fixtures", action="store_true", help="also the zero, random and bang-bang fixtures")
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--zeta", default="simplex")
    ap.add_argument("--conditions", default="nominal,randomized")
    ap.add_argument("--no-spin", action="store_true")
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    policies = dict(p.split("=", 1) for p in a.policy)
    tmp = Path(tempfile.mkdtemp(prefix="simplex_fixtures_"))
    if a.fixtures:
        subprocess.run([sys.executable, str(ROOT / "tests" / "policy_fixtures.py"), str(tmp)], check=True)
        policies.update({k: str(tmp / f"{k}.npz") for k in ("zero", "random", "bang-bang")})
    work = tmp / "run"
    fixtures = ("zero", "random", "bang-bang") if a.fixtures else ()
    for i, (name, spec) in enumerate(policies.items()):
        # the SMC once (every command flies the same runs), RL-only for the trained policies only
        ctrls = ",".join((["smc"] if i == 0 else []) + ([] if name in fixtures else ["rl"]) + ["hybrid"])
        for cond in a.conditions.split(","):
            rand = "--randomize" if cond == "randomized" else "--no-randomize"
            _cli("mc", "--controller", ctrls, "--zeta", a.zeta, "--policy", spec, "--runs",
                 str(a.runs), "--seed", str(a.seed), rand, "--out", str(work), "--force")  # fmt: skip
            doc = json.loads((work / "summary.json").read_text())
            results_bundle.add(a.out / "summaries.json", f"mc_{a.zeta}_{name}_{cond}.json", doc)
        if a.no_spin:
            continue
        for ctrl in ("rl", "hybrid"):
            _cli("fly", "--scenario", "spin", "--controller", ctrl, "--zeta", a.zeta, "--policy", spec,
                 "--out", str(work), "--force")  # fmt: skip
            doc = json.loads((work / "metrics.json").read_text())
            key = f"spin_{ctrl if ctrl == 'rl' else a.zeta}_{name}.json"
            results_bundle.add(a.out / "summaries.json", key, doc)
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
