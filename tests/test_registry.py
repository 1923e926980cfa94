"""The controller registry: a controller added with one ``register`` call is flown by ``fly``, ``mc`` and
``compare`` with no other change (the issue's "one module plus one registry line").

The toy controller below is the whole "module": a constant deflection command in the
``Controller(init, apply)`` form of ``harv_jax.control.base``. It is registered through the public
``harv_jax.control.registry.register`` and removed again after each test (fixture ``toy``).
"""

from __future__ import annotations

import json

import jax.numpy as jnp
import pytest
from cheap_controller import registered
from cli_util import cli_run

from harv_jax.control import registry
from harv_jax.control.base import Controller
from harv_jax.errors import UsageError

#: The toy's command [de, da, dr], rad: a little nose-down elevator, no aileron or rudder.
TOY_U_RAD = (-0.05, 0.0, 0.0)


def make_constant(u_rad: tuple[float, float, float] = TOY_U_RAD) -> Controller:
    """A controller that always commands ``u_rad`` (no state; no diagnostics)."""

    def init(params):
        del params
        return jnp.zeros(())

    def apply(state, x_wind, reference_rad, key):
        del reference_rad, key
        return jnp.asarray(u_rad, x_wind.dtype), state, {}

    return Controller(init=init, apply=apply)


@pytest.fixture
def toy():
    with registered("toy", make_constant, "constant deflection") as name:
        yield name


def test_register_adds_one_entry_and_refuses_duplicates(toy):
    assert registry.controller_names()[-1] == "toy"
    assert isinstance(registry.build_controller("toy"), Controller)
    assert not registry.uses_option(["toy"], "policy") and registry.uses_option(["toy", "rl"], "policy")
    with pytest.raises(ValueError, match="already registered"):
        registry.register("toy", lambda opts: make_constant())
    with pytest.raises(ValueError, match="unknown options"):
        registry.register("toy2", lambda opts: make_constant(), options=("gain",))
    assert registry.parse_controllers("smc, toy") == ["smc", "toy"]


def test_unknown_controller_names_the_registered_ones():
    with pytest.raises(UsageError, match="unknown controller 'toy'; allowed: smc, rl, hybrid"):
        registry.parse_controllers("toy")


def test_fly_flies_the_toy(toy, monkeypatch, capsys, tmp_path):
    out = tmp_path / "fly"
    code, _, err = cli_run(
        monkeypatch, capsys, "fly", "--controller", toy, "--scenario", "random", "--duration", "10.5",
        "--out", out,
    )  # fmt: skip
    assert code == 0, err
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["controller"] == "toy" and doc["policy"] is None and doc["zeta_schedule"] is None
    assert doc["certificate"] is None  # no sliding variables in its info
    header = (out / "trajectory.csv").read_text().splitlines()[0].split(",")
    assert "de_cmd" in header and "zeta" not in header
    rows = (out / "trajectory.csv").read_text().splitlines()[1:]
    de_cmd = [float(r.split(",")[header.index("de_cmd")]) for r in rows]
    assert de_cmd == pytest.approx([TOY_U_RAD[0]] * len(rows))


def test_mc_flies_the_toy(toy, monkeypatch, capsys, tmp_path):
    out = tmp_path / "mc"
    code, _, err = cli_run(
        monkeypatch, capsys, "mc", "--controller", toy, "--runs", "4", "--duration", "10.5",
        "--chunk", "4", "--out", out,
    )  # fmt: skip
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    assert list(s["controllers"]) == ["toy"] and s["policy"] is None and s["zeta_schedule"] is None
    assert sum(s["controllers"]["toy"]["outcomes"].values()) == 4
    assert (out / "bands_toy.png").exists() and len((out / "runs.csv").read_text().splitlines()) == 5


def test_compare_flies_the_toy(toy, monkeypatch, capsys, tmp_path):
    out = tmp_path / "cmp"
    code, _, err = cli_run(
        monkeypatch, capsys, "compare", "--controller", toy, "--duration", "10.5", "--spin-s", "0",
        "--out", out,
    )  # fmt: skip
    assert code == 0, err
    doc = json.loads((out / "compare.json").read_text())
    assert [(r["scenario"], r["controller"]) for r in doc["rows"]] == [("spin", "toy"), ("fixed", "toy")]
    assert doc["policy"] is None and doc["certificates"] == {}


def test_a_policy_of_another_size_is_refused_in_one_line(tmp_path):
    """A policy that does not map the 11 observations to 3 actions: one line naming its sizes, for rl and
    hybrid alike."""
    import jax

    from harv_jax.policy import export_npz, make_policy
    from harv_jax.ppo import normalize
    from harv_jax.ppo.networks import make_ppo_networks

    networks = make_ppo_networks(13, 3, (8,))
    pol = make_policy(
        networks.init(jax.random.key(0)), normalize.init_stats(13), networks, meta={"source": "test"}
    )
    path = export_npz(tmp_path / "thirteen.npz", pol)
    for name in ("rl", "hybrid"):
        with pytest.raises(UsageError) as e:
            registry.build_controller(name, registry.ControllerOptions(policy=str(path)))
        msg = str(e.value)
        assert "13 observations to 3 actions" in msg and "allowed: 11 observations -> 3 actions" in msg
        assert "\n" not in msg
