"""Markdown tables of the ``simplex`` hybrid study (``experiments/hybrid_simplex/README.md``).

    python experiments/hybrid_simplex/table.py experiments/hybrid_simplex/results

Reads the ``mc_<zeta>_<policy>_<condition>.json`` and ``spin_<controller>_<policy>.json`` entries that
``run.py`` wrote into ``<folder>/summaries.json`` and prints one row per controller and policy, with the
SMC's row of the same runs first.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import results_bundle  # noqa: E402


def _f(v, fmt: str) -> str:
    return "–" if v is None else format(v, fmt)


def mc_rows(folder: Path) -> list[str]:
    out = [
        "| condition | policy | controller | recovered | t_rec p50 s | t_rec p95 s | p50 / SMC p50 | TV rad "
        "| altitude loss mean ft | handed over (runs): any / box / deadline |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for cond in ("nominal", "randomized"):
        smc_p50 = None
        rows = []
        for key, d in results_bundle.select(folder / "summaries.json", f"mc_*_{cond}.json").items():
            stem = key.removesuffix(".json")
            zeta, policy = stem.split("_", 2)[1], stem.split("_", 2)[2].rsplit("_", 1)[0]
            for ctrl, v in d["controllers"].items():
                t = v["recovery_time_s"]
                if ctrl == "smc":
                    if smc_p50 is not None:
                        continue  # every file flies the same runs: one SMC row
                    smc_p50 = t["p50"]
                h = v.get("hybrid", {}).get("handover_run_fraction")
                hand = "–" if not h else f"{h['any']:.2f} / {h['box']:.2f} / {h['deadline']:.2f}"
                name = f"hybrid/{zeta}" if ctrl == "hybrid" else ctrl
                rows.append((ctrl != "smc", cond, "–" if ctrl == "smc" else policy, name, v, t, hand))
        for _, cond_, pol, name, v, t, hand in sorted(rows, key=lambda r: r[0]):
            ratio = t["p50"] / smc_p50 if smc_p50 and t["p50"] is not None else None
            out.append(
                f"| {cond_} | {pol} | {name} | {100 * v['recovery_rate']:.1f}% | {_f(t['p50'], '.2f')} | "
                f"{_f(t['p95'], '.1f')} | {_f(ratio, '.2f')} | {v['control_tv']['mean']:.2f} | "
                f"{v['altitude_loss_ft']['mean']:.0f} | {hand} |"
            )
    return out


def spin_rows(folder: Path) -> list[str]:
    out = ["| policy | controller | outcome | recovered after s | TV rad |", "|---|---|---|---:|---:|"]
    for key, m in results_bundle.select(folder / "summaries.json", "spin_*.json").items():
        ctrl, policy = key.removesuffix(".json").split("_", 2)[1:]
        metrics = m.get("metrics", m)
        tv = metrics.get("control_tv_rad")
        tv = sum(tv) if isinstance(tv, list) else tv
        out.append(
            f"| {policy} | {'rl' if ctrl == 'rl' else 'hybrid/' + ctrl} | {metrics.get('outcome')} | "
            f"{_f(metrics.get('t_recover_s'), '.2f')} | {_f(tv, '.2f')} |"
        )
    return out


def main() -> None:
    folder = Path(sys.argv[1])
    print("\n".join(mc_rows(folder)))
    print()
    print("\n".join(spin_rows(folder)))


if __name__ == "__main__":
    main()
