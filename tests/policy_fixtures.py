"""Erratic policies in the shipped policy file format, for tests and safety measurements (never shipped).

- ``zero``: every actor weight and bias 0 (action 0 everywhere: mid-range deflections);
- ``random``: Gaussian weights of unit gain (std 1/sqrt(fan_in)) in every layer, output included, so the
  action is O(1) and changes with the state;
- ``bang-bang``: the random network with its output layer scaled by ``BANG_BANG_GAIN``: every action
  component sits at -1 or +1 and flips sign with the state.

The observation statistics and the critic are the shipped partial policy's (a realistic scaling of the
inputs). ``python tests/policy_fixtures.py DIR`` writes ``DIR/{zero,random,bang-bang}.npz`` for the CLI
(``--policy DIR/random.npz``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from harv_jax.policy import NPZ_FORMAT, shipped_path

FIXTURE_POLICIES = ("zero", "random", "bang-bang")
HIDDEN_SIZES = (256, 128)
BANG_BANG_GAIN = 1.0e3
SEED = 17


def _actor(kind: str, obs_size: int, act_size: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(SEED)
    sizes = (obs_size, *HIDDEN_SIZES, act_size)
    names = [f"hidden_{i}" for i in range(len(HIDDEN_SIZES))] + ["out"]
    out = {}
    for name, n_in, n_out in zip(names, sizes[:-1], sizes[1:], strict=True):
        w = rng.normal(0.0, 1.0 / np.sqrt(n_in), (n_in, n_out))
        b = rng.normal(0.0, 0.1, (n_out,))
        if kind == "zero":
            w, b = np.zeros_like(w), np.zeros_like(b)
        elif kind == "bang-bang" and name == "out":
            w, b = w * BANG_BANG_GAIN, b * BANG_BANG_GAIN
        out[f"policy/{name}/kernel"] = w.astype(np.float32)
        out[f"policy/{name}/bias"] = b.astype(np.float32)
    out["policy/log_std"] = np.full((act_size,), -0.5, np.float32)
    return out


def write_fixture_policy(kind: str, path: Path) -> Path:
    """Write one fixture policy (``FIXTURE_POLICIES``) as a policy ``.npz``."""
    if kind not in FIXTURE_POLICIES:
        raise ValueError(f"kind={kind!r}; allowed: {', '.join(FIXTURE_POLICIES)}")
    with np.load(shipped_path("partial"), allow_pickle=False) as data:
        base = {k: data[k] for k in data.files}
    meta = json.loads(str(base["meta"]))
    arrays = {k: v for k, v in base.items() if k.startswith("value/") or k.startswith("obs_")}
    arrays.update(_actor(kind, int(meta["observation_size"]), int(meta["action_size"])))
    arrays["meta"] = np.asarray(
        json.dumps(
            {
                "format": NPZ_FORMAT,
                "observation_size": meta["observation_size"],
                "action_size": meta["action_size"],
                "hidden_sizes": list(HIDDEN_SIZES),
                "normalize_observations": True,
                "source": f"test fixture '{kind}' (tests/policy_fixtures.py, seed {SEED}), not trained",
            }
        )
    )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **arrays)
    return path


def write_fixture_policies(directory: Path) -> dict[str, Path]:
    """Write every fixture policy into ``directory``; returns name -> path."""
    return {k: write_fixture_policy(k, Path(directory) / f"{k}.npz") for k in FIXTURE_POLICIES}


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python tests/policy_fixtures.py DIR")
    for name, p in write_fixture_policies(Path(sys.argv[1])).items():
        print(name, p)
