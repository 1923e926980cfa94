"""The braking SMCs (``smc-brake``, ``smc-brake-zoom``): the SMC's command for alpha_brake while braking,
the SMC's exactly otherwise; a traced schedule; the registry names; a short Monte Carlo without NaN."""

from __future__ import annotations

import functools
import json
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cli_util import cli_run

from harv_jax.aircraft import harv
from harv_jax.control import registry
from harv_jax.control.base import Controller
from harv_jax.control.smc import SMCConfig, make_smc
from harv_jax.control.smc_brake import (
    ALPHA_BRAKE_RAD,
    V_SWITCH_FPS,
    V_ZOOM_FPS,
    ZOOM_SLOPE_FPS_PER_RAD,
    ZOOM_V_SWITCH_FPS,
    SMCBrakeState,
    brake_schedule,
    braking_reference,
    make_smc_brake,
)
from harv_jax.errors import UsageError
from harv_jax.evaluation.montecarlo.rollout import run_mc, sample_mc_inputs
from harv_jax.task.criteria import Outcome
from harv_jax.task.spec import ALPHA_TARGET_RAD

REF = jnp.array([ALPHA_TARGET_RAD, 0.0, 0.0])
KEY = jax.random.key(0)


def _state(v_fps: float, k: int = 0) -> jnp.ndarray:
    """An upset wind state [10] at airspeed ``v_fps`` (k varies the angles and rates)."""
    return jnp.array([v_fps, 0.5 + 0.05 * k, 0.1, 0.4, -0.2 + 0.1 * k, 0.1, 0.3, 0.2, 0.0, 20_000.0])


def _fly(
    ctrl: Controller, states: list[jnp.ndarray], refs: list[jnp.ndarray], apply=None
) -> list[np.ndarray]:
    """Commands of ``ctrl`` (its jitted ``apply``, if given) stepped through ``states`` with references
    ``refs``, the controller state carried from step to step."""
    apply = jax.jit(ctrl.apply) if apply is None else apply
    cs = ctrl.init(harv())
    out = []
    for x, r in zip(states, refs, strict=True):
        u, cs, _ = apply(cs, x, r, KEY)
        out.append(np.asarray(u))
    return out


@functools.cache
def _smc(switching: str = "sat") -> tuple[Controller, Callable]:
    """``make_smc`` with ``switching`` and its jitted apply, built once: the tests below share its compile."""
    ctrl = make_smc(SMCConfig(switching=switching))
    return ctrl, jax.jit(ctrl.apply)


@pytest.mark.parametrize("switching", ["sat", "sign"])
def test_command_is_the_smc_for_the_scheduled_reference(switching):
    """Above V_switch: the SMC's command with alpha_d -> alpha_brake; below: the SMC's exactly. Over a
    sequence that crosses V_switch both ways, so the carried state (integral, reset) matches too."""
    brake = make_smc_brake(SMCConfig(switching=switching))
    brake_apply = jax.jit(brake.apply)
    smc, smc_apply = _smc(switching)
    speeds = [800.0, 700.0, 600.0, 450.0, 400.0, 550.0, 300.0]
    states = [_state(v, k) for k, v in enumerate(speeds)]
    brake_ref = REF.at[0].set(ALPHA_BRAKE_RAD)
    smc_refs = [brake_ref if v > V_SWITCH_FPS else REF for v in speeds]
    u_brake = _fly(brake, states, [REF] * len(states), brake_apply)
    u_smc = _fly(smc, states, smc_refs, smc_apply)
    for ub, us in zip(u_brake, u_smc, strict=True):
        np.testing.assert_array_equal(ub, us)
    # below V_switch throughout: the plain SMC's commands exactly
    slow = [_state(v, k) for k, v in enumerate([480.0, 300.0, 200.0])]
    u_slow_brake = _fly(brake, slow, [REF] * 3, brake_apply)
    for ub, us in zip(u_slow_brake, _fly(smc, slow, [REF] * 3, smc_apply), strict=True):
        np.testing.assert_array_equal(ub, us)
    # and the braking reference does change the command
    assert not np.array_equal(_fly(smc, states[:1], [REF], smc_apply)[0], u_brake[0])


