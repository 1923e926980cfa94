"""The report section of a ``harv-jax optimal`` run: optimal_report.md, built from its summary.json.

``harv-jax report`` includes every ``*.md`` of a run folder, so the section travels with the run; the
per-controller tables come from summary.json's ``controllers`` block as for ``harv-jax mc``.
"""

from __future__ import annotations

from typing import Any

from harv_jax.report.document import fmt


def optimal_markdown(summary: dict[str, Any]) -> str:
    """Markdown: what the optimum is over, the ratio table, the acceptance counts and the search settings."""
    o = summary["optimal"]
    srch = o["search"]
    n = summary["runs"]
    lines = [
        f"## Optimal recoveries ({summary.get('scenario', 'mc')}, {n} runs, seed {summary['seed']})",
        "",
        f"The optimum is searched over {o['control_class']}.",
        f"Search: normalized gradient steps of {srch['learning_rate']:g} with momentum, "
        f"{srch['iterations']} in {srch['rounds']} rounds on a {srch['horizon_s']:g} s horizon, "
        f"{srch['n_knots']} knots every {srch['knot_dt_s']:g} s; "
        f"every result re-simulated for {srch['run_s']:g} s and scored by the standard criterion.",
        "",
        f"Recovered: {fmt(o['recovered_fraction'], 'pct')}; never slower than the best controller: "
        f"{'yes' if o['never_slower_than_best'] else 'no'}; strictly faster than the best controller on "
        f"{fmt(o['strictly_faster_fraction'], 'pct')} of the runs.",
        "",
        "| controller | time / optimal, median | p95 | mean | its time, median (s) | p95 (s) |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, r in o["ratio_to_optimal"].items():
        t = o["recovery_time_s"][name]
        lines.append(
            f"| {name} | {fmt(r['median'], '.3f')} | {fmt(r['p95'], '.3f')} | {fmt(r['mean'], '.3f')} | "
            f"{fmt(t['median'], '.2f')} | {fmt(t['p95'], '.2f')} |"
        )
    t = o["recovery_time_s"]["optimal"]
    lines += [
        f"| optimal | 1 | 1 | 1 | {fmt(t['median'], '.2f')} | {fmt(t['p95'], '.2f')} |",
        "",
        "Times with not-recovered runs at the run length. Where the optimum comes from (runs): "
        + ", ".join(f"{k} {v}" for k, v in o["source_counts"].items())
        + "; the best registry controller per run: "
        + ", ".join(f"{k} {v}" for k, v in o["best_controller_counts"].items())
        + ".",
        "",
    ]
    return "\n".join(lines)
