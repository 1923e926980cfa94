"""Figures of one flight: the hybrid's authority and command split, sliding variables and tracking errors."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from harv_jax import atomic
from harv_jax.aircraft.params import U_MAX_RAD, U_MIN_RAD  # noqa: E402
from harv_jax.dynamics import CONTROL_NAMES  # noqa: E402
from harv_jax.units import DEG_PER_RAD  # noqa: E402

#: CSV/figure names of the sliding variables and the tracking errors (alpha, beta, mu).
S_E_NAMES = (("s_alpha", "s_beta", "s_mu"), ("e_alpha", "e_beta", "e_mu"))


def plot_hybrid(
    t: np.ndarray, hy: dict, path: Path, t_engage_s: float, u_cmd_rad: np.ndarray | None = None
) -> None:
    """hybrid.png: zeta and fallback, and per surface the commands as applied: the learned command u_RL,
    the command after the safety filter's position/rate box (u_cmd) and the feedback's applied share
    u_cmd - u_RL. The unsaturated zeta u_fb (which reaches thousands of degrees in a spin) is not drawn;
    its peak is given in the legend."""
    fig, axes = plt.subplots(4, 1, figsize=(10, 9.5), sharex=True)
    axes[0].plot(t, hy["zeta"], lw=1.2, label="zeta (authority of the feedback term)")
    axes[0].plot(t, hy["fallback"], lw=1.0, ls="--", label="fallback (1 = SMC-only)")
    axes[0].set_ylabel("zeta / fallback")
    axes[0].set_ylim(-0.05, 1.1)
    axes[0].legend(loc="center right", fontsize=8)
    zeta_fb = hy["zeta"][:, None] * hy["u_fb_rad"]
    for j, n in enumerate(CONTROL_NAMES):
        ax = axes[j + 1]
        u_rl = hy["u_rl_rad"][:, j] * DEG_PER_RAD
        if u_cmd_rad is not None:
            u_cmd = np.asarray(u_cmd_rad)[:, j] * DEG_PER_RAD
            ax.plot(t, u_cmd, color="k", lw=2.2, alpha=0.45, zorder=2)
            ax.plot(t, u_cmd - u_rl, color="C1", lw=1.0, ls="--", zorder=3)
        ax.plot(t, u_rl, color="C0", lw=1.2, zorder=4)
        lo, hi = U_MIN_RAD[j] * DEG_PER_RAD, U_MAX_RAD[j] * DEG_PER_RAD
        for y in (lo, hi):
            ax.axhline(y, color="grey", lw=0.7, ls="-.", zorder=1)
        fin = np.isfinite(zeta_fb[:, j])
        if fin.any():
            peak = np.max(np.abs(zeta_fb[fin, j])) * DEG_PER_RAD
            ax.set_title(
                f"{n}: the unsaturated feedback command |zeta u_fb| peaks at {peak:,.0f} deg "
                "(not drawn; the filter limits it)",
                fontsize=8,
                loc="left",
            )
        span = hi - lo
        ax.set_ylim(lo - 0.1 * span, hi + 0.1 * span)
        ax.set_ylabel(f"{n} [deg]")
    axes[-1].set_xlabel("t [s]")
    if t_engage_s > 0:
        axes[-1].set_xlim(max(t_engage_s - 2.0, t[0]), t[-1])  # the hybrid acts from engagement on
    for ax in axes:
        ax.grid(alpha=0.3)
        if t_engage_s > 0:
            ax.axvline(t_engage_s, color="grey", ls=":", lw=0.8)
    handles = [Line2D([], [], color="C0", lw=1.2, label="learned command u_RL")]
    if u_cmd_rad is not None:
        handles += [
            Line2D([], [], color="k", lw=2.2, alpha=0.45, label="applied command u_cmd (after the filter)"),
            Line2D([], [], color="C1", lw=1.0, ls="--", label="feedback share u_cmd - u_RL"),
        ]
    handles.append(Line2D([], [], color="grey", lw=0.7, ls="-.", label="position limits"))
    if t_engage_s > 0:
        handles.append(
            Line2D([], [], color="grey", ls=":", lw=0.8, label=f"engagement (t = {t_engage_s:g} s)")
        )
    fig.legend(
        handles=handles, loc="upper center", ncol=3, fontsize=8, frameon=False, bbox_to_anchor=(0.5, 0.965)
    )
    fig.suptitle("hybrid: authority factor and the applied command split", y=0.995)
    fig.tight_layout(rect=(0, 0, 1, 0.92))
    atomic.save_figure(fig, path, dpi=90)
    plt.close(fig)


def plot_sliding(
    t: np.ndarray, s: np.ndarray, e_rad: np.ndarray, path: Path, t_marker_s: float | None = None
) -> None:
    """sliding.png: sliding variables s [T, 3] (rad/s) over the tracking errors e [T, 3] (drawn in deg)."""
    fig, axes = plt.subplots(2, 3, figsize=(12, 5.5), sharex=True)
    for j, (sn, en) in enumerate(zip(*S_E_NAMES, strict=True)):
        axes[0, j].plot(t, s[:, j], lw=0.8)
        axes[0, j].set_ylabel(f"{sn} [rad/s]")
        axes[1, j].plot(t, e_rad[:, j] * DEG_PER_RAD, lw=0.8)
        axes[1, j].set_ylabel(f"{en} [deg]")
        axes[1, j].set_xlabel("t [s]")
        for ax in axes[:, j]:
            ax.grid(alpha=0.3)
            if t_marker_s is not None:
                ax.axvline(t_marker_s, color="grey", ls=":", lw=0.8)
    fig.suptitle("sliding variables and tracking errors")
    fig.tight_layout()
    atomic.save_figure(fig, path, dpi=90)
    plt.close(fig)
