"""Figures in the paper's layout: (V, alpha, beta) / (p, q, r) / (mu, gamma, h - h0) / (de, da, dr)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from harv_jax import atomic
from harv_jax.units import DEG_PER_RAD  # noqa: E402

_PANELS = (
    (
        ("V", "V [ft/s]", 1.0),
        ("alpha", "alpha [deg]", DEG_PER_RAD),
        ("beta", "beta [deg]", DEG_PER_RAD),
    ),
    (
        ("p", "p [deg/s]", DEG_PER_RAD),
        ("q", "q [deg/s]", DEG_PER_RAD),
        ("r", "r [deg/s]", DEG_PER_RAD),
    ),
    (
        ("mu", "mu [deg]", DEG_PER_RAD),
        ("gamma", "gamma [deg]", DEG_PER_RAD),
        ("dh", "h - h0 [ft]", 1.0),
    ),
    (
        ("de", "de [deg]", DEG_PER_RAD),
        ("da", "da [deg]", DEG_PER_RAD),
        ("dr", "dr [deg]", DEG_PER_RAD),
    ),
)


#: Line style of the i-th overlaid run (cycled): solid thin; a thick translucent band; dashed on top; dotted.
#: Runs that coincide (the hybrid flies the SMC law while zeta = 1) stay distinguishable.
RUN_STYLES = (
    {"ls": "-", "lw": 1.3, "alpha": 1.0, "zorder": 3},
    {"ls": "-", "lw": 3.4, "alpha": 0.45, "zorder": 2},
    {"ls": "--", "lw": 1.3, "alpha": 1.0, "zorder": 4},
    {"ls": ":", "lw": 1.8, "alpha": 1.0, "zorder": 5},
)


def unwrap_angle_rad(angle_rad: np.ndarray) -> np.ndarray:
    """Continuous angle (no jumps at +-pi) that starts at the recorded (wrapped) initial value, so runs
    from one initial state start together; a full turn then shows as 360 deg, not as a jump."""
    a = np.asarray(angle_rad, np.float64)
    ok = np.isfinite(a)
    if not ok.any():
        return a
    out = np.full_like(a, np.nan)
    out[ok] = np.unwrap(a[ok])
    return out


def plot_time_histories(
    t_s: np.ndarray,
    runs: Mapping[str, Mapping[str, np.ndarray]],
    path: str | Path,
    title: str = "",
    references: Mapping[str, float] | None = None,
    t_marker_s: float | None = None,
) -> Path:
    """Overlay time histories of one or more runs in a 4 x 3 grid (the paper's four figures).

    Runs are told apart by line style (``RUN_STYLES``) as well as colour, so a run lying exactly on
    another stays visible; mu is unwrapped (continuous); the altitude panel states h0.

    Args:
        t_s: [T] time, s.
        runs: label -> columns (``V, alpha, beta, p, q, r, mu, gamma, h, de, da, dr``; rad, ft).
        path: PNG path to write.
        title: figure title.
        references: optional column -> reference value (rad) drawn dashed black and labelled.
        t_marker_s: optional time of the controller's engagement (vertical dotted line, labelled).
    """
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(4, 3, figsize=(13, 11.5), sharex=True)
    h0s = {float(np.asarray(cols["h"])[0]) for cols in runs.values()}
    for row, panel in zip(axes, _PANELS, strict=True):
        for ax, (name, label, scale) in zip(row, panel, strict=True):
            for k, (run_label, cols) in enumerate(runs.items()):
                if name == "dh":
                    y = np.asarray(cols["h"]) - np.asarray(cols["h"])[0]
                elif name == "mu":
                    y = unwrap_angle_rad(cols["mu"])
                else:
                    y = np.asarray(cols[name])
                style = RUN_STYLES[k % len(RUN_STYLES)]
                ax.plot(t_s, y * scale, color=f"C{k}", label=run_label, **style)
            if references and name in references:
                ax.axhline(references[name] * scale, color="k", ls="--", lw=0.8, zorder=1)
                if name == "mu":  # an unwrapped angle meets its reference at every multiple of 360 deg
                    lo, hi = ax.get_ylim()
                    ref_deg = references[name] * scale
                    for k in range(
                        int(np.floor((lo - ref_deg) / 360)), int(np.ceil((hi - ref_deg) / 360)) + 1
                    ):
                        if k and lo <= ref_deg + 360 * k <= hi:
                            ax.axhline(ref_deg + 360 * k, color="k", ls="--", lw=0.5, alpha=0.5, zorder=1)
            if t_marker_s is not None:
                ax.axvline(t_marker_s, color="grey", ls=":", lw=1.0, zorder=1)
            if name == "dh" and len(h0s) == 1:
                label = f"h - h0 [ft], h0 = {h0s.pop():,.0f} ft"
            elif name == "mu":
                label = "mu [deg] (unwrapped; ref. mod 360)"
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    handles = [
        Line2D(
            [],
            [],
            color=f"C{k}",
            label=lab,
            **{kk: v for kk, v in RUN_STYLES[k % 4].items() if kk != "zorder"},
        )
        for k, lab in enumerate(runs)
    ]
    if references:
        handles.append(
            Line2D([], [], color="k", ls="--", lw=0.8, label="reference (alpha_d; beta_d = mu_d = 0)")
        )
    if t_marker_s is not None:
        handles.append(
            Line2D([], [], color="grey", ls=":", lw=1.0, label=f"controller engaged (t = {t_marker_s:g} s)")
        )
    fig.legend(
        handles=handles,
        loc="upper center",
        ncol=min(len(handles), 5),
        fontsize=9,
        frameon=False,
        bbox_to_anchor=(0.5, 0.975),
    )
    if title:
        fig.suptitle(title, y=0.995)
    fig.tight_layout(rect=(0, 0, 1, 0.955))
    path = Path(path)
    atomic.save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path
