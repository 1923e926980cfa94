"""Figures and number formatting: unwrapped mu, shared band scales, overflow bins, rounding."""

from __future__ import annotations

import json

import numpy as np

from harv_jax.numfmt import round_floats, round_sig, write_json
from harv_jax.plots.maps import outcome_labels
from harv_jax.plots.mc import band_limits_deg, plot_mc_bands_overlay, plot_terminal_errors
from harv_jax.plots.time_histories import plot_time_histories, unwrap_angle_rad

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_unwrap_mu_has_no_jumps_and_starts_at_the_initial_value():
    t = np.linspace(0.0, 10.0, 2001)
    true = -3.0 * t  # a spin: mu turns -30 rad, then the wrapped record jumps at +-pi
    wrapped = np.angle(np.exp(1j * true))
    assert np.max(np.abs(np.diff(wrapped))) > 6.0
    u = unwrap_angle_rad(wrapped)
    assert np.max(np.abs(np.diff(u))) < 0.1
    assert u[0] == wrapped[0]
    np.testing.assert_allclose(np.angle(np.exp(1j * u)), wrapped, atol=1e-9)


def test_band_limits_are_shared_and_cover_every_controller():
    rng = np.random.default_rng(0)
    narrow = rng.normal(0.35, 0.01, (50, 20, 3))
    wide = rng.normal(0.35, 0.5, (50, 20, 3))
    lims = band_limits_deg({"smc": narrow, "rl": wide}, np.array([0.349, 0.0, 0.0]))
    wide_deg = np.degrees(np.percentile(wide, [5, 95], axis=0))
    for i, (lo, hi) in enumerate(lims):
        assert lo <= wide_deg[0, :, i].min() and hi >= wide_deg[1, :, i].max()


def test_figures_write_pngs(tmp_path):
    t = np.linspace(0, 5, 51)
    cols = {n: np.zeros_like(t) for n in ("V", "alpha", "beta", "p", "q", "r", "gamma", "de", "da", "dr")}
    cols.update({"h": 25_000.0 - 10 * t, "mu": np.angle(np.exp(1j * (-4.0 * t)))})
    p = plot_time_histories(t, {"smc": cols, "hybrid": cols}, tmp_path / "th.png", "x",
                            references={"alpha": 0.349}, t_marker_s=1.0)  # fmt: skip
    assert p.read_bytes()[:8] == PNG_MAGIC
    rng = np.random.default_rng(1)
    hist = {"smc": rng.normal(0.35, 0.01, (20, 51, 3)), "rl": rng.normal(0.3, 0.2, (20, 51, 3))}
    assert (
        plot_mc_bands_overlay(t, hist, np.array([0.349, 0, 0]), tmp_path / "b.png").read_bytes()[:8]
        == PNG_MAGIC
    )
    errs = {"smc": rng.normal(0, 0.02, (100, 3)), "rl": np.concatenate([rng.normal(0, 3, (90, 3)),
                                                                       np.full((10, 3), 40.0)])}  # fmt: skip
    errs["rl"][0, 0] = np.nan
    assert plot_terminal_errors(errs, tmp_path / "te.png").read_bytes()[:8] == PNG_MAGIC


def test_outcome_labels_say_not_recovered_by_t():
    names = ("RECOVERED", "TIMEOUT", "DEPARTED", "GROUND_HIT", "NONFINITE")
    labels = outcome_labels(names, 30.0)
    assert labels[0] == "recovered"
    assert labels[1].startswith("not recovered by 30 s") and labels[2].startswith("not recovered by 30 s")
    assert not any("departed" in lab for lab in labels)


def test_json_numbers_are_rounded(tmp_path):
    assert round_sig(23.51999855041504) == 23.52
    assert round_sig(3.832364200206939e-06) == 3.83236e-06
    assert round_floats({"a": [0.1 + 0.2, None, 3], "b": float("nan")})["a"] == [0.3, None, 3]
    doc = json.loads(write_json(tmp_path / "x.json", {"t": np.float32(23.52).item()}).read_text())
    assert doc == {"t": 23.52}


def test_metrics_dict_stores_the_outcome_by_name():
    import jax.numpy as jnp

    from harv_jax.evaluation.summary import metrics_to_dict
    from harv_jax.task.criteria import OUTCOME_NAMES

    class _M:  # the fields metrics_to_dict reads
        __dataclass_fields__ = {"outcome": None, "t_recover_s": None}
        outcome = jnp.asarray(2)
        t_recover_s = jnp.asarray(jnp.nan)

    d = metrics_to_dict(_M())
    assert d["outcome"] == OUTCOME_NAMES[2] == "DEPARTED" and d["outcome_code"] == 2
