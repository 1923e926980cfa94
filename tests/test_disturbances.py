"""The disturbance model in the closed loop and the Monte Carlo: zero levels change nothing, common random
numbers, the noise's statistics, the delay, the gust's air-relative scoring and model error."""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.aircraft import harv
from harv_jax.cli_options import LEVEL_OPTION_HELP
from harv_jax.control.base import Controller
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.dynamics.disturbances import DEFAULT_NOISE_STD_MAX, DisturbanceParams
from harv_jax.dynamics.disturbed_step import air_relative
from harv_jax.dynamics.state import from_wind, to_wind
from harv_jax.errors import UsageError
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.evaluation.montecarlo.disturbances import DisturbanceSpec, parse_disturbances
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs, with_full_structure
from harv_jax.evaluation.robustness import margin
from harv_jax.task.disturbance_table import DISTURBANCES, markdown_table

X0 = jnp.array([600.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25_000.0])
REF = jnp.array([0.349, 0.0, 0.0])


def _probe(u_rad: float = 0.0, step_at: int = 0) -> Controller:
    """A controller that records what it sees (info["x_seen"]) and the mass of the aircraft it was built on;
    commands ``u_rad`` on the elevator from step ``step_at`` on. Both live in its state, so that a flight
    given that state as ``ctrl_state`` compiles once for every command (``_fly``)."""

    def init(params):
        return {
            "mass": params.mass_slug,
            "k": jnp.zeros((), jnp.int32),
            "u": jnp.asarray(u_rad, jnp.float32),
            "at": jnp.asarray(step_at, jnp.int32),
        }

    def apply(state, x, ref, key):
        u = jnp.array([1.0, 0.0, 0.0], x.dtype) * jnp.where(state["k"] >= state["at"], state["u"], 0.0)
        return u, {**state, "k": state["k"] + 1}, {"x_seen": x, "model_mass": state["mass"]}

    return Controller(init, apply)


def _levels(noise=0.0, delay=0, gust=0.0, tau=5.0) -> DisturbanceParams:
    return DisturbanceParams(
        noise_std=jnp.asarray(noise * DEFAULT_NOISE_STD_MAX, jnp.float32),
        delay_steps=jnp.asarray(delay, jnp.int32),
        gust_std_fps=jnp.asarray(gust, jnp.float32),
        gust_tau_s=jnp.asarray(tau, jnp.float32),
    )


#: One probe for every flight of ``_fly`` (the compiled flight is cached by its closure).
PROBE = _probe()
N_FLY = 200
MAX_DELAY = 8


@jax.jit
def _fly_compiled(ctrl_state, levels: DisturbanceParams, disturbance_key):
    return closed_loop(
        PROBE, harv(), X0, REF, jax.random.key(0), N_FLY, ctrl_state=ctrl_state, disturbance=levels,
        disturbance_key=disturbance_key, max_delay_steps=MAX_DELAY,
    ).traj  # fmt: skip


def _fly(disturbance_key, u_rad: float = 0.0, step_at: int = 0, **levels):
    """The trajectory of ``N_FLY`` steps of the probe commanding ``u_rad`` from step ``step_at``, disturbed at
    ``levels`` (``_levels``' arguments) drawn from ``disturbance_key``, a command FIFO of ``MAX_DELAY`` + 1.
    The command, the levels and the key are traced: one compile serves every call."""
    return _fly_compiled(_probe(u_rad, step_at).init(harv()), _levels(**levels), disturbance_key)


