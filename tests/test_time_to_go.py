"""The progress reward from a fitted time to recover: the term against hand-worked numbers, the file's
round trip and validation, the fit, and bad settings (one line, exit 2, no run folder)."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.errors import UsageError
from harv_jax.training import time_to_go as ttg
from harv_jax.training.environment import make_harv_env

SMALL_ENV = {"episode_steps": 50, "domain_randomization": False}


def _linear_net(a_s: float, c_s: float) -> ttg.TimeToGoNet:
    """T = max(a_s (V - 600) / 300 + c_s, 0): one linear layer on the first feature."""
    w = np.zeros((len(ttg.FEATURE_NAMES), 1), np.float32)
    w[0, 0] = a_s
    return ttg.TimeToGoNet(((jnp.asarray(w), jnp.asarray([c_s], jnp.float32)),))


def _x(v_fps: float) -> jnp.ndarray:
    return jnp.asarray([v_fps, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 20000.0])


def test_features_and_prediction_by_hand():
    f = np.asarray(ttg.features(jnp.asarray([900.0, 0.2, 0.1, 0.3, -0.4, 0.5, np.pi / 2, 0.7, 0.1, 30000.0])))
    np.testing.assert_allclose(f, [1.0, 0.2, 0.1, 0.3, -0.4, 0.5, 1.0, 0.0, 0.7, 1.0], atol=1e-6)
    net = _linear_net(4.0, 2.0)
    assert float(ttg.predict_s(net, _x(900.0))) == pytest.approx(6.0)
    assert float(ttg.predict_s(net, _x(0.0))) == 0.0  # -8 + 2 < 0: clipped at 0


def _file(tmp_path: Path, net: ttg.TimeToGoNet) -> Path:
    path = tmp_path / "t.npz"
    ttg.save(path, net, {"note": "test"})
    return path


def test_progress_term_is_w_times_the_time_gained_and_zero_on_termination(tmp_path):
    net = _linear_net(4.0, 2.0)
    table = {**SMALL_ENV, "time_to_go": str(_file(tmp_path, net)), "time_to_go_weight": 50.0}
    env, params = make_harv_env({**table, "time_to_go_discount": 0.9})
    plain, _ = make_harv_env(SMALL_ENV)
    key = jax.random.key(0)
    _, state = env.reset(key, params)
    action = jnp.asarray([0.1, -0.2, 0.3], jnp.float32)
    step = jax.jit(env.step_no_reset)
    _, new, reward, terminated, _, info = step(key, state, action, params)
    _, pnew, preward, _, _, _ = jax.jit(plain.step_no_reset)(key, state, action, params)
    assert not bool(terminated)
    t0 = max(4.0 * (float(state.wind[0]) - 600.0) / 300.0 + 2.0, 0.0)
    t1 = max(4.0 * (float(new.wind[0]) - 600.0) / 300.0 + 2.0, 0.0)
    np.testing.assert_allclose(float(info["time_to_go_reward"]), 50.0 * (t0 - 0.9 * t1), rtol=1e-4)
    np.testing.assert_allclose(float(reward), float(preward) + 50.0 * (t0 - 0.9 * t1), rtol=1e-5)
    np.testing.assert_array_equal(np.asarray(new.wind), np.asarray(pnew.wind))  # the flight is the same
    # a state outside the envelope terminates: the term is 0 there
    _, _, _, term, _, info = step(key, state.replace(aircraft=_far(state)), action, params)
    assert bool(term) and float(info["time_to_go_reward"]) == 0.0


def _far(state):
    """The integration state of ``state`` at 20 times its body velocity (beyond the envelope's V)."""
    return state.aircraft.replace(uvw_fps=state.aircraft.uvw_fps * 20.0)


def test_with_a_teacher_the_labels_stay_and_the_reward_gains_the_term(tmp_path):
    path = str(_file(tmp_path, _linear_net(4.0, 2.0)))
    env, params = make_harv_env({**SMALL_ENV, "teacher": "smc", "time_to_go": path})
    key = jax.random.key(1)
    _, state = env.reset(key, params)
    _, _, _, _, info = jax.jit(env.step)(key, state, jnp.zeros(3, jnp.float32), params)
    assert info["teacher_action"].shape == (3,) and "time_to_go_reward" in info


def test_file_round_trip(tmp_path):
    net = ttg.fit(np.asarray([_x(v) for v in np.linspace(300, 1500, 64)]), np.linspace(0, 20, 64), (8,), 50)
    back = ttg.load(_file(tmp_path, net))
    x = jnp.stack([_x(700.0), _x(1300.0)])
    np.testing.assert_allclose(
        np.asarray(ttg.predict_s(back, x)), np.asarray(ttg.predict_s(net, x)), rtol=1e-6
    )


def test_fit_learns_a_known_time_to_go():
    rng = np.random.default_rng(0)
    x = np.tile(np.asarray(_x(600.0)), (4000, 1))
    x[:, 0] = rng.uniform(300.0, 1500.0, 4000)
    x[:, 7] = rng.uniform(-1.0, 1.0, 4000)  # gamma
    y = 3.0 + 4.0 * (x[:, 0] - 600.0) / 300.0 * (x[:, 0] > 600.0) + 2.0 * x[:, 7]
    y = np.maximum(y, 0.0)
    net = ttg.fit(x, y, (16, 16), steps=1500)
    pred = np.asarray(ttg.predict_s(net, jnp.asarray(x)))
    assert 1.0 - np.mean((pred - y) ** 2) / np.var(y) > 0.97


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"not an npz", "cannot be read as .npz"),
        ("format", "is not a 'harv-jax time-to-go' file of version 1"),
        ("version", "is not a 'harv-jax time-to-go' file of version 1"),
        ("text_layer", "layer 0 is not a finite [10, n] matrix + [n]"),
        ("nan", "layer 0 is not a finite [10, n] matrix + [n]"),
        ("shape", "layer 0 is not a finite [10, n] matrix + [n]"),
        ("two_outputs", "the layers must end in one output"),
    ],
)
def test_a_bad_file_is_one_line(tmp_path, content, message):
    path = tmp_path / "bad.npz"
    good = {"format": np.str_(ttg.FORMAT), "version": np.int64(1), "w0": np.ones((10, 1)), "b0": np.zeros(1)}
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        bad = {
            "format": {**good, "format": np.str_("other")},
            "version": {**good, "version": np.str_("one")},
            "text_layer": {**good, "w0": np.full((10, 1), "x")},
            "nan": {**good, "w0": np.full((10, 1), np.nan)},
            "shape": {**good, "w0": np.ones((9, 1))},
            "two_outputs": {**good, "w0": np.ones((10, 2)), "b0": np.zeros(2)},
        }[content]
        np.savez(path, **bad)
    with pytest.raises(ValueError, match=re.escape(message)) as e:
        ttg.load(path)
    assert "\n" not in str(e.value)


