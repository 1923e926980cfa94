"""Adding a disturbance takes the two files ``docs/layout.md`` names; shown on a copy of the package.

The test copies ``harv_jax`` into a temporary folder and adds two toy disturbances there as the layout
page says: each a module in ``dynamics/`` with its ``DisturbanceModel`` and a row of
``task/disturbance_table.py``. ``alpha_bias`` biases the angle-of-attack vane by its level (deg);
``headwind`` blows along the body x axis at its level (ft/s). A script run against the copy shows that
nothing else is needed: ``harv-jax mc`` takes ``--disturbances alpha_bias`` and its level option, records
the level in the summary and the runs' table, and the SMC, tracking the biased vane, settles the true α off
the target by the bias; ``harv-jax robustness`` sweeps its row's levels; a training preset's
``[randomization]`` key draws an episode level in the env, whose observation then differs from the one
without it in α alone, by that level, every other draw unchanged; the head wind adds its velocity to the
air mass the aircraft flies in.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

MODULES = {
    "alpha_bias.py": '''"""A toy: the angle-of-attack vane reads high by the level, deg."""

import jax.numpy as jnp

from harv_jax.dynamics.disturbance_model import DisturbanceModel
from harv_jax.dynamics.state import WIND_INDEX


def _measure(x_wind, state, level_deg):
    return x_wind.at[WIND_INDEX["alpha"]].add(jnp.deg2rad(level_deg).astype(x_wind.dtype))


ALPHA_BIAS = DisturbanceModel(
    init=lambda level, key: jnp.zeros(()), step=lambda state, level, key, dt_s: state, measure=_measure
)
''',
    "headwind.py": '''"""A toy: a head wind along body x at the level, ft/s, gusting 1% (own draws)."""

import jax
import jax.numpy as jnp

from harv_jax.dynamics.disturbance_model import DisturbanceModel


def _init(level, key):
    return 1.0 + 0.01 * jax.random.normal(key, jnp.shape(level), jnp.result_type(level))


def _step(state, level, key, dt_s):
    return 1.0 + 0.01 * jax.random.normal(key, jnp.shape(state), state.dtype)


HEADWIND = DisturbanceModel(
    init=_init, step=_step, wind_fps=lambda state, level: jnp.stack([-level * state, 0 * level, 0 * level])
)
''',
}

ROWS = """    Disturbance(
        "alpha_bias",
        "--alpha-bias-deg",
        "deg",
        1.0,
        10.0,
        ("alpha_bias_max_deg",),
        "toy: the angle-of-attack vane reads high by this",
        in_default=False,
        model=ALPHA_BIAS,
        sweep=(0.0, 2.0),
    ),
    Disturbance(
        "headwind",
        "--headwind-fps",
        "ft/s",
        20.0,
        200.0,
        ("headwind_max_fps",),
        "toy: a head wind along the body x axis",
        in_default=False,
        model=HEADWIND,
        sweep=(0.0, 20.0),
    ),
)
"""

#: (file, anchor, text put in its place) for the table.
TABLE_EDITS = (
    (
        "from harv_jax.dynamics.disturbance_model import DisturbanceModel, Models\n",
        "from harv_jax.dynamics.alpha_bias import ALPHA_BIAS\n"
        "from harv_jax.dynamics.disturbance_model import DisturbanceModel, Models\n"
        "from harv_jax.dynamics.headwind import HEADWIND\n",
    ),
    (
        'sigma and scale length by altitude",\n    ),\n)\n',
        'sigma and scale length by altitude",\n    ),\n' + ROWS,
    ),
)

SCRIPT = r"""
import json, sys
import jax, jax.numpy as jnp
import numpy as np
from harv_jax.dynamics.disturbed_step import air_data, disturbance_init
from harv_jax.dynamics.disturbances import DisturbanceParams
from harv_jax.dynamics.state import WIND_INDEX, from_wind
from harv_jax.env import make_env
from harv_jax.env.settings import env_config, env_params, split_tables
from harv_jax.task.disturbance_table import added_models
from harv_jax.training.presets import load_preset

out = {}
# the env: the same reset with and without the bias's [randomization] key
obs = {}
for name in ("with", "without"):
    _, env_table = load_preset(sys.argv[1] if name == "with" else sys.argv[2])
    flat, nested = split_tables(env_table)
    env = make_env(env_config(flat))
    o, state = env.reset(jax.random.key(3), env_params(env_config(flat), nested))
    obs[name] = np.asarray(o).tolist()
    if name == "with":
        out["episode_level_deg"] = float(state.episode.added_levels["alpha_bias"])
        out["episode_wind"] = float(state.episode.added_levels["headwind"])
