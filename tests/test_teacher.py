"""Learning from a teacher: the teacher env's labels, the behaviour-cloning term of the PPO loss against
hand-worked numbers, its schedule, and the statistics over seeds."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_train import CFG, TOY_PARAMS, ToyEnv

from harv_jax.control.registry import build_controller
from harv_jax.errors import UsageError
from harv_jax.evaluation.seed_stats import iqm, iqm_ci, seed_table
from harv_jax.ppo.loss_terms import BehaviourCloning
from harv_jax.ppo.losses import LossWeights, PPOBatch, PPOLossSettings, ppo_loss
from harv_jax.ppo.networks import make_ppo_networks
from harv_jax.ppo.train import make_train
from harv_jax.task.spaces import command_to_action
from harv_jax.training.environment import make_harv_env

SMALL_ENV = {"episode_steps": 50, "domain_randomization": False}


def _batch(nets, params, teacher, n=4):
    obs = jnp.asarray(np.random.default_rng(0).normal(size=(n, nets.observation_size)), jnp.float32)
    mean, log_std = nets.policy(params, obs)
    raw = mean  # ratio 1 everywhere: the policy term is -mean(A), 0 after standardising A
    from harv_jax.ppo.networks import gaussian_log_prob

    lp = gaussian_log_prob(mean, log_std, raw)
    zeros = jnp.zeros((n,), jnp.float32)
    return obs, mean, PPOBatch(obs, raw, lp, zeros, jnp.arange(n, dtype=jnp.float32), zeros, (teacher,))


NO_VALUE = PPOLossSettings(vf_coef=0.0)
BC = (BehaviourCloning(1.0, 1.0, label_key="teacher_action"),)


def _loss(params, batch, nets, coef: float, actor: float | None = None):
    """The PPO loss without its value term, plus behaviour cloning with weight ``coef`` (actor factor
    ``actor``)."""
    actor_w = None if actor is None else jnp.asarray(actor)
    return ppo_loss(params, batch, nets, NO_VALUE, BC, LossWeights(actor_w, (jnp.asarray(coef),)))


def test_bc_term_equals_the_hand_worked_value():
    nets = make_ppo_networks(5, 3, (8,), -0.5)
    params = nets.init(jax.random.key(1))
    teacher = jnp.asarray([[0.5, -0.5, 0.0]] * 4, jnp.float32)
    obs, mean, batch = _batch(nets, params, teacher)
    mu = np.asarray(mean, np.float64)
    y = np.asarray(teacher, np.float64)
    bc = np.mean(np.sum((np.clip(mu, -1, 1) - y) ** 2 + 0.01 * (mu - y) ** 2, axis=-1))
    total_bc, m = _loss(params, batch, nets, 2.0)
    np.testing.assert_allclose(float(m["bc_loss"]), bc, rtol=1e-5)
    assert float(m["bc_coef"]) == 2.0
    total_0, _ = _loss(params, batch, nets, 0.0)
    np.testing.assert_allclose(float(total_bc - total_0), 2.0 * bc, rtol=1e-4, atol=1e-6)
    plain, _ = ppo_loss(params, batch._replace(term_data=()), nets, NO_VALUE)
    assert float(total_0) == float(plain)  # weight 0: the plain PPO loss
    # actor factor 0: only the BC term (the value term is off here) is left
    total_pg0, _ = _loss(params, batch, nets, 2.0, actor=0.0)
    np.testing.assert_allclose(float(total_pg0), 2.0 * bc, rtol=1e-5)


def test_bc_gradient_pulls_the_mean_toward_the_teacher():
    nets = make_ppo_networks(5, 3, (8,), -0.5)
    params = nets.init(jax.random.key(2))
    teacher = jnp.full((4, 3), 0.3, jnp.float32)
    obs, mean, batch = _batch(nets, params, teacher)
    grads = jax.grad(lambda p: _loss(p, batch, nets, 1.0, actor=0.0)[0])(params)
    stepped = jax.tree.map(lambda p, g: p - 0.05 * g, params, grads)
    after, _ = nets.policy(stepped, obs)
    assert float(jnp.mean((after - teacher) ** 2)) < float(jnp.mean((mean - teacher) ** 2))


def test_without_loss_terms_the_trainer_compiles_the_plain_ppo_loss():
    """No term: the loss is ``actor + value`` with no factor, whatever the config's unused settings."""
    from harv_jax.ppo.loss_terms import terms_from_config

    assert terms_from_config(CFG) == ()
    assert terms_from_config(dataclasses.replace(CFG, bc_coef=0.0, bc_coef_end=0.0)) == ()


