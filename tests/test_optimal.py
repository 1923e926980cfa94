"""``harv_jax.optimal``: the class of controls, the demos format, the report section, the command's checks.

The search itself (gradient check, the Monte Carlo against the registry's controllers) is in
``test_optimal_slow.py``: its gradient graph takes minutes to compile on a CPU.
"""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.optimal import demos as demos_mod
from harv_jax.optimal.demos import FORMAT_VERSION, check_demos_path, load_demos, make_demos, save_demos
from harv_jax.optimal.schedule import OFFSET_AMPLITUDE_RAD, offset_at_rad
from harv_jax.optimal.search import SearchConfig, _better, check_search_config, rounds_for
from tests.cli_util import cli_run


def test_offset_is_piecewise_linear_through_the_knots_and_zero_after() -> None:
    z = jnp.asarray([[0.5, -0.2, 1.0], [-1.0, 0.3, 0.0]], jnp.float32)
    o = np.asarray(OFFSET_AMPLITUDE_RAD) * np.tanh(np.asarray(z))  # knot values
    at = lambda t: np.asarray(offset_at_rad(z, jnp.asarray(t, jnp.float32), 1.0))  # noqa: E731
    np.testing.assert_allclose(at(0.0), o[0], rtol=1e-6)
    np.testing.assert_allclose(at(1.0), o[1], rtol=1e-6)
    np.testing.assert_allclose(at(0.25), 0.75 * o[0] + 0.25 * o[1], rtol=1e-6)
    np.testing.assert_allclose(at(1.5), 0.5 * o[1], rtol=1e-6, atol=1e-7)  # toward 0 at t = 2
    np.testing.assert_array_equal(at(2.0), np.zeros(3))
    np.testing.assert_array_equal(at(7.3), np.zeros(3))
    assert np.all(np.abs(at(0.6)) <= np.asarray(OFFSET_AMPLITUDE_RAD))


