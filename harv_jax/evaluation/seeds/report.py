"""What ``harv-jax evaluate`` reports: each seed's numbers, the acceptance criteria, IQM over seeds.

From the cells of ``harv_jax.evaluation.seeds.conditions`` (per-run arrays of every controller on every
condition) this module computes each seed's flat metrics (``<condition>.<controller>.<metric>``, the names
``harv_jax.evaluation.seeds.acceptance`` reads), judges them, and writes ``evaluate.json``, ``evaluate.md``
and ``evaluate.png``. Times count a run not recovered at the run length; "slower" is slower than the
condition's reference controller by more than 1 s on the same run.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from harv_jax import atomic
from harv_jax.evaluation.montecarlo.paired import paired_vs_reference, times_nr_at_run_s
from harv_jax.evaluation.seed_stats import iqm_ci
from harv_jax.evaluation.seeds.acceptance import CRITERIA, judge, passes
from harv_jax.evaluation.seeds.conditions import BRAKE_ZOOM, CONDITIONS, POLICY_CONTROLLERS

#: The metrics of each (condition, controller) that the per-seed table shows.
TABLE_METRICS = ("recovered", "mean_over_ref", "slower_than_ref", "tv_over_ref")


def _ratio(a: float | None, b: float | None) -> float | None:
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)) or b <= 0:
        return None
    return float(a / b)


def cell_numbers(cell: dict[str, np.ndarray], run_length_s: float) -> dict[str, float]:
    """Recovered share, mean/p95 time (not recovered at the run length), mean TV and chatter of a cell."""
    t = times_nr_at_run_s(cell["t_recover_s"], cell["recovered"], run_length_s)
    return {
        "recovered": float(np.mean(cell["recovered"])),
        "mean_s": float(t.mean()),
        "p95_s": float(np.percentile(t, 95)),
        "tv_rad": float(np.mean(cell["tv_rad"])),
        "chatter_rad2": float(np.mean(cell["chatter_rad2"])),
    }


def versus(cell: dict[str, np.ndarray], ref: dict[str, np.ndarray], run_length_s: float) -> dict[str, Any]:
    """A cell against a reference cell on the same runs: time, p95 and TV ratios, paired slower share."""
    a, b = cell_numbers(cell, run_length_s), cell_numbers(ref, run_length_s)
    vs = paired_vs_reference(
        cell["t_recover_s"], cell["recovered"], ref["t_recover_s"], ref["recovered"], run_length_s
    )
    return {
        "mean_over_ref": vs["mean_ratio"],
        "slower_than_ref": vs["slower_fraction"],
        "p95_over_ref": _ratio(a["p95_s"], b["p95_s"]),
        "tv_over_ref": _ratio(a["tv_rad"], b["tv_rad"]),
    }


def seed_metrics(cells: dict[str, dict[str, dict[str, np.ndarray]]], seed: int, run_length_s: float) -> dict:
    """One seed's flat metrics from the cells (``cells[condition][controller]``; the policy's controllers
    under ``rl_seed<i>`` and ``hybrid_seed<i>``)."""
    out: dict[str, Any] = {}
    for cname, by_ctrl in cells.items():
        cond = CONDITIONS[cname]
        ref = by_ctrl.get(cond.reference)
        zoom = by_ctrl.get(BRAKE_ZOOM)
        for kind in POLICY_CONTROLLERS:
            cell = by_ctrl.get(f"{kind}_seed{seed}")
            if cell is None:
                continue
            p = f"{cname}.{kind}."
            nums = cell_numbers(cell, run_length_s)
            out.update({p + k: v for k, v in nums.items()})
            if cname == "spin":
                if ref is not None:  # a spin the policy does not recover counts at the run length over
                    ref_t = cell_numbers(ref, run_length_s)["mean_s"]
                    own = nums["mean_s"] if nums["recovered"] == 1.0 else 2.0 * run_length_s
                    out[p + "time_minus_ref_s"] = own - ref_t
                continue
            if ref is not None:
                out.update({p + k: v for k, v in versus(cell, ref, run_length_s).items()})
            if zoom is not None:
                out[p + "mean_over_smc_brake_zoom"] = _ratio(
                    nums["mean_s"], cell_numbers(zoom, run_length_s)["mean_s"]
                )
    for kind in POLICY_CONTROLLERS:
        for what in ("tv_rad", "chatter_rad2"):
            clean, dist = out.get(f"clean.{kind}.{what}"), out.get(f"disturbed.{kind}.{what}")
            short = what.split("_")[0]
            if clean is not None and dist is not None:
                out[f"disturbed.{kind}.{short}_over_clean"] = _ratio(dist, clean)
    return out


def build_document(
    settings: dict[str, Any],
    seeds: list[dict[str, Any]],
    cells: dict[str, dict[str, dict[str, np.ndarray]]],
    run_length_s: float,
) -> dict[str, Any]:
    """The evaluation's JSON document.

    Args:
        settings: the evaluation's settings record (and provenance: command, CPU, run folder).
        seeds: per seed ``{"seed", "policy", "sha256"}``.
        cells: every cell.
        run_length_s: run length, s.
    """
    rows = []
    for s in seeds:
        m = seed_metrics(cells, s["seed"], run_length_s)
        verdicts = judge(m)
        rows.append({**s, "metrics": m, "criteria": verdicts, "pass": passes(verdicts)})
    baselines = {
        cname: {ctrl: cell_numbers(cell, run_length_s) for ctrl, cell in by.items() if "_seed" not in ctrl}
        for cname, by in cells.items()
    }
    names = sorted({k for r in rows for k, v in r["metrics"].items() if v is not None})
    over = {k: iqm_ci([r["metrics"].get(k, math.nan) for r in rows]) for k in names}
    criteria = []
    for c in CRITERIA:
        v = [r["criteria"][c.name] for r in rows]
        judged = [x for x in v if x is not None]
        criteria.append(
            {
                "name": c.name,
                "text": c.text,
                "metric": c.metric,
                "op": c.op,
                "bar": c.bar,
                "stretch": c.stretch,
                "seeds_passing": sum(bool(x) for x in judged),
                "seeds_judged": len(judged),
                "all_seeds_pass": bool(judged) and len(judged) == len(v) and all(judged),
            }
        )
    verdicts = [r["pass"] for r in rows]
    return {
        **settings,
        "baselines": baselines,
        "seeds": rows,
        "over_seeds": over,
        "criteria": criteria,
        "all_seeds_pass": bool(verdicts) and all(v is True for v in verdicts),
    }


def _fmt(v: Any, pct: bool = False) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{100 * v:.1f}%" if pct else f"{v:.3g}"


def markdown(doc: dict[str, Any]) -> str:
    """The report section: per-seed table per condition, the criteria, IQM with CI."""
    lines = [
        "## Evaluation of every seed",
        "",
        f"Run `{doc.get('run_dir')}`, {doc['runs']} Monte Carlo runs of seed {doc['mc_seed']}, "
        f"{doc['duration_s']:g} s each; machine: {doc.get('cpu_model', '?')}. "
        f"Command: `{doc.get('command')}`.",
        "",
    ]
    for cname in doc["conditions"]:
        cond = CONDITIONS[cname]
        lines += [f"### {cname}: {cond.text} (reference `{cond.reference}`)", ""]
        base = doc["baselines"].get(cname, {})
        lines.append("| controller | recovered | mean s | p95 s | TV rad |")
        lines.append("|---|---:|---:|---:|---:|")
        for ctrl, b in base.items():
            lines.append(
                f"| {ctrl} | {_fmt(b['recovered'], True)} | {_fmt(b['mean_s'])} | {_fmt(b['p95_s'])} | "
                f"{_fmt(b['tv_rad'])} |"
            )
        lines += ["", "| seed | controller | recovered | mean s | mean / ref | slower > 1 s | TV / ref |"]
        lines.append("|---:|---|---:|---:|---:|---:|---:|")
        for r in doc["seeds"]:
            m = r["metrics"]
            for kind in POLICY_CONTROLLERS:
                p = f"{cname}.{kind}."
                if p + "recovered" not in m:
                    continue
                lines.append(
                    f"| {r['seed']} | {kind} | {_fmt(m[p + 'recovered'], True)} | "
                    f"{_fmt(m.get(p + 'mean_s'))} | "
                    f"{_fmt(m.get(p + 'mean_over_ref'))} | {_fmt(m.get(p + 'slower_than_ref'), True)} | "
                    f"{_fmt(m.get(p + 'tv_over_ref'))} |"
                )
        lines.append("")
    lines += [
        "### Criteria",
        "",
        "| criterion | metric | bar | seeds passing | IQM [95% CI] |",
        "|---|---|---|---:|---|",
    ]
    for c in doc["criteria"]:
        o = doc["over_seeds"].get(c["metric"])
        ci = "-" if o is None else f"{_fmt(o['iqm'])} [{_fmt(o['ci_low'])}, {_fmt(o['ci_high'])}]"
        lines.append(
            f"| {c['text']} | `{c['metric']}` | {c['op']} {c['bar']:g} | "
            f"{c['seeds_passing']}/{c['seeds_judged']} | {ci} |"
        )
    lines += [
        "",
        f"Every seed passes every required criterion: {'yes' if doc['all_seeds_pass'] else 'no'}.",
        "",
    ]
    return "\n".join(lines)


def figure(doc: dict[str, Any], path: Path) -> Path:
    """Per condition, each seed's RL-only and hybrid mean recovery time over the reference's, with the
    recovered share printed above the bar and the 0.75 bar drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    conds = [c for c in doc["conditions"] if c != "spin"]
    fig, axes = plt.subplots(1, max(1, len(conds)), figsize=(3.2 * max(1, len(conds)), 3.2), squeeze=False)
    for ax, cname in zip(axes[0], conds, strict=False):
        for j, kind in enumerate(POLICY_CONTROLLERS):
            xs, ys, rec = [], [], []
            for r in doc["seeds"]:
                v = r["metrics"].get(f"{cname}.{kind}.mean_over_ref")
                if v is not None:
                    xs.append(r["seed"] + (j - 0.5) * 0.35)
                    ys.append(v)
                    rec.append(r["metrics"].get(f"{cname}.{kind}.recovered"))
            ax.bar(xs, ys, width=0.35, label=kind)
            for x, y, q in zip(xs, ys, rec, strict=True):
                ax.text(x, y, _fmt(q, True), ha="center", va="bottom", fontsize=6, rotation=90)
        ax.axhline(0.75, color="k", lw=0.8, ls="--")
        ax.set_title(cname, fontsize=9)
        ax.set_xlabel("seed")
    axes[0][0].set_ylabel("mean recovery time / reference's")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    atomic.save_figure(fig, path, dpi=120)
    plt.close(fig)
    return path