def test_teacher_env_labels_each_step_with_the_teachers_normalized_command():
    table = {**SMALL_ENV, "teacher": "smc"}
    env, params = make_harv_env(table)
    plain, _ = make_harv_env(SMALL_ENV)
    key = jax.random.key(0)
    obs, state = env.reset(key, params)
    smc = build_controller("smc")
    cs = smc.init(state.env.episode.aircraft).replace(u_prev_rad=state.env.delta_rad)
    u, _, _ = smc.apply(cs, state.env.wind, state.env.target_rad, key)
    ac = state.env.episode.aircraft
    want = np.clip(np.asarray(command_to_action(u, ac.u_min_rad, ac.u_max_rad)), -1, 1)
    action = jnp.asarray([0.1, -0.2, 0.3], jnp.float32)
    obs2, state2, reward, done, info = env.step(key, state, action, params)
    np.testing.assert_allclose(np.asarray(info["teacher_action"]), want, rtol=1e-5, atol=1e-6)
    # the policy's action flies, not the teacher's: the plain env from the same state agrees
    _, pstate = plain.reset(key, params)
    pobs2, _, preward, _, _ = plain.step(key, pstate, action, params)
    np.testing.assert_array_equal(np.asarray(obs2), np.asarray(pobs2))
    assert float(reward) == float(preward)


def _first_label(table: dict) -> tuple[np.ndarray, object]:
    env, params = make_harv_env(table)
    key = jax.random.key(4)
    _, state = env.reset(key, params)
    _, _, _, _, info = env.step(key, state, jnp.zeros(3, jnp.float32), params)
    return np.asarray(info["teacher_action"]), (state, params)


def test_the_teacher_labels_with_the_episodes_aircraft():
    """On a randomized episode the teacher labels as the controller built on the episode's aircraft (a
    privileged teacher), not as the one built on the nominal aircraft."""
    label, (state, params) = _first_label({"episode_steps": 50, "teacher": "smc"})
    smc = build_controller("smc")
    key = jax.random.key(4)
    want = {}
    for name, model in (("nominal", params.aircraft), ("episode", state.env.episode.aircraft)):
        cs = smc.init(model).replace(u_prev_rad=state.env.delta_rad)
        u, _, _ = smc.apply(cs, state.env.wind, state.env.target_rad, key)
        ac = state.env.episode.aircraft
        want[name] = np.clip(np.asarray(command_to_action(u, ac.u_min_rad, ac.u_max_rad)), -1, 1)
    np.testing.assert_allclose(label, want["episode"], rtol=1e-5, atol=1e-6)
    assert np.any(np.abs(want["nominal"] - want["episode"]) > 1e-4)


def _spec(env: dict, **ppo):
    from harv_jax.ppo.config import PPOConfig
    from harv_jax.training.spec import TrainSpec

    return TrainSpec.from_settings("test", PPOConfig(**ppo), env)


def test_teacher_name_is_checked():
    assert _spec({"teacher": "smc-brake"}).teacher == "smc-brake"
    assert _spec({}).teacher is None
    for bad in ("rl", "hybrid", "nope", 3):
        with pytest.raises(UsageError, match="is not a controller that can teach; allowed: .*smc"):
            _spec({"teacher": bad})
    with pytest.raises(UsageError, match="cannot be combined with --in-loop"):
        _spec({"teacher": "smc", "loop": "hybrid:gated"})


def test_bc_and_demos_are_checked_once_in_the_spec():
    with pytest.raises(UsageError, match="clone a teacher, and this run has none"):
        _spec({}, bc_coef=1.0)
    with pytest.raises(UsageError, match="are cloned with weight bc_coef; set bc_coef > 0"):
        _spec({}, demos="/d.npz")
    spec = _spec({"teacher": "smc", "episode_steps": 50}, bc_coef=1.0)
    assert spec.behaviour_cloning and spec.env_settings() == {"episode_steps": 50, "teacher": "smc"}
    assert _spec(spec.env_settings(), bc_coef=1.0) == spec  # the recorded settings give the spec back


