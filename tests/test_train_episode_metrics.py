"""The HARV episode metrics read the state and targets by name; the generic trainer imports nothing HARV."""

from __future__ import annotations

import ast
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from harv_jax.env.episode_metrics import (
    ALPHA_TOL_RAD,
    BETA_TOL_RAD,
    MU_TOL_RAD,
    OMEGA_TOL_RADPS,
    harv_episode_metrics,
)

PPO_DIR = Path(__file__).resolve().parents[1] / "harv_jax" / "ppo"
HARV_PACKAGES = ("env", "task", "aircraft", "dynamics", "control", "evaluation", "scenarios", "spin_bank",
                 "units", "training", "commands", "policy", "plots")  # fmt: skip


def _positional(info: dict) -> dict:
    """The metrics as computed before by position: x = [V, alpha, beta, p, q, r, mu, ...], obs[8:11]."""
    x, target = info["final_state_wind"], info["final_obs"][8:11]
    omega = jnp.sqrt(jnp.sum(jnp.square(x[3:6])))
    e_alpha = jnp.abs(x[1] - target[0])
    e_beta = jnp.abs(x[2] - target[1])
    e_mu = jnp.abs(jnp.mod(x[6] - target[2] + jnp.pi, 2.0 * jnp.pi) - jnp.pi)
    ok = ~info["terminated"]
    alpha_ok = ok & (e_alpha < ALPHA_TOL_RAD)
    rec = alpha_ok & (e_beta < BETA_TOL_RAD) & (e_mu < MU_TOL_RAD) & (omega < OMEGA_TOL_RADPS)
    return {
        "recovered": rec,
        "alpha_ok": alpha_ok,
        "final_omega_radps": omega,
        "final_abs_e_alpha_rad": e_alpha,
    }


def test_by_name_equals_by_position():
    n = 256
    k1, k2, k3 = jax.random.split(jax.random.key(0), 3)
    x = jax.random.normal(k1, (n, 10)) * 0.05
    obs = jax.random.normal(k2, (n, 11)) * 0.05
    info = {"final_state_wind": x, "final_obs": obs, "terminated": jax.random.bernoulli(k3, 0.2, (n,))}
    got = jax.vmap(harv_episode_metrics)(info)
    want = jax.vmap(_positional)(info)
    ok = ~np.asarray(info["terminated"])
    assert 0 < float(jnp.mean(got["recovered"])) < 1  # both outcomes occur
    for k in ("recovered", "alpha_ok"):
        np.testing.assert_array_equal(np.asarray(got[k]), np.asarray(want[k]).astype(np.float32))
    np.testing.assert_array_equal(np.asarray(got["final_omega_radps"]), np.asarray(want["final_omega_radps"]))
    np.testing.assert_array_equal(
        np.asarray(got["final_abs_e_alpha_rad"]), np.where(ok, np.asarray(want["final_abs_e_alpha_rad"]), 0.0)
    )


def test_generic_trainer_imports_nothing_harv_specific():
    for path in sorted(PPO_DIR.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            for name in names:
                parts = name.split(".")
                bad = parts[0] == "harv_jax" and len(parts) > 1 and parts[1] in HARV_PACKAGES
                assert not bad, f"{path.name} imports {name}"
