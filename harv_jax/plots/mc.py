"""Monte Carlo figures and tables: percentile bands of alpha, beta, mu and terminal-error histograms."""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from harv_jax import atomic
from harv_jax.plots.time_histories import RUN_STYLES  # noqa: E402

#: Percentiles of the Monte Carlo bands.
BAND_PERCENTILES = (5, 25, 50, 75, 95)


def band_percentiles(history_rad: np.ndarray) -> np.ndarray:
    """[5, T, 3] percentiles (BAND_PERCENTILES) over runs of [N, T, 3] alpha, beta, mu, in degrees."""
    return np.nanpercentile(np.degrees(history_rad), BAND_PERCENTILES, axis=0)


def write_bands_csv(t_s: np.ndarray, history_rad: np.ndarray, path: str | Path) -> Path:
    """bands_<controller>.csv: t and the BAND_PERCENTILES of alpha, beta, mu (deg) per sample time."""
    pct = band_percentiles(history_rad)
    names = [f"{y}_p{q}_deg" for y in ("alpha", "beta", "mu") for q in BAND_PERCENTILES]
    cols = [pct[j, :, i] for i in range(3) for j in range(len(BAND_PERCENTILES))]
    atomic.savetxt(
        path,
        np.column_stack([t_s, *cols]),
        delimiter=",",
        header=",".join(["t_s", *names]),
        comments="",
        fmt="%.6g",
    )
    return Path(path)


def band_limits_deg(
    histories_rad: Mapping[str, np.ndarray], reference_rad: np.ndarray
) -> list[tuple[float, float]]:
    """One shared y-range per variable (alpha, beta, mu; deg) over every controller's 5-95 % band and
    the reference, so that band plots of different controllers can be compared by eye."""
    lims = []
    for i in range(3):
        vals = [np.degrees(float(reference_rad[i]))]
        for h in histories_rad.values():
            pct = band_percentiles(h)[[0, -1], :, i]
            vals += [float(np.nanmin(pct)), float(np.nanmax(pct))]
        lo, hi = min(vals), max(vals)
        pad = 0.05 * max(hi - lo, 1.0)
        lims.append((lo - pad, hi + pad))
    return lims


def plot_mc_bands(
    t_s: np.ndarray,
    history_rad: np.ndarray,
    reference_rad: np.ndarray,
    path: str | Path,
    title: str = "",
    ylims_deg: list[tuple[float, float]] | None = None,
) -> Path:
    """Monte Carlo bands of alpha, beta, mu: 5-95 and 25-75 percentiles and the median.

    Args:
        t_s: [T] sample times, s.
        history_rad: [N, T, 3] alpha, beta, mu of every run, rad.
        reference_rad: [3] references, rad.
        path: PNG path.
        title: figure title.
        ylims_deg: optional (low, high) per variable, deg ([`band_limits_deg`][]: shared scales).
    """
    fig, axes = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    names = ("alpha", "beta", "mu")
    pct = band_percentiles(history_rad)
    for i, (ax, name) in enumerate(zip(axes, names, strict=True)):
        p5, p25, p50, p75, p95 = pct[:, :, i]
        ax.fill_between(t_s, p5, p95, alpha=0.25, color="C0", lw=0, label="5-95%")
        ax.fill_between(t_s, p25, p75, alpha=0.45, color="C0", lw=0, label="25-75%")
        ax.plot(t_s, p50, color="C0", lw=1.2, label="median")
        ax.axhline(np.degrees(reference_rad[i]), color="k", ls="--", lw=0.8, label="reference")
        ax.set_ylabel(f"{name} [deg]")
        if ylims_deg is not None:
            ax.set_ylim(*ylims_deg[i])
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="upper right")
    axes[-1].set_xlabel("t [s]")
    fig.suptitle(textwrap.fill(title or f"Monte Carlo bands (N = {history_rad.shape[0]})", width=90))
    fig.tight_layout()
    path = Path(path)
    atomic.save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def plot_mc_bands_overlay(
    t_s: np.ndarray,
    histories_rad: Mapping[str, np.ndarray],
    reference_rad: np.ndarray,
    path: str | Path,
    title: str = "",
) -> Path:
    """Every controller's bands side by side (small multiples): one column per controller, one row per
    variable (alpha, beta, mu) on one y-scale per row; each panel shows its controller's 5-95 % and 25-75 %
    bands and median, and the other controllers' medians in thin grey for comparison.

    Args:
        t_s: [T] sample times, s.
        histories_rad: controller -> [N, T, 3] alpha, beta, mu of every run, rad.
        reference_rad: [3] references, rad.
        path: PNG path.
        title: figure title (wrapped to the figure's width).
    """
    names = list(histories_rad)
    n = len(names)
    fig, axes = plt.subplots(
        3, n, figsize=(2.6 * n + 1.2, 7.5), sharex=True, sharey="row", squeeze=False, layout="constrained"
    )
    lims = band_limits_deg(histories_rad, reference_rad)
    pct = {c: band_percentiles(h) for c, h in histories_rad.items()}
    for k, ctrl in enumerate(names):
        for i, var in enumerate(("alpha", "beta", "mu")):
            ax = axes[i, k]
            for other in names:
                if other != ctrl:
                    ax.plot(t_s, pct[other][2, :, i], color="0.6", lw=0.7, label="other medians")
            p5, p25, p50, p75, p95 = pct[ctrl][:, :, i]
            ax.fill_between(t_s, p5, p95, color=f"C{k}", alpha=0.25, lw=0, label="5-95%")
            ax.fill_between(t_s, p25, p75, color=f"C{k}", alpha=0.45, lw=0, label="25-75%")
            ax.plot(t_s, p50, color=f"C{k}", lw=1.3, label="median")
            ax.axhline(np.degrees(reference_rad[i]), color="k", ls="--", lw=0.8, label="reference")
            ax.set_ylim(*lims[i])
            ax.grid(alpha=0.3)
            if k == 0:
                ax.set_ylabel(f"{var} [deg]")
            if i == 0:
                ax.set_title(ctrl, fontsize=10, color=f"C{k}")
            if i == 2:
                ax.set_xlabel("t [s]")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    keep = dict(zip(labels, handles, strict=True))  # one entry per label
    fig.legend(keep.values(), keep.keys(), loc="outside lower center", ncol=len(keep), fontsize=8)
    text = title or "Monte Carlo bands of all controllers"
    fig.suptitle(textwrap.fill(text, width=max(40, int(fig.get_figwidth() * 11))), fontsize=10)
    path = Path(path)
    atomic.save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