def test_spec_none_is_the_undisturbed_monte_carlo_exactly():
    key = jax.random.key(3)
    plain = sample_mc_inputs(key, 8, harv())
    spec = sample_mc_inputs(key, 8, harv(), disturbances=DisturbanceSpec())
    assert spec.disturbance is None and spec.model_params is None and spec.max_delay_steps == 0
    np.testing.assert_array_equal(plain.x0_wind, spec.x0_wind)
    np.testing.assert_array_equal(jax.random.key_data(plain.keys), jax.random.key_data(spec.keys))
    for a, b in zip(jax.tree.leaves(plain.params), jax.tree.leaves(spec.params), strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow
def test_zero_levels_fly_as_none():
    """Every disturbance on at level zero (noise 0, delay 0, gust 0, the plant's own model): the same
    outcomes, recovery times and histories as the undisturbed loop (a constant command: cheap to compile)."""
    ctrl = _probe(-0.03)
    inputs = sample_mc_inputs(jax.random.key(5), 6, harv())
    full = with_full_structure(inputs, max_delay_steps=3)
    a, _ = run_mc(ctrl, inputs, REF, 400, record_every=100)
    b, _ = run_mc(ctrl, full, REF, 400, record_every=100)
    np.testing.assert_array_equal(a.metrics.outcome, b.metrics.outcome)
    np.testing.assert_allclose(a.metrics.t_recover_s, b.metrics.t_recover_s, rtol=0, atol=1e-4)
    np.testing.assert_allclose(a.history, b.history, rtol=1e-5, atol=1e-5)


def _noise_seen(key, u_rad: float = 0.0, noise: float = 1.0) -> np.ndarray:
    traj = _fly(key, u_rad, noise=noise)
    return np.asarray(traj.info["x_seen"] - traj.x_wind)


def test_every_controller_sees_the_same_noise_sequence():
    key = jax.random.key(11)
    n_a = _noise_seen(key, 0.0)
    n_b = _noise_seen(key, -0.2)  # another command: another flight, the same noise
    np.testing.assert_allclose(n_a[:, :8], n_b[:, :8], rtol=0, atol=2e-3)  # V (ft/s) carries float32 rounding
    np.testing.assert_allclose(n_a[:, 1:8], n_b[:, 1:8], rtol=0, atol=2e-6)
    assert np.all(n_a[:, 8:] == 0)  # chi and h are not measured with noise
    assert not np.allclose(_noise_seen(jax.random.key(12)), n_a)


def test_noise_has_the_configured_mean_and_std():
    """20,000 samples: 100 flights of 200 steps, each with its own disturbance key."""
    keys = jax.random.split(jax.random.key(2), 100)
    noise = np.concatenate([_noise_seen(k, noise=2.0)[:, :8] for k in keys])
    std = 2.0 * DEFAULT_NOISE_STD_MAX
    n = noise.shape[0]
    assert n == 20_000
    assert np.all(np.abs(noise.mean(axis=0)) < 5 * std / np.sqrt(n))
    np.testing.assert_allclose(noise.std(axis=0), std, rtol=0.03)


@pytest.mark.parametrize("delay", [0, 1, 5])
def test_a_step_command_reaches_the_plant_d_steps_later(delay):
    k0 = 10
    de = np.asarray(_fly(jax.random.key(1), -0.05, k0, delay=delay).delta_rad[:, 0])
    moved = np.flatnonzero(de != 0.0)
    assert moved[0] == k0 + delay  # delta_rad[k]: the deflection over the step after the command of step k


def test_delay_is_clipped_to_the_fifo():
    k0 = 10
    de = np.asarray(_fly(jax.random.key(1), -0.05, k0, delay=50).delta_rad[:, 0])
    assert np.flatnonzero(de != 0.0)[0] == k0 + MAX_DELAY


def test_gust_is_stationary_and_scored_air_relative():
    body = from_wind(X0)
    np.testing.assert_array_equal(np.asarray(air_relative(body, jnp.zeros(3))), np.asarray(to_wind(body)))
    x = air_relative(body, jnp.array([0.0, 0.0, 30.0]))  # a 30 ft/s downward body-axis gust: alpha falls
    assert float(x[1]) < float(X0[1]) - 0.04
    traj = _fly(jax.random.key(4), gust=10.0, tau=0.2)
    seen = np.asarray(traj.info["x_seen"])  # no noise: the controller sees the scored state
    np.testing.assert_array_equal(seen, np.asarray(traj.x_wind))


@jax.jit
def _model_mass_seen(params, model_params):
    """The mass the probe was built on, flying ``params`` with the controller's model ``model_params``."""
    res = closed_loop(PROBE, params, X0, REF, jax.random.key(0), 3, model_params=model_params)
    return res.traj.info["model_mass"][0]


def test_model_error_builds_controllers_on_the_nominal_aircraft():
    nominal_mass = float(harv().mass_slug)
    for knows in (False, True):
        spec = DisturbanceSpec(model_error=2.0, controller_knows_aircraft=knows)
        inputs = sample_mc_inputs(jax.random.key(9), 6, harv(), disturbances=spec)
        plant_mass = np.asarray(inputs.params.mass_slug)
        assert np.ptp(plant_mass) > 0.05 * nominal_mass  # the plant is randomized (2x the ranges)
        run = jax.tree.map(lambda a: a[0], inputs)
        seen = float(_model_mass_seen(run.params, run.model_params))
        assert seen == pytest.approx(plant_mass[0] if knows else nominal_mass)


def test_randomize_equals_model_error_one():
    a = sample_mc_inputs(jax.random.key(1), 5, harv(), randomize=True)
    b = sample_mc_inputs(jax.random.key(1), 5, harv(), disturbances=DisturbanceSpec(model_error=1.0))
    np.testing.assert_array_equal(a.params.aero_scale, b.params.aero_scale)
    np.testing.assert_array_equal(a.model_params.mass_slug, float(harv().mass_slug))


def test_parse_disturbances_levels_and_errors():
    assert parse_disturbances("none").active == ()
    d = parse_disturbances("default")
    assert d.active == ("noise", "delay", "model", "lag", "turbulence") and d.delay_steps == 2
    assert d.turbulence == "moderate" and d.gust_fps == 0.0
    assert parse_disturbances("default", turbulence="severe").turbulence == "severe"
    assert parse_disturbances("default", turbulence="none").active == ("noise", "delay", "model", "lag")
    assert parse_disturbances("noise", {"noise": 3.0}).noise_scale == 3.0
    assert parse_disturbances("none", randomize=True).model_error == 1.0
    bad = [
        ("wind", {}), ("noise,noise", {}), ("default,noise", {}), ("", {}),
        ("noise", {"noise": -1.0}), ("noise", {"noise": float("nan")}), ("delay", {"delay": 5000.0}),
        ("noise", {"gust": 5.0}),
    ]  # fmt: skip
    for names, levels in bad:
        with pytest.raises(UsageError):
            parse_disturbances(names, levels)
    with pytest.raises(UsageError, match="controller-knows-aircraft"):
        parse_disturbances("noise", controller_knows_aircraft=True)


def test_margin():
    assert margin([0, 50, 100, 150], [1.0, 0.995, 0.98, 1.0]) == 50
    assert margin([0, 1], [0.5, 1.0]) is None
    assert margin([0, 1, 2], [1.0, 1.0, 1.0]) == 2


@pytest.mark.parametrize("order", [1, 2])
def test_measurement_filter_gain_equals_its_design(order):
    """A sine through the wrapped controller's input: the measured steady-state gain at a few frequencies
    equals the design's (1 at DC, 1/sqrt(2) at the cutoff, the Butterworth roll-off above)."""
    from harv_jax.control.filters import butterworth_coefficients, frequency_gain, with_measurement_filter

    cutoff_hz = 2.0
    probe = Controller(lambda p: jnp.zeros(()), lambda s, x, r, k: (jnp.zeros(3), s, {"y": x[:8]}))
    ctrl = with_measurement_filter(probe, cutoff_hz, order)
    b, a = butterworth_coefficients(cutoff_hz, order)
    assert frequency_gain(b, a, 0.0) == pytest.approx(1.0, abs=1e-12)
    assert frequency_gain(b, a, cutoff_hz) == pytest.approx(2**-0.5, abs=1e-9)
    t = jnp.arange(3000) * 0.01

    def run(f_hz):
        def step(state, tk):
            x = jnp.zeros(10).at[:8].set(jnp.sin(2 * jnp.pi * f_hz * tk))
            _, state, info = ctrl.apply(state, x, REF, None)
            return state, info["y"]

        _, y = jax.lax.scan(step, ctrl.init(harv()), t)
        return np.asarray(y[1500:])

    for f_hz in (0.25, 1.0, cutoff_hz, 8.0):
        y = run(f_hz)
        gain = (y.max(axis=0) - y.min(axis=0)) / 2
        np.testing.assert_allclose(gain, frequency_gain(b, a, f_hz), rtol=0.01, atol=2e-3)
    x_const = jnp.full((10,), 3.0)
    _, _, info = ctrl.apply(ctrl.init(harv()), x_const, REF, None)
    np.testing.assert_allclose(np.asarray(info["y"]), 3.0, rtol=1e-6)  # starts at the first measurement


def test_filter_rejects_bad_designs():
    from harv_jax.control.filters import butterworth_coefficients

    for cutoff, order in ((0.0, 2), (50.0, 2), (float("nan"), 1), (2.0, 3)):
        with pytest.raises(ValueError):
            butterworth_coefficients(cutoff, order)


def test_filter_suffix_in_the_registry():
    from harv_jax.control.registry import parse_controllers, split_filter, uses_option

    assert split_filter("smc+lp2") == ("smc", ("+lp", 2.0)) and split_filter("rl") == ("rl", None)
    assert split_filter("smc+obs0.5") == ("smc", ("+obs", 0.5))
    assert parse_controllers("smc+lp2,rl+lp1.5") == ["smc+lp2", "rl+lp1.5"]
    assert uses_option(["rl+lp2"], "policy") and not uses_option(["smc+lp2"], "policy")
    for bad in ("smc+lp", "smc+lpx", "smc+lp0", "smc+lp60", "smc+lpnan", "bogus+lp2"):
        with pytest.raises(UsageError):
            parse_controllers(bad)
    # the filtered SMC from the plant's initial deflections: its state carries them to the wrapped SMC
    ctrl, plain = build_controller("smc+lp2", ControllerOptions()), build_controller("smc")
    delta0 = jnp.array([-0.1, 0.05, 0.02])
    start_f = ctrl.init(harv()).replace(u_prev_rad=delta0)  # as closed_loop starts any controller
    start_p = plain.init(harv()).replace(u_prev_rad=delta0)
    _, filtered, _ = ctrl.apply(start_f, X0, REF, jax.random.key(0))  # one step, eager
    _, plain_state, _ = plain.apply(start_p, X0, REF, jax.random.key(0))
    u_f, u_p = filtered.inner.u_prev_rad, plain_state.u_prev_rad
    np.testing.assert_allclose(np.asarray(u_f), np.asarray(u_p), atol=1e-5)  # first step: same input
    assert ctrl.init(harv()).u_prev_rad.shape == (3,)


@pytest.mark.slow
def test_a_users_controller_flies_in_the_monte_carlo(tmp_path):
    """``monte_carlo`` takes name -> Controller: a user's own controller beside a registered one; runs.csv
    gets the disturbance levels as its last columns. Both fly the same probe: the second rollout's program
    is the first's, which the test run's compilation cache (conftest) reads back instead of compiling."""
    import csv

    from harv_jax.evaluation.montecarlo.study import monte_carlo, write_runs_csv

    spec = DisturbanceSpec(noise_scale=1.0, delay_ms=30.0)
    study = monte_carlo({"hold": PROBE, "smc": PROBE}, None, 3, 0.349, 1.0, 1, False, disturbances=spec)
    assert list(study.outputs) == ["hold", "smc"] and "vs_smc" in study.summary["controllers"]["hold"]
    assert study.summary["disturbances"]["delay_steps"] == 3
    write_runs_csv(tmp_path / "runs.csv", study.x0_wind, study.outputs, spec)
    rows = list(csv.DictReader((tmp_path / "runs.csv").open()))
    assert len(rows) == 6 and rows[0]["delay_ms"] == "30" and rows[0]["noise_scale"] == "1"


def test_the_docs_show_the_declared_disturbance_table():
    docs = (Path(__file__).resolve().parents[1] / "docs" / "robustness.md").read_text()
    assert markdown_table() in docs
    # every numeric level has its CLI option, with the table's default in its help
    for d in DISTURBANCES:
        if d.name != "turbulence":
            assert f"default {d.default:g})" in LEVEL_OPTION_HELP[d.parameter]
