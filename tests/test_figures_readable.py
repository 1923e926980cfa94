"""The Monte Carlo figures as a person reads them: every title and label inside the figure, five
controllers readable side by side, every legend entry drawn."""

from __future__ import annotations

import numpy as np

CONTROLLERS = ("smc", "smc-brake", "smc-brake-zoom", "rl", "hybrid")


def _histories(n_runs: int = 40, n_t: int = 120) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    t = np.linspace(0, 1, n_t)[None, :, None]
    return {
        c: 0.3 * np.exp(-4 * t) * rng.normal(1, 0.3, (n_runs, 1, 3)) + 0.02 * k
        for k, c in enumerate(CONTROLLERS)
    }


def test_bands_of_five_controllers_are_small_multiples_with_every_text_inside(tmp_path, figure_texts):
    from harv_jax.plots.mc import plot_mc_bands, plot_mc_bands_overlay

    h = _histories()
    t = np.linspace(0, 60, 120)
    ref = np.array([0.2, 0.0, 0.0])
    title = f"{', '.join(CONTROLLERS)}: Monte Carlo bands (N = 1000, alpha_d = 11.5 deg, h0 = 25,000 ft)"
    plot_mc_bands_overlay(t, h, ref, tmp_path / "all.png", title=title)
    fig = figure_texts.figures["all.png"]
    assert figure_texts["all.png"] == []
    # one panel per controller and variable: no band is drawn over another's
    panels = [ax for ax in fig.axes if ax.collections]
    assert len(panels) == 3 * len(CONTROLLERS)
    assert all(len(ax.collections) == 2 for ax in panels)  # its own 5-95 % and 25-75 % bands only
    assert [ax.get_title() for ax in fig.axes[: len(CONTROLLERS)]] == list(CONTROLLERS)
    plot_mc_bands(t, h["hybrid"], ref, tmp_path / "one.png", title=f"smc-brake-zoom: {title}")
    assert figure_texts["one.png"] == []


def test_terminal_errors_draw_what_their_labels_name_and_keep_texts_inside(tmp_path, figure_texts):
    from harv_jax.plots.mc import plot_terminal_errors

    rng = np.random.default_rng(1)
    errors = {c: rng.normal(0, 0.05 * (k + 1), (200, 3)) for k, c in enumerate(CONTROLLERS)}
    errors["rl"][:3] = 30.0  # overflow bars and their note
    plot_terminal_errors(errors, tmp_path / "t.png")
    fig = figure_texts.figures["t.png"]
    assert figure_texts["t.png"] == []
    for ax in fig.axes:
        assert "dotted: +-0.5 deg" in ax.get_xlabel()
        dotted = [ln for ln in ax.get_lines() if ln.get_linestyle() == ":"]
        assert sorted(ln.get_xdata()[0] for ln in dotted) == [-0.5, 0.5]
        lo, hi = ax.get_xlim()
        assert lo < -0.5 and hi > 0.5  # the named lines are on the panel


def test_training_curve_keeps_a_long_title_inside(tmp_path, figure_texts):
    from harv_jax.plots.training import plot_training_curve

    history = [
        {"env_steps": 1000 * (k + 1), "episode_return": [float(k), k + 1.0, k - 1.0],
         "episode/recovered": [0.1 * k] * 3, "episode/terminated": [0.05] * 3}
        for k in range(10)
    ]  # fmt: skip
    title = "harv-jax train --preset teacher --seeds 5 --steps 3000000 --out runs/teacher_41 (5 seeds) " * 2
    plot_training_curve(tmp_path / "curve.png", history, title)
    assert figure_texts["curve.png"] == []
