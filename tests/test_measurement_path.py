"""A policy's measurement path: recorded in its metadata, validated on load, flown by ``rl`` and ``hybrid``
exactly as the suffix flies it, refused with a suffix and by the StableHLO export; the training env's
observation through it; a policy without one unchanged."""

from __future__ import annotations

import json
import math
from pathlib import Path

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from cli_util import assert_train_preset_refused, cli_run

from harv_jax.aircraft import harv
from harv_jax.control.registry import ControllerOptions, build_controller
from harv_jax.control.rl import make_rl_controller
from harv_jax.dynamics.disturbances import DEFAULT_NOISE_STD_MAX, DisturbanceParams
from harv_jax.errors import UsageError
from harv_jax.evaluation.closed_loop import closed_loop
from harv_jax.policy import resolve_policy
from harv_jax.task.measurement_path import path_from_record

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "harv_jax/policies/teacher.npz"


def _with_meta(tmp_path: Path, name: str, **changes) -> Path:
    """A copy of the shipped policy with its metadata changed."""
    with np.load(SHIPPED, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays["meta"]))
    meta.update(changes)
    arrays["meta"] = np.asarray(json.dumps(meta))
    out = tmp_path / name
    np.savez(out, **arrays)
    return out


def _fly(controller, n_steps=300):
    x0 = jnp.array([350.0, 0.5, 0.05, 0.3, 0.1, 0.2, 0.2, 0.0, 0.0, 25000.0])
    noise = DisturbanceParams(
        jnp.asarray(DEFAULT_NOISE_STD_MAX, jnp.float32),
        jnp.asarray(0, jnp.int32),
        jnp.asarray(0.0),
        jnp.asarray(5.0),
    )
    res = jax.jit(
        lambda: closed_loop(
            controller, harv(), x0, jnp.array([0.349, 0.0, 0.0]), jax.random.key(1), n_steps,
            disturbance=noise, disturbance_key=jax.random.key(2),
        )
    )()  # fmt: skip
    return np.asarray(res.traj.x_wind), np.asarray(res.traj.u_cmd_rad)


@pytest.mark.parametrize(
    "kind",
    ["rl", pytest.param("hybrid", marks=pytest.mark.slow)],  # the hybrid: 3 more compiles, ~35 s
)
def test_a_policy_flies_behind_the_path_it_carries(tmp_path, kind):
    carried = _with_meta(tmp_path, "lp.npz", measurement_path={"kind": "lp", "bandwidth_hz": 2.0})
    behind = build_controller(kind, ControllerOptions(policy=str(carried)))
    suffixed = build_controller(f"{kind}+lp2", ControllerOptions(policy=str(SHIPPED)))
    plain = build_controller(kind, ControllerOptions(policy=str(SHIPPED)))
    x_b, u_b = _fly(behind)
    x_s, u_s = _fly(suffixed)
    np.testing.assert_array_equal(u_b, u_s)  # exactly as the suffix flies it
    np.testing.assert_array_equal(x_b, x_s)
    assert not np.array_equal(u_b, _fly(plain)[1])  # and the path acts


def test_behind_a_path_the_hybrid_flies_the_path_gains(tmp_path, monkeypatch):
    """Carried or by suffix, behind a path the hybrid takes ``path_hybrid_gains`` (its simplex fallback on
    the default SMC gains); without one the default gains, as before."""
    from harv_jax.control.hybrid import law

    seen = []
    monkeypatch.setattr(law, "make_hybrid", lambda act, cfg, gains: seen.append(gains))
    monkeypatch.setattr("harv_jax.control.registry.with_measurement_path", lambda ctrl, path: ctrl)
    carried = _with_meta(tmp_path, "lp.npz", measurement_path={"kind": "lp", "bandwidth_hz": 2.0})
    build_controller("hybrid", ControllerOptions(policy=str(carried)))
    build_controller("hybrid+obs0.3", ControllerOptions(policy=str(SHIPPED)))
    build_controller("hybrid", ControllerOptions(policy=str(SHIPPED)))
    path, plain = law.path_hybrid_gains(), law.default_hybrid_gains()
    chex.assert_trees_all_equal(seen[0], path)
    chex.assert_trees_all_equal(seen[1], path)
    chex.assert_trees_all_equal(seen[2], plain)


def test_a_policy_without_a_path_is_unchanged():
    pol = resolve_policy(str(SHIPPED))
    assert "measurement_path" not in pol.meta
    x_a, u_a = _fly(build_controller("rl", ControllerOptions(policy=str(SHIPPED))))
    x_b, u_b = _fly(make_rl_controller(pol.deterministic))
    np.testing.assert_array_equal(u_a, u_b)
    np.testing.assert_array_equal(x_a, x_b)


@pytest.mark.parametrize(
    ("record", "message"),
    [
        (
            {"kind": "kalman", "bandwidth_hz": 1.0},
            "measurement path kind 'kalman' is unknown; allowed: lp, obs, eso",
        ),
        ({"kind": "lp", "bandwidth_hz": math.nan}, "measurement path bandwidth nan Hz"),
        ({"kind": "obs", "bandwidth_hz": 100.0}, "measurement path bandwidth 100.0 Hz"),
        ({"kind": "lp"}, "must be {'kind': ..., 'bandwidth_hz': ...}"),
        ("lp2", "must be {'kind': ..., 'bandwidth_hz': ...}"),
    ],
)
def test_bad_path_metadata_is_refused_on_load(tmp_path, record, message):
    bad = _with_meta(tmp_path, "bad.npz", measurement_path=record)
    with pytest.raises(UsageError, match=None) as e:
        resolve_policy(str(bad))
    assert message in str(e.value) and "\n" not in str(e.value)