@pytest.mark.slow
def test_zero_knots_fly_smc_brake_and_smc_exactly_and_iterates_respect_actuator_limits() -> None:
    from harv_jax.aircraft import harv
    from harv_jax.control.registry import build_controller
    from harv_jax.evaluation.closed_loop import closed_loop
    from harv_jax.optimal.schedule import BRAKE_SWITCH_FPS, NO_BRAKE_SWITCH_FPS, make_scheduled_smc

    p = harv()
    # fast (braking: V > 500 ft/s at first), nose-low, rolling: the braking reference switches in 300 steps
    x0 = jnp.asarray([540.0, -0.1, 0.1, 1.5, 0.3, -0.3, 0.4, -0.5, 0.0, 25_000.0], jnp.float32)
    ref = jnp.asarray([0.349, 0.0, 0.0], jnp.float32)
    n = 300
    z_rand = 3.0 * jax.random.normal(jax.random.key(0), (4, 3))

    @jax.jit
    def run():
        def fly(c):
            return closed_loop(
                controller=c, params=p, x0=x0, reference_rad=ref, key=jax.random.key(1), n_steps=n
            ).traj

        z0 = jnp.zeros((4, 3))
        return (
            fly(build_controller("smc-brake")), fly(make_scheduled_smc(z0, BRAKE_SWITCH_FPS, 0.5)),
            fly(build_controller("smc")), fly(make_scheduled_smc(z0, NO_BRAKE_SWITCH_FPS, 0.5)),
            fly(make_scheduled_smc(z_rand, BRAKE_SWITCH_FPS, 0.5)),
        )  # fmt: skip

    brake, brake_z0, smc, smc_z0, rand = run()
    assert np.any(np.asarray(brake.info["braking"])) and not np.all(np.asarray(brake.info["braking"]))
    # the same law: equal to float32 rounding (two compiled graphs may round differently, and 3 s of
    # closed loop amplify it only slightly; a wrong reference would differ by degrees at once)
    close = {"rtol": 1e-4, "atol": 1e-4}
    np.testing.assert_allclose(np.asarray(brake_z0.x_wind), np.asarray(brake.x_wind), **close)
    np.testing.assert_allclose(np.asarray(brake_z0.u_cmd_rad), np.asarray(brake.u_cmd_rad), **close)
    np.testing.assert_allclose(np.asarray(smc_z0.x_wind), np.asarray(smc.x_wind), **close)
    assert np.max(np.abs(np.asarray(brake.x_wind)[:, 1] - np.asarray(smc.x_wind)[:, 1])) > 0.01
    # an iterate far from the warm start: the reference moved (so the test is not vacuous) ...
    moved = np.abs(np.asarray(rand.info["reference_rad"]) - np.asarray(ref))
    assert np.max(moved[: n // 2, 1]) > 0.05  # beta's reference (0 for the warm start)
    # ... and the deflections still respect the position and rate limits of the actuator model
    d = np.asarray(rand.delta_rad)
    lo, hi, rate = np.asarray(p.u_min_rad), np.asarray(p.u_max_rad), np.asarray(p.u_rate_max_radps)
    assert np.all(d >= lo - 1e-6) and np.all(d <= hi + 1e-6)
    assert np.all(np.abs(np.diff(d, axis=0)) <= rate * 0.01 * (1 + 1e-4) + 1e-7)
    assert np.all(np.abs(d[0]) <= rate * 0.01 * (1 + 1e-4) + 1e-7)  # from 0 deflection at engagement


def _demo_arrays(n: int = 3, t: int = 5) -> demos_mod.Demos:
    rng = np.random.default_rng(0)
    x = 0.1 * rng.normal(size=(n, t + 1, 10)).astype(np.float32)  # inside the observation box
    x[..., 0] = 400.0
    cmd = rng.uniform(-0.3, 0.3, size=(n, t, 3)).astype(np.float32)
    lo, hi = np.array([-0.436, -0.436, -0.524]), np.array([0.175, 0.436, 0.524])
    return make_demos(x, cmd, np.array([0.349, 0, 0]), lo, hi, np.array([4.0, np.nan, 7.0]),
                      np.array([True, False, True]), np.array([True, False, False]), 0.01)  # fmt: skip


def test_demos_round_trip_observations_and_actions(tmp_path) -> None:
    d = _demo_arrays()
    path = save_demos(tmp_path / "d.npz", d)
    got = load_demos(path)
    np.testing.assert_array_equal(got.states_wind, d.states_wind)
    np.testing.assert_array_equal(got.actions, d.actions)
    assert got.n_runs == 3 and got.dt_s == 0.01
    # observation = the first 8 wind states then the target; action = affine map of the command to [-1, 1]
    np.testing.assert_allclose(got.observations[1, 2, :8], d.states_wind[1, 2, :8], rtol=0, atol=0)
    np.testing.assert_allclose(got.observations[1, 2, 8:], [0.349, 0, 0], rtol=1e-6)
    # de = 0 rad with limits [-0.436, 0.175]: 2 (0 + 0.436) / 0.611 - 1
    c = d.commands_rad[0, 0, 0]
    np.testing.assert_allclose(got.actions[0, 0, 0], 2 * (c + 0.436) / 0.611 - 1, rtol=1e-5)
    with np.load(path, allow_pickle=False) as z:
        assert int(z["format_version"]) == FORMAT_VERSION


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda a: a.update(format_version=np.array(FORMAT_VERSION + 1)), "format_version"),
        (lambda a: a.update(format=np.array("other")), "format"),
        (lambda a: a["states_wind"].__setitem__((0, 1, 2), np.nan), "non-finite"),
        (lambda a: a.update(actions=a["actions"][:, :-1]), "actions has shape"),
        (lambda a: a.pop("recovered"), "lacks recovered"),
        (lambda a: a.update(actions=a["actions"] * 3.0), "outside [-1, 1]"),
    ],
)
def test_load_demos_refuses_bad_files(tmp_path, change, message) -> None:
    d = _demo_arrays()
    good = save_demos(tmp_path / "good.npz", d)
    with np.load(good, allow_pickle=False) as z:
        arrays = {k: z[k].copy() for k in z.files}
    if message == "outside [-1, 1]":
        arrays["actions"][0, 0, 0] = 1.5
    else:
        change(arrays)
    bad = tmp_path / "bad.npz"
    np.savez(bad, **arrays)
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        load_demos(bad)