def test_schedule_is_traced_and_reported():
    """A new schedule in the state reuses the compiled apply; info reports the reference flown."""
    ctrl = make_smc_brake()
    traces = []

    @jax.jit
    def step(cs: SMCBrakeState, x: jnp.ndarray):
        traces.append(1)
        return ctrl.apply(cs, x, REF, KEY)

    cs0 = ctrl.init(harv())
    x = _state(550.0)
    u_brake, _, info_brake = step(cs0, x)
    u_high, _, info_high = step(cs0.replace(schedule=brake_schedule(0.8, 600.0)), x)
    assert len(traces) == 1
    assert bool(info_brake["braking"]) and float(info_brake["alpha_ref_rad"]) == pytest.approx(1.0)
    assert not bool(info_high["braking"]) and float(info_high["alpha_ref_rad"]) == pytest.approx(REF[0])
    smc, smc_apply = _smc()
    u_smc = _fly(smc, [x], [REF], smc_apply)[0]
    np.testing.assert_array_equal(np.asarray(u_high), u_smc)
    assert not np.array_equal(np.asarray(u_brake), u_smc)


@pytest.mark.parametrize(
    "args, needle",
    [
        ((2.0, 500.0), "alpha_brake_rad 2.0 is outside the alpha envelope"),
        ((float("nan"), 500.0), "alpha_brake_rad nan"),
        ((1.0, -1.0), "v_switch_fps -1.0 must be in [0, 2000]"),
    ],
)
def test_bad_schedule_is_a_one_line_usage_error(args, needle):
    with pytest.raises(UsageError) as e:
        brake_schedule(*args)
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_registry_name():
    assert "smc-brake" in registry.controller_names()
    assert registry.CONTROLLERS["smc-brake"].options == ("switching",)
    assert registry.parse_controllers("smc,smc-brake") == ["smc", "smc-brake"]
    assert not registry.uses_option(["smc-brake"], "policy")
    ctrl = registry.build_controller("smc-brake", registry.ControllerOptions(switching="sign"))
    assert isinstance(ctrl, Controller) and isinstance(ctrl.init(harv()), SMCBrakeState)


@pytest.mark.slow
def test_short_monte_carlo_is_finite():
    """16 runs of 20 s: finite metrics, no non-finite outcome, and the schedule brakes on the fast runs."""
    inputs = sample_mc_inputs(jax.random.key(1), 16, harv())
    out, _ = run_mc(make_smc_brake(), inputs, REF, 2000, record_every=10, chunk_size=16)
    m = out.metrics
    assert not np.any(np.asarray(m.nonfinite)) and not np.any(np.asarray(m.outcome) == Outcome.NONFINITE)
    assert np.all(np.isfinite(out.history)) and np.all(np.isfinite(out.terminal_error_rad))
    assert np.all(np.isfinite(m.control_tv_rad)) and np.all(np.isfinite(m.altitude_loss_ft))
    braking = out.info_means["braking"]
    fast = np.asarray(inputs.x0_wind[:, 0]) > V_SWITCH_FPS
    assert fast.any() and np.all(braking[fast] > 0) and np.all((braking >= 0) & (braking <= 1))


@pytest.mark.slow
def test_short_monte_carlo_beside_the_smc(monkeypatch, capsys, tmp_path):
    """``harv-jax mc --controller smc,smc-brake``, 16 runs of 20 s: no NaN, smc-brake paired against smc
    (two compiles: slow)."""
    out = tmp_path / "mc"
    code, stdout, err = cli_run(
        monkeypatch, capsys, "mc", "--controller", "smc,smc-brake", "--runs", "16", "--duration", "20",
        "--chunk", "16", "--out", out,
    )  # fmt: skip
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    assert list(s["controllers"]) == ["smc", "smc-brake"] and "vs_smc" not in s["controllers"]["smc"]
    brake = s["controllers"]["smc-brake"]
    assert brake["outcomes"]["nonfinite"] == 0 and sum(brake["outcomes"].values()) == 16
    assert all(brake["terminal_error_deg"][ch]["mean"] is not None for ch in ("alpha", "beta", "mu"))
    assert 0.0 < brake["t_recover_mean_nr_at_run_s"] <= 20.0
    vs = brake["vs_smc"]
    assert vs["runs"] == 16 and vs["run_length_s"] == pytest.approx(20.0) and vs["mean_ratio"] > 0
    assert vs["faster_fraction"] + vs["slower_fraction"] <= 1.0
    rows = [r.split(",") for r in (out / "runs.csv").read_text().splitlines()[1:]]
    # terminal errors, altitude loss, control TV and chatter of every run: finite
    assert len(rows) == 32 and all(np.isfinite(float(v)) for r in rows for v in r[15:21])
    assert "[mc] smc-brake vs smc:" in stdout and (out / "bands_smc-brake.png").exists()


