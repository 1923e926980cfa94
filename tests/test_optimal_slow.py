"""``harv_jax.optimal``'s search: the rollout's gradient against finite differences (float64), and the study
never slower than the best registry controller. Slow: each compiles the gradient of the closed loop (SMC
with its Lie derivatives, RK4, aero tables), which takes minutes on a CPU."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytestmark = pytest.mark.slow


def test_surrogate_gradient_matches_central_differences_float64(x64) -> None:
    from harv_jax.aircraft import harv
    from harv_jax.dynamics.state import from_wind
    from harv_jax.optimal.objective import SurrogateConfig, surrogate
    from harv_jax.optimal.schedule import BRAKE_SWITCH_FPS, make_scheduled_smc
    from harv_jax.task.scenarios import sample_table_states

    params = jax.tree.map(lambda a: jnp.asarray(a, jnp.float64), harv())
    x0 = jnp.asarray(sample_table_states(jax.random.key(3), 1)[0], jnp.float64)
    # 0.6 s of closed loop, three chunks, knots every 0.2 s (all three inside the horizon)
    cfg = SurrogateConfig(n_steps=60, chunk_steps=20, hold_s=0.2)
    ref = jnp.asarray([0.349, 0.0, 0.0], jnp.float64)

    def objective(z):
        ctrl = make_scheduled_smc(z, BRAKE_SWITCH_FPS, 0.2)
        return surrogate(ctrl, params, from_wind(x0), jnp.zeros(3, jnp.float64), ref, cfg)

    z = 0.3 * jax.random.normal(jax.random.key(1), (3, 3), jnp.float64)
    grad = np.asarray(jax.jit(jax.grad(objective))(z))
    f = jax.jit(objective)
    h = 1e-6
    fd = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            e = jnp.zeros((3, 3), jnp.float64).at[i, j].set(h)
            fd[i, j] = (float(f(z + e)) - float(f(z - e))) / (2 * h)
    assert np.all(np.isfinite(grad)) and np.max(np.abs(fd)) > 1e-5  # a gradient that is not trivially 0
    # float64, step 1e-6: truncation ~h^2 |f'''| and rounding ~eps |f| / h, both far below 1e-5 relative
    np.testing.assert_allclose(grad, fd, rtol=1e-5, atol=1e-5 * np.max(np.abs(fd)))


def test_study_is_never_slower_than_the_best_controller_and_rescored_honestly() -> None:
    from harv_jax.evaluation.montecarlo.paired import times_nr_at_run_s
    from harv_jax.optimal.search import SearchConfig
    from harv_jax.optimal.study import BASELINES, OPTIMAL, mc_scenario, optimal_study

    cfg = SearchConfig(horizon_s=8.0, knot_dt_s=1.0, iterations=2, rounds=2)
    study = optimal_study(mc_scenario(seed=123, runs=4), 0.349, cfg)
    run_s = cfg.run_s
    t = {
        k: times_nr_at_run_s(o.metrics.t_recover_s, o.metrics.recovered, run_s)
        for k, o in study.outputs.items()
    }
    t_best = np.min(np.stack([t[k] for k in BASELINES]), axis=0)
    assert np.all(t[OPTIMAL] <= t_best)
    for i, src in enumerate(study.source):
        if src == OPTIMAL:  # the searched control's own re-simulated score, strictly faster
            assert study.search.metrics.recovered[i] and t[OPTIMAL][i] < t_best[i]
            np.testing.assert_allclose(t[OPTIMAL][i], study.search.metrics.t_recover_s[i], atol=0.011)
        else:  # a controller's own result, bit for bit
            assert src in BASELINES and t[OPTIMAL][i] == t[src][i] == t_best[i]
    assert study.search.objective.shape == (2, 4) and np.all(np.isfinite(study.search.objective))


def test_cli_writes_the_mc_layout_and_readable_demos(monkeypatch, capsys, tmp_path) -> None:
    import csv
    import json

    from harv_jax.optimal.demos import load_demos
    from tests.cli_util import cli_run

    out, demos = tmp_path / "o", tmp_path / "d.npz"
    code, stdout, err = cli_run(
        monkeypatch, capsys, "optimal", "--runs", "2", "--seed", "9", "--iterations", "1", "--horizon", "7",
        "--knot-spacing", "0.5", "--out", out, "--save-demos", demos,
    )  # fmt: skip
    assert code == 0, err
    rows = list(csv.DictReader((out / "runs.csv").open()))
    assert [r["controller"] for r in rows] == ["smc"] * 2 + ["smc-brake"] * 2 + ["rl"] * 2 + [
        "hybrid"
    ] * 2 + ["optimal"] * 2
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["controllers"]) == {"smc", "smc-brake", "rl", "hybrid", "optimal"}
    assert summary["optimal"]["never_slower_than_best"] is True
    for name in ("vs_optimal.png", "search_progress.png", "optimal_report.md", "optimal_runs.csv"):
        assert (out / name).stat().st_size > 0
    d = load_demos(demos)
    assert d.states_wind.shape == (2, 6001, 10) and d.observations.shape == (2, 6000, 11)
