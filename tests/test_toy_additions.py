"""Extension points of the trainer, each shown with a toy: a loss term defined in one place and a critic that
observes more than the policy, both on the toy env of ``test_train``."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
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


def test_a_loss_term_defined_outside_the_package_joins_the_loss():
    """The trainer composes the toy term after the PPO loss: its metric and coefficient are reported, and a
    heavy weight on it pulls the policy mean from about 0 at initialisation toward 0.5 within one period."""
    cfg = _short_cfg()
    trainer = make_train(ToyEnv(), cfg, TOY_PARAMS, terms=(PullTowardHalf(50.0),))
    init = trainer.init(seed_keys(jax.random.key(0), cfg.num_seeds), TOY_PARAMS)
    obs = jnp.asarray(np.random.default_rng(0).normal(size=(64, ToyEnv.observation_size)), jnp.float32)

    def distance(params) -> float:
        mean = jax.vmap(lambda p: trainer.networks.policy(p, obs)[0])(params)
        return float(jnp.mean(jnp.abs(mean - 0.5)))

    d0 = distance(init.params)
    state, metrics = trainer.period(init, TOY_PARAMS)
    assert np.allclose(np.asarray(metrics["toy_pull_coef"]), 50.0)
    assert np.isfinite(np.asarray(metrics["toy_pull_loss"])).all()
    assert distance(state.params) < 0.6 * d0, (distance(state.params), d0)


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


def _first_layer_on_position(params, net: str) -> np.ndarray:
    """[S, 3, H] the first layer's weights on the three position inputs, per seed."""
    return np.asarray(getattr(params, net)["params"]["mlp"]["hidden_0"]["kernel"][:, :3])


def test_a_critic_that_sees_more_than_the_policy_learns_from_it():
    """With ``critic_observation`` the critic learns from the position the policy cannot see: its first
    layer's weights on the position move in training; with the critic on the policy's observation (where the
    position is always 0) they stay at their initial values, as the policy's do in both runs."""
    cfg = _short_cfg()

    class Blind(SeeingEnv):
        critic_observation = None

    moved = {}
    for name, env in (("privileged", SeeingEnv()), ("blind", Blind())):
        trainer = make_train(env, cfg, TOY_PARAMS)
        init = trainer.init(seed_keys(jax.random.key(0), cfg.num_seeds), TOY_PARAMS)
        before = {n: _first_layer_on_position(init.params, n) for n in ("value", "policy")}
        state, metrics = trainer.period(init, TOY_PARAMS)
        assert np.isfinite(np.asarray(metrics["value_loss"])).all()
        moved[name] = {
            n: not np.array_equal(_first_layer_on_position(state.params, n), b) for n, b in before.items()
        }
    assert moved == {
        "privileged": {"value": True, "policy": False},
        "blind": {"value": False, "policy": False},
    }