out["obs"] = obs
# the wind: the head wind adds its velocity to the gust
x0 = jnp.array([500.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25000.0])
lv = DisturbanceParams(jnp.zeros(8), jnp.zeros((), jnp.int32), jnp.asarray(3.0), jnp.asarray(2.0),
                       added_levels={"headwind": jnp.asarray(20.0)}, added_models=added_models(["headwind"]))
st = disturbance_init(jnp.ones(12), lv, jnp.zeros(3), jnp.asarray(0.0), 0, jax.random.key(5))
air = air_data(from_wind(x0), st, lv)
out["wind"] = np.asarray(air.wind_fps).tolist()
out["gust"] = np.asarray(st.gust_fps).tolist()
out["headwind_state"] = float(st.added["headwind"])
print(json.dumps(out))
"""


def _copy_with_toys(dest: Path) -> Path:
    pkg = dest / "harv_jax"
    shutil.copytree(ROOT / "harv_jax", pkg, ignore=shutil.ignore_patterns("__pycache__"))
    for name, text in MODULES.items():
        (pkg / "dynamics" / name).write_text(text)
    table = pkg / "task" / "disturbance_table.py"
    text = table.read_text()
    for anchor, replacement in TABLE_EDITS:
        assert text.count(anchor) == 1, f"the place the layout page's recipe edits is gone: {anchor!r}"
        text = text.replace(anchor, replacement)
    table.write_text(text)
    return dest


def _run(args: list[str], copy: Path, cwd: Path) -> subprocess.CompletedProcess:
    env = os.environ | {"PYTHONPATH": str(copy), "JAX_PLATFORMS": "cpu"}
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, cwd=cwd)


@pytest.mark.slow  # ~40 s: a Monte Carlo, two env resets and a sweep, each compiled in a fresh interpreter
def test_a_toy_disturbance_takes_two_files(tmp_path):
    copy = _copy_with_toys(tmp_path / "copy")
    mc = _run(
        ["-m", "harv_jax.cli", "mc", "--controller", "smc", "--disturbances", "alpha_bias",
         "--alpha-bias-deg", "1.5", "--runs", "6", "--duration", "60", "--seed", "2",
         "--out", str(tmp_path / "mc")],
        copy,
        tmp_path,
    )  # fmt: skip
    assert mc.returncode == 0, mc.stderr[-3000:]
    summary = json.loads((tmp_path / "mc" / "summary.json").read_text())
    assert summary["disturbances"]["active"] == ["alpha_bias"]
    assert summary["disturbances"]["alpha_bias_level"] == 1.5
    with open(tmp_path / "mc" / "runs.csv") as f:
        rows = list(csv.DictReader(f))
    assert {r["alpha_bias_deg"] for r in rows} == {"1.5"}
    # the SMC holds the vane's alpha on the target: the true alpha settles 1.5 deg below it
    errors = np.array([float(r["terminal_alpha_err_deg"]) for r in rows])
    np.testing.assert_allclose(np.median(errors), -1.5, atol=0.1)

    with_bias, without = tmp_path / "with.toml", tmp_path / "without.toml"
    table = "[env]\ndomain_randomization = true\n\n[randomization]\n"
    with_bias.write_text(table + "alpha_bias_max_deg = 2.0\nheadwind_max_fps = 30.0\n")
    without.write_text(table + "gust_on = true\n")
    run = _run(["-c", SCRIPT, str(with_bias), str(without)], copy, tmp_path)
    assert run.returncode == 0, run.stderr[-3000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    level = out["episode_level_deg"]
    assert 0.0 < level < 2.0 and 0.0 < out["episode_wind"] < 30.0
    diff = np.array(out["obs"]["with"]) - np.array(out["obs"]["without"])
    alpha = 1  # [V, alpha, beta, p, q, r, mu, gamma, target...]
    np.testing.assert_allclose(diff[alpha], np.deg2rad(level), rtol=1e-5)
    assert np.count_nonzero(np.delete(diff, alpha)) == 0  # every other draw of the reset unchanged
    np.testing.assert_allclose(out["wind"][0], out["gust"][0] - 20.0 * out["headwind_state"], rtol=1e-6)
    assert out["wind"][1:] == out["gust"][1:] and out["headwind_state"] != 1.0

    sweep = _run(
        ["-m", "harv_jax.cli", "robustness", "--controller", "smc", "--disturbances", "alpha_bias",
         "--runs", "4", "--duration", "10.5", "--out", str(tmp_path / "sweep")],
        copy,
        tmp_path,
    )  # fmt: skip
    assert sweep.returncode == 0, sweep.stderr[-3000:]
    doc = json.loads((tmp_path / "sweep" / "robustness.json").read_text())["disturbances"]
    assert list(doc) == ["alpha_bias"] and doc["alpha_bias"]["option"] == "--alpha-bias-deg"
    assert doc["alpha_bias"]["levels"] == [0.0, 2.0]  # the row's sweep