#: Terminal errors beyond this (deg) are counted in overflow bins, not drawn as if they were modes.
TERMINAL_ERROR_RANGE_DEG = 10.0


def plot_terminal_errors(errors_deg: Mapping[str, np.ndarray], path: str | Path) -> Path:
    """Step histograms (log count axis) of terminal alpha, beta, mu errors (deg) per controller ([N, 3]).

    Errors beyond +-``TERMINAL_ERROR_RANGE_DEG`` are not clipped into the edge bins: each side has a
    separate, hatched overflow bar labelled with its count, and non-finite runs are counted in the legend.
    """
    lim = TERMINAL_ERROR_RANGE_DEG
    fig, axes = plt.subplots(3, 1, figsize=(12, 10))
    any_overflow = False
    for i, (ax, name) in enumerate(zip(axes, ("alpha", "beta", "mu"), strict=True)):
        cols = {c: np.asarray(e[:, i], np.float64) for c, e in errors_deg.items()}
        inside = np.concatenate(
            [v[np.isfinite(v) & (np.abs(v) <= lim)] for v in cols.values()] + [np.zeros(0)]
        )
        span = max(float(np.max(np.abs(inside))) if inside.size else 0.6, 0.6)  # the +-0.5 lines inside
        bins = np.linspace(-span, span, 81)
        width = bins[1] - bins[0]
        for k, (ctrl, v) in enumerate(cols.items()):
            style = RUN_STYLES[k % len(RUN_STYLES)]
            fin = v[np.isfinite(v)]
            under, over = int(np.sum(fin < -lim)), int(np.sum(fin > lim))
            n_nan = int(v.size - fin.size)
            extra = [
                f"{under} < -{lim:g}" if under else "",
                f"{over} > {lim:g}" if over else "",
                f"{n_nan} non-finite" if n_nan else "",
            ]
            extra = ", ".join(x for x in extra if x)
            label = f"{ctrl} (N = {v.size}" + (f"; {extra}" if extra else "") + ")"
            shown = fin[np.abs(fin) <= lim]
            ax.hist(
                shown,
                bins=bins,
                histtype="step",
                color=f"C{k}",
                lw=style["lw"] * 0.9,
                ls=style["ls"],
                alpha=max(style["alpha"], 0.7),
                label=label,
                zorder=style["zorder"],
            )
            ax.hist(shown, bins=bins, histtype="stepfilled", color=f"C{k}", alpha=0.12, zorder=1)
            for side, count in ((-1, under), (1, over)):
                if count:
                    x = side * (span + (3 + 2 * k) * width)
                    ax.bar(
                        x, count, width=1.6 * width, color=f"C{k}", alpha=0.5, hatch="//", edgecolor=f"C{k}"
                    )
                    ax.text(
                        x,
                        count * 1.15,
                        f"{count} {'<' if side < 0 else '>'} {side * lim:+g}",
                        ha="center",
                        va="bottom",
                        fontsize=7,
                        color=f"C{k}",
                    )
        if any(np.any(np.abs(v[np.isfinite(v)]) > lim) for v in cols.values()):
            any_overflow = True
            for side in (-1, 1):
                ax.axvline(side * (span + 1.5 * width), color="grey", lw=0.8, ls="-")
        for x in (-0.5, 0.5):  # always inside: span >= 0.6
            ax.axvline(x, color="k", ls=":", lw=0.8)
        ax.set_yscale("log")
        ax.set_ylim(top=ax.get_ylim()[1] * 3)  # room for the overflow counts and the legend
        ax.set_xlabel(f"terminal {name} error [deg] (mean over the last 1 s; dotted: +-0.5 deg)")
        ax.set_ylabel("runs (log)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    note = (
        f"; hatched bars beyond the grey lines: number of runs with |error| > {lim:g} deg (overflow, "
        "not their values)"
        if any_overflow
        else ""
    )
    fig.suptitle(f"terminal tracking errors per controller{note}", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    atomic.save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
