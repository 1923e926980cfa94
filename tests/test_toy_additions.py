"""Extension points of the trainer, each shown with a toy: a loss term defined in one place and a critic that
observes more than the policy, both on the toy env of ``test_train``."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_train import CFG, TOY_PARAMS, ToyEnv

from harv_jax.ppo.loss_terms import LossTerm
from harv_jax.ppo.train import make_train, seed_keys


def _short_cfg():
    return dataclasses.replace(CFG, num_periods=1, total_steps=32 * 16 * 6)


class PullTowardHalf(LossTerm):
    """A toy loss term: the mean squared distance of the policy mean from 0.5, weight ``w`` throughout."""

    name = "toy_pull"

    def __init__(self, w: float) -> None:
        self.w = w

    def coef(self, frac: jax.Array) -> float:
        return self.w

    def value(self, params, networks, mean, data, sample):
        v = jnp.mean(jnp.sum(jnp.square(mean - 0.5), axis=-1))
        return v, {"toy_pull_loss": v}


class SeeingEnv(ToyEnv):
    """The toy env whose policy sees a corrupted position and whose critic sees the true one."""

    def critic_observation(self, s):
        return ToyEnv._obs(self, s)

    def _obs(self, s):
        return ToyEnv._obs(self, s).at[:3].multiply(0.0)  # the policy sees only the time

    def step(self, key, state, action, params):
        obs, s, reward, done, info = ToyEnv.step(self, key, state, action, params)
        info["final_critic_obs"] = (
            info["final_obs"].at[:3].set(state.x + params.gain * jnp.clip(action, -1, 1))
        )
        return obs, s, reward, done, info


@pytest.fixture(scope="module")
def trained():
    """One period on the toy env whose critic sees more than its policy, with the toy term at weight 50."""
    cfg = _short_cfg()
    trainer = make_train(SeeingEnv(), cfg, TOY_PARAMS, terms=(PullTowardHalf(50.0),))
    init = trainer.init(seed_keys(jax.random.key(0), cfg.num_seeds), TOY_PARAMS)
    init_params = jax.tree.map(np.array, init.params)  # a host copy: the period donates the state
    state, metrics = trainer.period(init, TOY_PARAMS)
    return trainer, init_params, state, metrics


def test_a_loss_term_defined_outside_the_package_joins_the_loss(trained):
    """The trainer composes the toy term after the PPO loss: its metric and coefficient are reported, and a
    heavy weight on it pulls the policy mean from about 0 at initialisation toward 0.5 within one period."""
    trainer, init_params, state, metrics = trained
    obs = jnp.asarray(np.random.default_rng(0).normal(size=(64, ToyEnv.observation_size)), jnp.float32)
    obs = obs.at[:, :3].set(0.0)  # what this env's policy sees

    def distance(params) -> float:
        mean = jax.vmap(lambda p: trainer.networks.policy(p, obs)[0])(params)
        return float(jnp.mean(jnp.abs(mean - 0.5)))

    assert np.allclose(np.asarray(metrics["toy_pull_coef"]), 50.0)
    assert np.isfinite(np.asarray(metrics["toy_pull_loss"])).all()
    assert distance(state.params) < 0.6 * distance(init_params)


def _first_layer_on_position(params, net: str) -> np.ndarray:
    """[S, 3, H] the first layer's weights on the three position inputs, per seed."""
    return np.asarray(getattr(params, net)["params"]["mlp"]["hidden_0"]["kernel"][:, :3])


def test_a_critic_that_sees_more_than_the_policy_learns_from_it(trained):
    """With ``critic_observation`` the critic learns from the position the policy cannot see: its first
    layer's weights on the position move in training, the policy's (whose input there is always 0) stay at
    their initial values."""
    _, init_params, state, metrics = trained
    assert np.isfinite(np.asarray(metrics["value_loss"])).all()
    for net, moves in (("value", True), ("policy", False)):
        before, after = (_first_layer_on_position(p, net) for p in (init_params, state.params))
        assert (not np.array_equal(after, before)) == moves, net