def test_load_demos_refuses_pickles_and_missing_files(tmp_path) -> None:
    bad = tmp_path / "obj.npz"
    np.savez(bad, format=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ValueError, match="pickle-free"):
        load_demos(bad)
    with pytest.raises(ValueError, match="does not exist"):
        load_demos(tmp_path / "none.npz")


def test_demos_path_checks(tmp_path) -> None:
    assert check_demos_path(tmp_path / "d.npz") == tmp_path / "d.npz"
    with pytest.raises(ValueError, match="does not exist"):
        check_demos_path(tmp_path / "no" / "d.npz")
    with pytest.raises(ValueError, match=r"\.npz"):
        check_demos_path(tmp_path / "d.txt")


def test_search_config_checks_and_rounds() -> None:
    check_search_config(SearchConfig())
    assert SearchConfig().n_knots == 10  # (15 s horizon - 5 s hold) / 1 s
    for bad, what in [(dict(iterations=0), "iterations"), (dict(horizon_s=4.0), "horizon"),
                      (dict(knot_dt_s=0.0), "knot spacing"), (dict(knot_dt_s=-1.0), "knot spacing"),
                      (dict(iterations=16, rounds=3), "rounds")]:  # fmt: skip
        with pytest.raises(ValueError, match=what):
            check_search_config(SearchConfig(**bad))
    assert rounds_for(12) == 6 and rounds_for(7) == 7 and rounds_for(11) == 1 and rounds_for(30) == 6


def test_acceptance_takes_only_strictly_faster_recovered_runs() -> None:
    t_new = np.array([5.0, 5.0, 5.0, np.nan, 3.0])
    rec_new = np.array([True, True, True, False, False])
    t_old = np.array([6.0, 5.0, np.nan, 9.0, 9.0])
    rec_old = np.array([True, True, False, True, True])
    np.testing.assert_array_equal(_better(t_new, rec_new, t_old, rec_old), [True, False, True, False, False])


def test_command_defaults_match_the_search() -> None:
    from harv_jax.commands import optimal as cmd

    cfg = SearchConfig()
    assert (cmd.RUN_S, cmd.SURROGATE_HOLD_S) == (cfg.run_s, cfg.hold_s)


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (("--iterations", "0"), "--iterations 0"),
        (("--iterations", "-3"), "--iterations -3"),
        (("--horizon", "0"), "--horizon 0.0"),
        (("--horizon", "-5"), "--horizon -5.0"),
        (("--knot-spacing", "0"), "--knot-spacing 0.0"),
        (("--knot-spacing", "-1"), "--knot-spacing -1.0"),
        (("--knot-spacing", "nan"), "--knot-spacing nan"),
        (("--scenario", "tumble"), "--scenario 'tumble'"),
        (("--save-demos", "/proc/demos.npz"), "--save-demos '/proc/demos.npz'"),
        (("--save-demos", "NODIR/d.npz"), "does not exist"),
    ],
)
def test_bad_input_one_line_exit_2_nothing_written(monkeypatch, capsys, tmp_path, args, named) -> None:
    monkeypatch.chdir(tmp_path)
    code, out, err = cli_run(monkeypatch, capsys, "optimal", "--out", "o", *args)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and named in lines[0], err
    assert list(tmp_path.iterdir()) == []


def test_report_section_from_a_summary() -> None:
    from harv_jax.report.optimal_section import optimal_markdown

    block = {"median": 2.0, "p95": 3.0, "mean": 2.2}
    summary = {
        "runs": 2, "seed": 5, "scenario": "mc",
        "optimal": {
            "control_class": "X", "recovered_fraction": 1.0, "never_slower_than_best": True,
            "strictly_faster_fraction": 0.5,
            "search": {"learning_rate": 0.1, "iterations": 4, "rounds": 2, "horizon_s": 20.0, "n_knots": 15,
                       "knot_dt_s": 1.0, "run_s": 60.0},
            "ratio_to_optimal": {"smc": block}, "recovery_time_s": {"smc": block, "optimal": block},
            "source_counts": {"optimal": 1, "rl": 1}, "best_controller_counts": {"rl": 2},
        },
    }  # fmt: skip
    md = optimal_markdown(json.loads(json.dumps(summary)))
    assert "| smc | 2.000 | 3.000 | 2.200 |" in md and "optimal 1, rl 1" in md and "50.0%" in md