def _wind(v_fps: float, gamma_rad: float) -> jnp.ndarray:
    """_state(v_fps) with flight-path angle ``gamma_rad``."""
    return _state(v_fps).at[7].set(gamma_rad)


@pytest.mark.parametrize(
    "v_fps, gamma_rad, brakes",
    [
        (700.0, 0.0, True),  # inside the band, level
        (1150.0, 0.0, True),  # below the level-flight bound 1200
        (1250.0, 0.0, False),  # above it: the zoom climb does the braking
        (1000.0, 0.5, False),  # bound 1200 - 600 * 0.5 = 900 ft/s
        (850.0, 0.5, True),
        (1100.0, -0.5, True),  # a dive does not raise the bound: max(gamma, 0)
        (550.0, 0.0, False),  # below V_switch = 600 ft/s
    ],
)
def test_smc_brake_zoom_brakes_below_the_zoom_bound(v_fps, gamma_rad, brakes):
    """Braking iff V_switch < V < V_zoom - k_zoom max(gamma, 0), and the alpha reference follows the flag."""
    sched = brake_schedule(
        v_switch_fps=ZOOM_V_SWITCH_FPS, v_zoom_fps=V_ZOOM_FPS, zoom_slope_fps_per_rad=ZOOM_SLOPE_FPS_PER_RAD
    )
    ref, braking = braking_reference(_wind(v_fps, gamma_rad), REF, sched)
    assert bool(braking) is brakes
    assert float(ref[0]) == pytest.approx(ALPHA_BRAKE_RAD if brakes else float(REF[0]))
    np.testing.assert_array_equal(np.asarray(ref[1:]), np.asarray(REF[1:]))
    # smc-brake (no upper bound) brakes at every airspeed above its V_switch, whatever the climb angle
    _, default_braking = braking_reference(_wind(1900.0, 1.2), REF, brake_schedule())
    assert bool(default_braking)


def test_smc_brake_zoom_flies_smc_brake_or_the_smc_exactly():
    """The registry's smc-brake-zoom: smc-brake's command while braking, the SMC's in a zoom climb."""
    zoom = registry.build_controller("smc-brake-zoom")
    assert zoom.init(harv()).schedule.v_zoom_fps == pytest.approx(V_ZOOM_FPS)
    braking = [_wind(900.0, 0.1), _wind(800.0, 0.2)]
    zooming = [_wind(1300.0, 0.0), _wind(1000.0, 0.6)]
    for states, other in ((braking, make_smc_brake()), (zooming, make_smc())):
        refs = [REF] * len(states)
        got, want = _fly(zoom, states, refs, zoom.apply), _fly(other, states, refs, other.apply)
        for g, w in zip(got, want, strict=True):
            np.testing.assert_array_equal(g, w)


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"v_zoom_fps": 400.0}, "v_zoom_fps 400.0 must be above v_switch_fps (500"),
        ({"v_zoom_fps": float("nan")}, "v_zoom_fps nan"),
        ({"zoom_slope_fps_per_rad": -1.0}, "zoom_slope_fps_per_rad -1.0 must be finite and >= 0"),
        ({"zoom_slope_fps_per_rad": float("inf")}, "zoom_slope_fps_per_rad inf"),
    ],
)
def test_bad_zoom_bound_is_a_one_line_usage_error(kwargs, needle):
    with pytest.raises(UsageError) as e:
        brake_schedule(**kwargs)
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_integral_resets_on_any_reference_change():
    """Any change of the reference, however small, resets the SMC's integral (it starts again from 0)."""
    x = jnp.array([400.0, float(REF[0]) + 0.01, 0.005, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 20_000.0])
    refs = [REF, REF, REF.at[0].add(0.005), REF.at[0].add(0.005 + 0.1)]
    # (no freeze while saturated: this test is about the reset rule alone)
    ctrl = make_smc(SMCConfig(freeze_integral_when_saturated=False))
    cs = ctrl.init(harv())
    integrals = []
    for r in refs:
        _, cs, _ = ctrl.apply(cs, x, r, KEY)
        integrals.append(np.asarray(cs.integral_rad_s))
    assert np.abs(integrals[1][1]) > np.abs(integrals[0][1])  # unchanged reference: the integral grows
    for k in (2, 3):  # after each move the integral went on from 0, not from its last value
        assert not np.abs(integrals[k][1]) > np.abs(integrals[k - 1][1]) * 1.2, integrals