def test_settings_are_checked(tmp_path):
    path = str(_file(tmp_path, _linear_net(1.0, 0.0)))
    assert ttg.progress_settings({}) is None
    net, w, g = ttg.progress_settings({"time_to_go": path})
    assert (w, g) == (100.0, 1.0) and len(net.layers) == 1
    with pytest.raises(UsageError, match="time_to_go_weight given without a time-to-go file"):
        ttg.progress_settings({"time_to_go_weight": 3.0})
    with pytest.raises(UsageError, match="time_to_go 3; allowed: the path of a time-to-go .npz file"):
        ttg.progress_settings({"time_to_go": 3})
    for key, bad in (("time_to_go_weight", -1.0), ("time_to_go_weight", "x"), ("time_to_go_discount", 1.5)):
        with pytest.raises(UsageError, match=f"{key} .*; allowed: a number in"):
            ttg.progress_settings({"time_to_go": path, key: bad})


@pytest.mark.parametrize(
    ("env", "message"),
    [
        (
            'time_to_go = "missing.npz"',
            "missing.npz' cannot be read as .npz",
        ),
        ('time_to_go = "FILE"\ntime_to_go_weight = -2.0', "[env] time_to_go_weight -2.0; allowed: a number"),
        ("time_to_go_discount = 0.5", "[env] time_to_go_discount given without a time-to-go file"),
    ],
)
def test_bad_progress_settings_are_one_line_and_no_run_folder(tmp_path, monkeypatch, capsys, env, message):
    from cli_util import cli_run

    monkeypatch.chdir(tmp_path)
    ttg.save(tmp_path / "good.npz", _linear_net(1.0, 0.0), {})
    preset = tmp_path / "p.toml"
    preset.write_text(f"[ppo]\ntotal_steps = 4096\nnum_envs = 16\n[env]\n{env.replace('FILE', 'good.npz')}\n")
    code, _, err = cli_run(monkeypatch, capsys, "train", "--preset", preset, "--out", tmp_path / "run")
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "run").exists()


def test_a_presets_relative_file_is_its_folders(tmp_path, monkeypatch):
    from harv_jax.training.presets import TIME_TO_GO_KEY, load_preset

    assert TIME_TO_GO_KEY == ttg.FILE_KEY
    (tmp_path / "sub").mkdir()
    ttg.save(tmp_path / "sub" / "t.npz", _linear_net(1.0, 0.0), {})
    (tmp_path / "sub" / "p.toml").write_text('[env]\ntime_to_go = "t.npz"\n')
    monkeypatch.chdir(tmp_path)
    _, env = load_preset("sub/p.toml")
    assert env["time_to_go"] == str(tmp_path / "sub" / "t.npz")
    make_harv_env({**env, **SMALL_ENV})  # the file is found from another working folder


def test_a_run_pins_the_files_digest_and_a_changed_file_is_refused(tmp_path):
    path = _file(tmp_path, _linear_net(1.0, 0.0))
    table = ttg.pin_file_digest({"time_to_go": str(path)})
    assert table["time_to_go_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert ttg.pin_file_digest(table) == table and ttg.pin_file_digest({}) == {}
    assert ttg.progress_settings(table) is not None
    ttg.save(path, _linear_net(2.0, 0.0), {})  # the file changes under the run
    with pytest.raises(UsageError, match="SHA-256 .*, the run recorded .*; restore that file or start a new"):
        ttg.progress_settings(table)
    with pytest.raises(UsageError, match="time_to_go_sha256 given without a time-to-go file"):
        ttg.progress_settings({"time_to_go_sha256": "ab"})