def test_bc_needs_an_env_with_teacher_labels():
    from harv_jax.ppo.loss_terms import terms_from_config

    cfg = dataclasses.replace(CFG, bc_coef=1.0)
    with pytest.raises(ValueError, match="needs an env that writes a teacher's action labels, or demos"):
        terms_from_config(cfg)
    with pytest.raises(ValueError, match=r"asks for the loss terms \['bc'\]; pass them"):
        make_train(ToyEnv(), cfg, TOY_PARAMS)  # without terms it would not clone at all
    with pytest.raises(
        ValueError, match="reads the env's info\\['teacher_action'\\], which this env does not"
    ):
        make_train(ToyEnv(), cfg, TOY_PARAMS, terms=terms_from_config(cfg, "teacher_action"))


def test_iqm_and_its_bootstrap_interval():
    assert iqm([1.0, 2.0, 3.0, 4.0]) == pytest.approx(2.5)  # middle half: 2, 3
    assert iqm([0.0, 1.0, 1.0, 1.0, 100.0, 1.0, 1.0, 1.0]) == pytest.approx(1.0)
    q = iqm_ci([0.9, 0.95, 1.0, 1.0, 0.2])
    assert q["ci_low"] <= q["iqm"] <= q["ci_high"] and q["n"] == 5
    assert iqm_ci([0.7]) == {"iqm": 0.7, "ci_low": 0.7, "ci_high": 0.7, "n": 1}
    assert iqm_ci([0.9, 0.95, 1.0], seed=3) == iqm_ci([0.9, 0.95, 1.0], seed=3)  # reproducible


def test_seed_table_names_the_seeds_that_meet_the_bar():
    t = seed_table({"recovered": [1.0, 0.99, 0.996], "t_recover_mean_s": [10.0, 12.0, 11.0]}, bar=0.995)
    assert t["seeds_meeting_bar"] == [0, 2] and not t["all_seeds_meet_bar"]
    assert t["per_seed"]["t_recover_mean_s"] == [10.0, 12.0, 11.0]
    assert set(t["iqm"]) == {"recovered", "t_recover_mean_s"}


def test_best_seed_is_picked_on_the_evaluation_batch_then_by_return():
    from harv_jax.training.outputs import best_seed, seed_summary, seed_verdict

    row = {
        "eval/recovered": np.array([1.0, 0.98, 1.0]),
        "eval/t_recover_mean_s": np.array([14.0, 10.0, 13.0]),
        "episode_return": np.array([9.0, 8.0, 1.0]),
    }
    assert best_seed([row]) == 2  # all recovered first, then the shortest mean time; not the best return
    assert best_seed([{"episode_return": np.array([1.0, 5.0, np.nan])}]) == 1
    seeds = seed_summary(row)
    assert seeds["seeds_meeting_bar"] == [0, 2]
    line = seed_verdict(seeds)
    assert line.startswith("2 of 3 seeds (0, 2) recover >= 99.5% of the evaluation batch")
    assert "seed 1: 98.0%" in line and "t_recover_mean_s IQM" in line


def test_report_section_lists_every_seed_and_the_iqm():
    from harv_jax.report.document import Doc, to_markdown
    from harv_jax.report.train_section import train_section
    from harv_jax.training.outputs import seed_summary

    row = {"eval/recovered": np.array([1.0, 0.98]), "eval/t_recover_mean_s": np.array([14.0, 10.0])}
    doc = Doc()
    train_section(doc, {"seeds": seed_summary(row), "best_seed": 0})
    text = to_markdown(doc, Path("."))
    assert "| recovered (evaluation batch) | 100.0% | 98.0% |" in text
    assert "Seeds that recover at least 99.5% of the evaluation batch: 0 (1 of 2)" in text


@pytest.mark.parametrize(
    ("teacher", "message"),
    [
        ('"nope"', "[env] teacher 'nope' is not a controller that can teach; allowed: smc"),
        ('"rl"', "[env] teacher 'rl' is not a controller that can teach"),
        ("3", "[env] teacher 3 is not a controller that can teach"),
        ('"smc"\nteacher_model = "nominal"', "unknown env setting 'teacher_model'"),
        (None, "bc_coef 1 / bc_coef_end 0 clone a teacher, and this run has none"),
    ],
)
def test_a_bad_teacher_is_one_line_and_no_run_folder(tmp_path, monkeypatch, capsys, teacher, message):
    from cli_util import cli_run

    preset = tmp_path / "p.toml"
    env = "" if teacher is None else f"[env]\nteacher = {teacher}\n"
    preset.write_text(f"[ppo]\ntotal_steps = 4096\nnum_envs = 16\nbc_coef = 1.0\n{env}")
    code, _, err = cli_run(monkeypatch, capsys, "train", "--preset", preset, "--out", tmp_path / "run")
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "run").exists()
