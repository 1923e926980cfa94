"""Adding a reward term takes the two files ``docs/layout.md`` names; shown on a copy of the package.

The test copies ``harv_jax`` into a temporary folder and adds a toy term there as the layout page says: a
field of ``RewardParams`` (``env/reward_params.py``: default 0, range, meaning) and its term in
``env/reward.py`` (added after the paper's sum, and reported on its own). A script run against the copy
shows that nothing else is needed: a preset's ``[reward]`` table takes the new key (the unchanged package
refuses it), the env's parameters carry it, the env steps with it, its default leaves every reward term bit
for bit as the unchanged package computes it, and a weight adds exactly the toy term to the reward.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

from harv_jax.env.reward import reward_terms
from harv_jax.env.reward_params import paper_reward_params
from harv_jax.errors import UsageError
from harv_jax.training.presets import load_preset

ROOT = Path(__file__).resolve().parents[1]

#: The two edits, each as (file, anchor, text put after the anchor). An anchor that is gone fails the test:
#: the layout page then describes files that changed.
EDITS = (
    (
        "env/reward_params.py",
        '"the high-drag alpha tracked while fast, rad")\n',
        '    toy_altitude_weight: jnp.ndarray = _field(0.0, 0.0, 10.0, "toy: weight of -h / 10,000 ft")\n',
    ),
    ("env/reward.py", "    recovered: jnp.ndarray\n", "    toy: jnp.ndarray\n"),
    (
        "env/reward.py",
        "    performance = (r_raw + jnp.sum(bonus) + r_action) + (jnp.sum(dense) + r_recovered)\n",
        "    r_toy = -params.toy_altitude_weight * x_wind[9] / 1e4\n    performance = performance + r_toy\n",
    ),
    ("env/reward.py", '        "recovered": r_recovered,\n', '        "toy": r_toy,\n'),
)

#: States [V, alpha, beta, p, q, r, mu, gamma, chi, h] and actions the reward is computed on.
STATES = np.array(
    [
        [600.0, 0.5, 0.05, 0.3, -0.2, 0.1, 0.4, -0.3, 1.0, 25000.0],
        [300.0, 0.36, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 20000.0],
        [1200.0, -0.1, -0.2, 1.5, 0.8, -0.4, -2.5, 0.9, -3.0, 28000.0],
    ]
)
ACTIONS = np.array([[0.1, -0.5, 0.9], [0.0, 0.0, 0.0], [-1.0, 1.0, 0.3]])
TARGET = [0.349, 0.0, 0.0]

SCRIPT = """
import json, sys
import jax.numpy as jnp
import numpy as np
from harv_jax.env.reward import reward_terms
from harv_jax.env.reward_params import paper_reward_params
from harv_jax.env import make_env
from harv_jax.env.settings import env_config, env_params, split_tables
from harv_jax.training.presets import load_preset
import jax

states, actions, target = (np.array(v) for v in json.loads(sys.argv[1]))
_, env_table = load_preset(sys.argv[2])
flat, nested = split_tables(env_table)
params = env_params(env_config(flat), nested)
out = {"preset_weight": float(params.reward.toy_altitude_weight)}
env = make_env(env_config(flat))
_, state = env.reset(jax.random.key(0), params)
_, _, reward, _, _, info = env.step_no_reset(jax.random.key(1), state, jnp.zeros(3), params)
out["env_step_toy"] = float(info["reward_terms"]["toy"])
out["env_step_reward_finite"] = bool(np.isfinite(float(reward)))
for name, weight in (("default", 0.0), ("weighted", 0.5)):
    rp = paper_reward_params().replace(toy_altitude_weight=jnp.asarray(weight))
    rows = []
    for x, a in zip(states, actions):
        terms, pot = reward_terms(jnp.asarray(x), jnp.asarray(target), jnp.asarray(a), jnp.asarray(1.5),
                                  jnp.asarray(False), rp)
        rows.append({k: float(v) for k, v in terms._asdict().items()} | {"potential": float(pot)})
    out[name] = rows
print(json.dumps(out))
"""


def _copy_with_toy_term(dest: Path) -> Path:
    pkg = dest / "harv_jax"
    shutil.copytree(ROOT / "harv_jax", pkg, ignore=shutil.ignore_patterns("__pycache__"))
    for rel, anchor, added in EDITS:
        path = pkg / rel
        text = path.read_text()
        assert text.count(anchor) == 1, (
            f"{rel}: the anchor the layout page's recipe edits is gone: {anchor!r}"
        )
        path.write_text(text.replace(anchor, anchor + added))
    return dest


def _unchanged_terms() -> list[dict[str, float]]:
    rows = []
    for x, a in zip(STATES, ACTIONS, strict=True):
        terms, pot = reward_terms(
            jnp.asarray(x), jnp.asarray(TARGET), jnp.asarray(a), jnp.asarray(1.5), jnp.asarray(False),
            paper_reward_params(),
        )  # fmt: skip
        rows.append({k: float(v) for k, v in terms._asdict().items()} | {"potential": float(pot)})
    return rows


def test_a_toy_reward_term_takes_two_files(tmp_path):
    preset = tmp_path / "toy.toml"
    preset.write_text("[reward]\ntoy_altitude_weight = 0.5\n")
    with pytest.raises(UsageError, match="unknown \\[reward\\] setting 'toy_altitude_weight'"):
        load_preset(str(preset))  # the unchanged package does not know the key
    copy = _copy_with_toy_term(tmp_path / "copy")
    env = os.environ | {"PYTHONPATH": str(copy), "JAX_PLATFORMS": "cpu"}
    args = json.dumps([STATES.tolist(), ACTIONS.tolist(), TARGET])
    proc = subprocess.run(
        [sys.executable, "-c", SCRIPT, args, str(preset)],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["preset_weight"] == 0.5
    assert out["env_step_toy"] != 0.0 and out["env_step_reward_finite"]
    unchanged = _unchanged_terms()
    for before, default, weighted, x in zip(unchanged, out["default"], out["weighted"], STATES, strict=True):
        assert default == before | {"toy": 0.0}  # bit for bit (float64 round-trip of float32 values)
        toy = float(jnp.float32(-0.5) * jnp.float32(x[9]) / jnp.float32(1e4))
        assert weighted["toy"] == toy
        np.testing.assert_allclose(weighted["total"], before["total"] + toy, rtol=1e-6)
        assert {k: v for k, v in weighted.items() if k not in ("toy", "total")} == {
            k: v for k, v in before.items() if k != "total"
        }
