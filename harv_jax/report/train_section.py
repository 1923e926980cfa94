"""The report's section of a training run: each seed's last evaluation and the IQM over seeds."""

from __future__ import annotations

from typing import Any

from harv_jax.report.document import Doc

#: Rows of the per-seed table: summary.json "seeds" name -> (label, format).
SEED_ROWS = {
    "recovered": ("recovered (evaluation batch)", ".1%"),
    "recovered_spin": ("recovered, spins", ".1%"),
    "t_recover_mean_s": ("mean recovery time, not recovered at the run length [s]", ".2f"),
    "t_recover_median_s": ("median recovery time [s]", ".2f"),
    "tv_median_rad": ("median control TV [rad]", ".2f"),
}


def train_section(doc: Doc, summary: dict[str, Any]) -> None:
    """Per-seed evaluation table with the IQM and its 95% bootstrap CI, and which seeds meet the bar."""
    seeds = summary["seeds"]
    per_seed = seeds["per_seed"]
    n = len(next(iter(per_seed.values()), []))
    doc.h(3, "Every seed's last evaluation")
    header = ["", *[f"seed {i}" for i in range(n)], "IQM [95% CI]"]
    rows = []
    for name, (label, spec) in SEED_ROWS.items():
        if name not in per_seed:
            continue
        q = seeds["iqm"][name]
        ci = f"{format(q['iqm'], spec)} [{format(q['ci_low'], spec)}, {format(q['ci_high'], spec)}]"
        rows.append([label, *[format(v, spec) for v in per_seed[name]], ci])
    doc.table(header, rows)
    ok = seeds["seeds_meeting_bar"]
    doc.p(
        f"Seeds that recover at least {seeds['bar']:.1%} of the evaluation batch: "
        f"{', '.join(map(str, ok)) or 'none'} ({len(ok)} of {n}). Best seed (policy/policy.npz): "
        f"{summary.get('best_seed', '?')}."
    )
