"""Markdown tables of the gated-zeta measurements (``experiments/hybrid_gated/README.md``).

    python experiments/hybrid_gated/table.py experiments/hybrid_gated/results

Reads the entries ``mc_<controller>_<policy>_<condition>_<runs>.json`` (``harv-jax mc`` summaries) and
``spin_*.json`` (``harv-jax fly`` metrics) of the folder's ``summaries.json``
(``experiments/results_bundle.py``) and prints the tables.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import results_bundle  # noqa: E402

POLICIES = ("partial", "full", "zero", "random", "bang-bang")


def _f(v, fmt: str) -> str:
    return "–" if v is None else format(v, fmt)


def mc_rows(folder: Path) -> list[str]:
    out = [
        "| condition | N | policy | controller | recovered | not recovered | t_rec p50 s | t_rec p95 s "
        "| TV rad | chatter 1e-6 rad² | ζ α/β/μ | policy unmodified | fallback | certificate unsat. α/β/μ "
        "| certificate sat. α/β/μ | sat. steps |",
        "|---|---:|---|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---|---|---:|",
    ]
    files = results_bundle.load(folder / "summaries.json")
    for cond in ("nominal", "randomized"):
        for n in (1000, 256):
            entries = [("–", "smc", f"mc_smc_{cond}_{n}.json")]
            for p in POLICIES:
                for z in ("gated", "continuous"):
                    entries.append((p, f"hybrid/{z}", f"mc_{z}_{p}_{cond}_{n}.json"))
            for pol, ctrl, key in entries:
                if key not in files:
                    continue
                d = files[key]
                v = next(iter(d["controllers"].values()))
                h, t = v["hybrid"], v["recovery_time_s"]
                cert = h.get("certificate")
                row = [
                    cond, str(d["runs"]), pol, ctrl, f"{100 * v['recovery_rate']:.1f}%",
                    str(d["runs"] - v["outcomes"]["recovered"]), _f(t["p50"], ".1f"), _f(t["p95"], ".1f"),
                    f"{v['control_tv']['mean']:.2f}", f"{1e6 * v['chatter_index']['mean']:.2f}",
                ]  # fmt: skip
                if "zeta_mean_by_channel" in h:
                    row += [
                        "/".join(f"{x:.2f}" for x in h["zeta_mean_by_channel"].values()),
                        f"{100 * h['policy_unmodified_fraction']:.1f}%",
                        f"{100 * h['fallback_fraction']:.1f}%",
                        "/".join(_f(x, ".3f") for x in cert["holds_unsaturated"].values()),
                        "/".join(_f(x, ".3f") for x in cert["holds_saturated"].values()),
                        f"{100 * cert['saturated_step_fraction']:.1f}%",
                    ]
                else:
                    row += ["–"] * 6
                out.append("| " + " | ".join(row) + " |")
    return out


def spin_rows(folder: Path) -> list[str]:
    out = ["| policy | controller | recovered | t_rec after engagement s | TV rad | altitude loss ft |",
           "|---|---|---:|---:|---:|---:|"]  # fmt: skip
    for key, d in results_bundle.select(folder / "summaries.json", "spin_*.json").items():
        m = d["metrics"]
        name = key.removesuffix(".json").removeprefix("spin_")
        ctrl, _, pol = name.partition("_")
        tv = m.get("control_tv_rad")
        tv = sum(tv) if isinstance(tv, list) else tv
        out.append(
            f"| {pol or '–'} | {'smc' if ctrl == 'smc' else 'hybrid/' + ctrl} | {m.get('recovered')} | "
            f"{_f(m.get('t_recover_s'), '.2f')} | {_f(tv, '.2f')} | {_f(m.get('altitude_loss_ft'), '.0f')} |"
        )
    return out


def main() -> None:
    folder = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).resolve().parent / "results")
    print("\n".join(mc_rows(folder)))
    print()
    print("\n".join(spin_rows(folder)))


if __name__ == "__main__":
    main()
