"""The shipped default policy recovers on its own (RL-only, the Monte Carlo's criterion), the paper's do not;
shipped names resolve."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from harv_jax.aircraft import harv
from harv_jax.control.registry import policy_path, with_measurement_path
from harv_jax.control.rl import make_rl_controller
from harv_jax.errors import UsageError
from harv_jax.evaluation.policy_eval import make_eval_batch, make_policy_eval
from harv_jax.policy import resolve_policy, shipped_path


@pytest.fixture(scope="module")
def batch():
    # 15 reset-bound upsets (MC sampling, evaluation key: not a training or tuning seed) + the 30 s spin
    return make_eval_batch(15, 1, harv(), seed=77)


def _recovered(policy: str, batch) -> np.ndarray:
    """Per run of ``batch``: recovered within 60 s, RL-only, scored as the Monte Carlo scores its runs (the
    trainer's evaluation, ``make_policy_eval``: the spin starts at its pro-spin controls), behind the
    measurement path the policy carries, as ``--controller rl`` flies it. One vmapped rollout, one compile,
    flies them all."""
    pol = resolve_policy(policy)
    path = policy_path(pol)

    def controller(act):
        ctrl = make_rl_controller(act)
        return ctrl if path is None else with_measurement_path(ctrl, path)

    evaluate = make_policy_eval(
        lambda params, normalizer, obs: pol.deterministic(obs), batch, make_controller=controller
    )
    return np.asarray(jax.jit(evaluate)(None, None)["recovered"])


def test_default_policy_recovers_on_its_own(batch):
    rec = _recovered("shipped", batch)
    assert rec[:-1].sum() >= 14, rec  # >= 14 of 15 upsets (the 1000-run MC: experiments/recovery_policy)
    assert rec[-1], "the 30 s developed spin"


@pytest.mark.slow
def test_paper_policy_does_not(batch):
    assert _recovered("shipped:paper-full", batch)[:-1].sum() == 0


def test_shipped_names():
    assert shipped_path() == shipped_path("robust")  # the default
    assert resolve_policy("shipped").meta["measurement_path"] == {"kind": "lp", "bandwidth_hz": 2.0}
    assert "measurement_path" not in resolve_policy("shipped:teacher").meta
    assert shipped_path("paper-full") == shipped_path("full")
    assert shipped_path("recovery").name == "recovery.npz"
    with pytest.raises(UsageError, match="shipped policy 'bogus' is unknown"):
        shipped_path("bogus")
