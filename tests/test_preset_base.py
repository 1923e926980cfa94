"""A preset file that names a ``base`` file: its tables read on top of the base's, key by key."""

from __future__ import annotations

from pathlib import Path

from harv_jax.training.presets import load_preset

REPO = Path(__file__).resolve().parents[1]

BASE = """description = "the base"
[ppo]
total_steps = 100_000
lr = 1e-3
hidden_sizes = [64, 64]
[env]
episode_steps = 3000
[reward]
action_weight = 0.1
raw_weight = 0.3
"""


def test_a_file_overrides_its_base_key_by_key(tmp_path):
    (tmp_path / "base.toml").write_text(BASE)
    (tmp_path / "mid.toml").write_text('base = "base.toml"\n[reward]\nraw_weight = 0.5\n')
    (tmp_path / "child.toml").write_text(
        'description = "the child"\nbase = "mid.toml"\n[ppo]\nlr = 3e-4\nhidden_sizes = [128, 128]\n'
    )
    cfg, env = load_preset(str(tmp_path / "child.toml"))
    base_cfg, base_env = load_preset(str(tmp_path / "base.toml"))
    assert (cfg.lr, cfg.hidden_sizes) == (3e-4, (128, 128))
    assert cfg.replace(lr=base_cfg.lr, hidden_sizes=base_cfg.hidden_sizes) == base_cfg
    assert env["episode_steps"] == 3000
    assert env["reward"] == {"action_weight": 0.1, "raw_weight": 0.5}  # the mid file's key, the base's other


def test_an_experiment_preset_is_its_base_plus_what_it_lists():
    folder = REPO / "experiments" / "teacher_recipe"
    cfg, env = load_preset(str(folder / "v27_teacher_zoom_256.toml"))
    base_cfg, base_env = load_preset(str(folder / "v23_teacher_zoom_wide.toml"))
    assert cfg.hidden_sizes == (256, 256) and base_cfg.hidden_sizes == (128, 128)
    assert cfg.replace(hidden_sizes=(128, 128)) == base_cfg
    assert env == base_env