def test_a_suffix_on_a_policy_that_carries_a_path_is_refused(tmp_path, monkeypatch, capsys):
    carried = _with_meta(tmp_path, "obs.npz", measurement_path={"kind": "obs", "bandwidth_hz": 0.3})
    with pytest.raises(UsageError, match="carries its measurement path .obs 0.3 Hz. and flies behind it"):
        build_controller("rl+lp2", ControllerOptions(policy=str(carried)))
    code, _, err = cli_run(
        monkeypatch, capsys, "mc", "--controller", "rl+lp2", "--policy", carried, "--runs", "2", "--out",
        tmp_path / "mc",
    )  # fmt: skip
    assert code == 2 and "drop the suffix" in err and err.count("\n") == 1
    assert not (tmp_path / "mc").exists()


def test_the_stablehlo_export_refuses_a_policy_with_a_path(tmp_path):
    from harv_jax.policy_stablehlo import export_available, export_stablehlo

    if not export_available():
        pytest.skip("jax.export serialization needs flatbuffers")
    carried = resolve_policy(
        str(_with_meta(tmp_path, "lp.npz", measurement_path={"kind": "lp", "bandwidth_hz": 2}))
    )
    with pytest.raises(UsageError, match="carries a measurement path"):
        export_stablehlo(tmp_path / "p.stablehlo", carried)
    assert not (tmp_path / "p.stablehlo").exists()


def test_the_training_env_observes_through_the_path():
    """The measured env's observation is the path's estimate of the noisy air data: at a reset the
    low-pass starts at its input (the env's own observation), then it is smoother than the sensors."""
    from harv_jax.training.environment import make_harv_env

    table = {"episode_steps": 200, "domain_randomization": True, "measurement_path": "lp2"}
    env, params = make_harv_env(table)
    plain, _ = make_harv_env({k: v for k, v in table.items() if k != "measurement_path"})
    assert env.measurement_path == {"kind": "lp", "bandwidth_hz": 2.0}
    n, steps = 32, 100
    keys = jax.random.split(jax.random.key(0), n)

    def roll(e):
        obs, st = jax.vmap(e.reset, in_axes=(0, None))(keys, params)

        def body(st, k):
            obs, st, *_ = jax.vmap(e.step_no_reset, in_axes=(0, 0, 0, None))(
                jax.random.split(k, n), st, jnp.zeros((n, 3)), params
            )
            return st, obs

        _, seq = jax.lax.scan(body, st, jax.random.split(jax.random.key(1), steps))
        return obs, seq

    obs0, seq = jax.jit(lambda: roll(env))()
    obs0_plain, seq_plain = jax.jit(lambda: roll(plain))()
    np.testing.assert_allclose(np.asarray(obs0), np.asarray(obs0_plain), rtol=1e-5, atol=1e-6)
    # p, q, r (indices 3-5): the second difference (white sensor noise, not the flight) through the 2 Hz
    # low-pass is far below the sensors'
    d_path = np.abs(np.diff(np.asarray(seq)[:, :, 3:6], 2, axis=0)).mean()
    d_plain = np.abs(np.diff(np.asarray(seq_plain)[:, :, 3:6], 2, axis=0)).mean()
    assert d_path < 0.2 * d_plain, (d_path, d_plain)


def test_the_path_of_a_preset_is_checked(tmp_path, monkeypatch, capsys):
    for value, message in (
        ('"kalman2"', "[env] measurement_path 'kalman2': allowed: none, lpHZ"),
        ('"lp900"', "[env] measurement_path 'lp900'"),
        ("2", "[env] measurement_path 2: allowed"),
    ):
        assert_train_preset_refused(tmp_path, monkeypatch, capsys, f"measurement_path = {value}", message)
    assert path_from_record({"kind": "eso", "bandwidth_hz": 0.075}, "x").bandwidth_hz == 0.075


@pytest.mark.slow  # ~1 min: a short training run
def test_a_run_trained_behind_a_path_ships_it(tmp_path, monkeypatch, capsys):
    preset = tmp_path / "p.toml"
    preset.write_text(
        "[ppo]\ntotal_steps = 8192\nnum_envs = 16\nunroll = 32\nnum_periods = 1\n"
        "hidden_sizes = [16]\n"
        '[env]\nepisode_steps = 200\ndomain_randomization = true\nmeasurement_path = "obs0.3"\n'
    )
    code, out, err = cli_run(
        monkeypatch, capsys, "train", "--preset", preset, "--watchdog-s", "0", "--out", tmp_path / "run"
    )
    assert code == 0, err
    pol = resolve_policy(str(tmp_path / "run/policy/policy_seed0.npz"))
    assert pol.meta["measurement_path"] == {"kind": "obs", "bandwidth_hz": 0.3}
    assert not (tmp_path / "run/policy/policy.stablehlo").exists()
    assert json.loads((tmp_path / "run/config.json").read_text())["env"]["measurement_path"] == "obs0.3"
