"""Every bad input of every command is one line on stderr, exit code 2, no traceback, and writes nothing.

:data:`CASES` runs each case in-process (``cli_util.cli_run``) in a fresh working directory ``root/cwd`` with
sentinel files in ``root``, in ``cwd`` and in a foreign non-empty folder; after the command the tree under
``root`` must be exactly as before: nothing deleted, no output folder, no lock or half-made file. Placeholders
in the arguments name prepared inputs: bad presets (:data:`BAD_PRESETS`), state files (:data:`BAD_STATES`),
policy files and checkpoints (the ``bad_policies`` and ``bad_checkpoints`` fixtures) and folders for
``--resume`` (:data:`BAD_RESUME_DIRS`). The same files go through the Python API too, which raises a one-line
ValueError. Bad inputs are rejected before anything is compiled, so the table is fast.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import zipfile
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import pytest
from cli_util import cli_run

from harv_jax.policy import shipped_path

HUGE_SEED = "99999999999999999999"
REPO = Path(__file__).resolve().parents[1]

# ----------------------------------------------------------------------------------------- bad presets

#: name -> (the text of a preset file, a word the error line must contain); ``harv-jax train --preset FILE``
#: and ``load_preset(FILE)`` must refuse each. ``None`` as text: a folder named ``<name>.toml``.
BAD_PRESETS: dict[str, tuple[str | bytes | None, str]] = {
    # the file itself
    "folder": (None, "is a directory"),
    "binary": (b"\xff\xfe\x00\x81[ppo]\n", "not UTF-8"),
    "malformed": ("[ppo\nlr = 1e-3\n", "not valid TOML"),
    "no_value": ("[ppo]\nlr =\n", "not valid TOML"),
    "duplicate_key": ("[ppo]\nlr = 1e-3\nlr = 2e-3\n", "not valid TOML"),
    "unknown_table": ("[bogus]\nx = 1\n", "unknown tables ['bogus']"),
    "ppo_not_table": ("ppo = 5\n", "ppo = 5 must be a table"),
    "env_not_table": ("env = [1, 2]\n", "env = [1, 2] must be a table"),
    "reward_not_table": ("reward = 1.0\n", "reward = 1.0 must be a table"),
    "description": ("description = 5\n", "description = 5 must be a string"),
    # a base file
    "base_missing": ('base = "nope.toml"\n', "base = 'nope.toml' is not a file"),
    "base_path": ('base = "../ppo_nan.toml"\n', "the name of a .toml file in the same folder"),
    "base_not_string": ("base = 5\n", "base = 5; allowed"),
    "base_loop_a": ('base = "base_loop_b.toml"\n', "none twice"),
    "base_loop_b": ('base = "base_loop_a.toml"\n', "none twice"),
    "base_bad_value": ('base = "ppo_nan.toml"\n', "--lr nan"),
    # [ppo]
    "ppo_unknown": ("[ppo]\nlrr = 1e-3\n", "unknown PPO setting 'lrr'"),
    "ppo_string": ('[ppo]\ntotal_steps = "lots"\n', "--steps 'lots'"),
    "ppo_float_for_int": ("[ppo]\nnum_envs = 256.0\n", "--num-envs 256.0"),
    "ppo_bool_for_int": ("[ppo]\nepochs = true\n", "--epochs True"),
    "ppo_int_for_bool": ("[ppo]\nnormalize_observations = 1\n", "normalize_observations 1"),
    "ppo_bool_for_float": ("[ppo]\nlr = true\n", "--lr True"),
    "ppo_nan": ("[ppo]\nlr = nan\n", "--lr nan"),
    "ppo_inf": ("[ppo]\nmax_grad_norm = inf\n", "--max-grad-norm inf"),
    "ppo_minus_inf": ("[ppo]\nent_coef = -inf\n", "--ent-coef -inf"),
    "ppo_float_overflow": ("[ppo]\nvf_coef = 1e400\n", "--vf-coef inf"),
    "ppo_int_overflow": ("[ppo]\nlr = 1" + "0" * 400 + "\n", "--lr inf"),
    "ppo_zero": ("[ppo]\nunroll = 0\n", "--unroll 0"),
    "ppo_negative": ("[ppo]\nclip_eps = -0.2\n", "--clip-eps -0.2"),
    "ppo_gamma": ("[ppo]\ngamma = 1.5\n", "--gamma 1.5"),
    "ppo_gae_lambda": ("[ppo]\ngae_lambda = -0.1\n", "--gae-lambda -0.1"),
    "ppo_lr_huge": ("[ppo]\nlr = 1e30\n", "--lr 1e+30"),
    "ppo_log_std": ("[ppo]\ninit_log_std = 100.0\n", "--init-log-std 100.0"),
    "ppo_steps_huge": ("[ppo]\ntotal_steps = 9_000_000_000_000_000_000\n", "--steps 9000000000000000000"),
    "ppo_steps_max": ("[ppo]\ntotal_steps = 1_000_000_000_000\n", "past the maximum"),
    "ppo_steps_optimizer": (
        "[ppo]\ntotal_steps = 10_000_000_000\nnum_envs = 8\nunroll = 8\nminibatches = 1\nepochs = 100\n",
        "optimizer steps",
    ),
    "ppo_num_envs_huge": ("[ppo]\nnum_envs = 100_000_000\n", "--num-envs 100,000,000"),
    "ppo_epochs_huge": ("[ppo]\nepochs = 100_000\n", "--epochs 100000"),
    "ppo_seed_negative": ("[ppo]\nseed = -1\n", "--seed -1"),
    "ppo_seed_huge": ("[ppo]\nseed = 4_294_967_296\n", "--seed 4294967296"),
    "ppo_schedule": ('[ppo]\nlr_schedule = "cosine"\n', "--lr-schedule 'cosine'"),
    "ppo_minibatches": ("[ppo]\nminibatches = 7\n", "--minibatches 7 must divide"),
    "ppo_hidden_empty": ("[ppo]\nhidden_sizes = []\n", "hidden_sizes ()"),
    "ppo_hidden_string": ('[ppo]\nhidden_sizes = "64"\n', "hidden_sizes '64'"),
    "ppo_hidden_bool": ("[ppo]\nhidden_sizes = [64, true]\n", "hidden_sizes (64, True)"),
    "ppo_hidden_zero": ("[ppo]\nhidden_sizes = [64, 0]\n", "hidden_sizes (64, 0)"),
    "ppo_hidden_wide": ("[ppo]\nhidden_sizes = [1_000_000]\n", "hidden_sizes[0] = 1000000"),
    "ppo_hidden_deep": ("[ppo]\nhidden_sizes = [" + "8, " * 100 + "8]\n", "hidden_sizes has 101 layers"),
    "ppo_hidden_memory": ("[ppo]\nhidden_sizes = [65536, 65536, 65536]\n", "memory"),
    # [env]
    "env_unknown": ("[env]\nepisode_step = 100\n", "unknown env setting 'episode_step'"),
    "env_string": ('[env]\ndt_s = "0.01"\n', "env.dt_s = '0.01'"),
    "env_float_for_int": ("[env]\nepisode_steps = 100.5\n", "env.episode_steps = 100.5"),
    "env_bool_for_int": ("[env]\nmax_delay_steps = true\n", "env.max_delay_steps = True"),
    "env_int_for_bool": ("[env]\ndomain_randomization = 1\n", "env.domain_randomization = 1"),
    "env_list": ("[env]\nthrottle = [0.2]\n", "env.throttle = [0.2]"),
    "env_dt_zero": ("[env]\ndt_s = 0.0\n", "env.dt_s = 0.0"),
    "env_dt_huge": ("[env]\ndt_s = 10.0\n", "env.dt_s = 10.0"),
    "env_nan": ("[env]\nthrottle = nan\n", "env.throttle = nan"),
    "env_inf": ("[env]\nh0_ft = inf\n", "env.h0_ft = inf"),
    "env_h0_negative": ("[env]\nh0_ft = -100.0\n", "env.h0_ft = -100.0"),
    "env_floor_nan": ("[env]\nh_floor_ft = nan\n", "env.h_floor_ft = nan"),
    "env_floor_inf": ("[env]\nh_floor_ft = inf\n", "env.h_floor_ft = inf"),
    "env_floor_above": ("[env]\nh0_ft = 10000.0\nh_floor_ft = 20000.0\n", "env.h_floor_ft = 20000.0"),
    "env_steps_negative": ("[env]\nepisode_steps = -5\n", "env.episode_steps = -5"),
    "env_steps_huge": ("[env]\nepisode_steps = 1_000_000_000_000\n", "env.episode_steps = 1000000000000"),
    "env_delay_huge": ("[env]\nmax_delay_steps = 100_000\n", "env.max_delay_steps = 100000"),
    "env_discount": ("[env]\ndiscount = 0.0\n", "env.discount = 0.0"),
    "env_throttle": ("[env]\nthrottle = 1.5\n", "env.throttle = 1.5"),
    "env_loop": ('[env]\nloop = "hybrid:bogus"\n', "'hybrid:bogus'"),
    # [reward]
    "reward_unknown": ("[reward]\nw_trak = [1.0, 1.0, 1.0]\n", "unknown [reward] setting 'w_trak'"),
    "reward_string": ('[reward]\naction_weight = "1"\n', "reward.action_weight = '1'"),
    "reward_bool": ("[reward]\nbonus_shape = true\n", "reward.bonus_shape = True"),
    "reward_short_list": ("[reward]\nw_track = [1.0, 2.0]\n", "w_track = [1.0, 2.0] must be a list of 3"),
    "reward_scalar_for_list": ("[reward]\nrecovered_tol = 0.1\n", "recovered_tol = 0.1 must be a list of 4"),
    "reward_list_for_scalar": ("[reward]\nw_p1 = [0.3]\n", "reward.w_p1 = [0.3]"),
    "reward_nan_in_list": ("[reward]\nw_track = [1.0, nan, 1.0]\n", "reward.w_track[1] = nan"),
    "reward_negative": ("[reward]\naction_weight = -1.0\n", "reward.action_weight = -1.0 is outside"),
    "reward_huge": ("[reward]\nterminal_reward = -1e30\n", "reward.terminal_reward = -1e+30"),
    "reward_inf": ("[reward]\nshaping_weight = inf\n", "reward.shaping_weight = inf"),
    # [randomization]
    "rand_unknown": ("[randomization]\nmass_fraction = 0.1\n", "setting 'mass_fraction'"),
    "rand_switch_int": ("[randomization]\ngust_on = 1\n", "randomization.gust_on = 1"),
    "rand_range": ("[randomization]\nmass_frac = 0.9\n", "randomization.mass_frac = 0.9"),
    "rand_nan": ("[randomization]\ninertia_frac = nan\n", "randomization.inertia_frac = nan"),
    "rand_string": ('[randomization]\ngust_std_max_fps = "10"\n', "randomization.gust_std_max_fps = '10'"),
    "rand_noise_length": ("[randomization]\nnoise_std_max = [1.0, 2.0]\n", "must be a list of 8"),
    "rand_delay_fraction": ("[randomization]\ndelay_max_steps = 1.5\n", "delay_max_steps = 1.5 must"),
    "rand_tau_order": ("[randomization]\ngust_tau_min_s = 20.0\n", "randomization.gust_tau_min_s = 20"),
    "rand_turbulence_name": ('[randomization]\nturbulence = "gale"\n', "randomization.turbulence = 'gale'"),
    "rand_turbulence_negative": ("[randomization]\nturbulence = -2.0\n", "randomization.turbulence = -2.0"),
    "rand_turbulence_nan": ("[randomization]\nturbulence = nan\n", "randomization.turbulence = nan"),
    "rand_turbulence_table": (
        "[randomization]\nturbulence_wind_20ft_fps = 5.0\n",
        "unknown [randomization] setting 'turbulence_wind_20ft_fps'",
    ),
    "rand_turbulence_no_dr": (
        '[env]\ndomain_randomization = false\n[randomization]\nturbulence = "light"\n',
        "needs env.domain_randomization = true",
    ),
    "rand_lag_negative": ("[randomization]\nlag_max_s = -0.1\n", "randomization.lag_max_s = -0.1"),
    "env_turbulence_switch": ("[env]\nturbulence = true\n", "unknown env setting 'turbulence'"),
    # [spin]
    "spin_unknown": ("[spin]\nmix = 0.2\n", "unknown [spin] setting 'mix'"),
    "spin_prob": ("[spin]\nreset_prob = 1.5\n", "spin.reset_prob = 1.5"),
    "spin_prob_nan": ("[spin]\nreset_prob = nan\n", "spin.reset_prob = nan"),
    "spin_bank_zero": ("[spin]\nbank_size = 0\n", "spin.bank_size = 0"),
    "spin_bank_huge": ("[spin]\nbank_size = 10_000_000\n", "spin.bank_size = 10000000"),
    "spin_bank_float": ("[spin]\nbank_size = 256.0\n", "spin.bank_size = 256.0"),
    "spin_seed_huge": ("[spin]\nbank_seed = 9_000_000_000\n", "spin.bank_seed 9000000000"),
    "spin_seed_negative": ("[spin]\nbank_seed = -1\n", "spin.bank_seed = -1"),
    "spin_times": ("[spin]\nspin_s_min = 20.0\nspin_s_max = 10.0\n", "spin.spin_s_max = 10.0"),
    "spin_switch": ('[spin]\nrandomize_aircraft = "yes"\n', "spin.randomize_aircraft = 'yes'"),
    # [eval]
    "eval_unknown": ("[eval]\nevry = 1\n", "unknown [eval] setting 'evry'"),
    "eval_negative": ("[eval]\nevery = -1\n", "eval.every = -1"),
    "eval_float": ("[eval]\nevery = 1.5\n", "eval.every = 1.5"),
    "eval_runs_huge": ("[eval]\nupset_runs = 10_000_000\n", "eval.upset_runs = 10000000"),
    "eval_duration": ("[eval]\nduration_s = 5.0\n", "eval.duration_s = 5.0"),
    "eval_duration_inf": ("[eval]\nduration_s = inf\n", "eval.duration_s = inf"),
    "eval_empty_batch": ("[eval]\nevery = 1\nupset_runs = 0\nspin_runs = 0\n", "upset_runs + eval.spin_runs"),
}  # fmt: skip

# ------------------------------------------------------------------------------------- bad state files

BASE_STATE = {"V": 600.0, "alpha": 0.3, "beta": 0.0, "p": 0.0, "q": 0.0, "r": 0.0, "mu": 0.0, "gamma": 0.0}


def _json_state(**changes: Any) -> str:
    return json.dumps({**BASE_STATE, **changes})


def _csv_state(**changes: str) -> str:
    row = {**{k: str(v) for k, v in BASE_STATE.items()}, **changes}
    return ",".join(row) + "\n" + ",".join(row.values()) + "\n"


#: name -> (file name, content, a word the error line must contain); ``harv-jax fly --scenario FILE`` and
#: ``load_state_file`` must refuse each. ``None`` as content: a folder of that name.
BAD_STATES: dict[str, tuple[str, str | bytes | None, str]] = {
    "bad": ("bad.json", "{not json", "not valid JSON"),
    "huge": ("huge.json", _json_state(V=1e30), "V=1e+30"),
    "missing": ("missing.json", json.dumps({"V": 600.0}), "lacks alpha, beta"),
    "empty": ("empty.json", "", "is empty"),
    "blank": ("blank.csv", "\n  \n", "is empty"),
    "list": ("list.json", "[600, 0.3]", "must hold a JSON object"),
    "number": ("number.json", "600", "must hold a JSON object"),
    "nested": ("nested.json", _json_state(V={"value": 600}), "V={'value': 600} is not a number"),
    "string": ("string.json", _json_state(V="600"), "V='600' is not a number"),
    "bool": ("bool.json", _json_state(p=True), "p=True is not a number"),
    "null": ("null.json", _json_state(q=None), "q=None is not a number"),
    "nan": ("nan.json", _json_state(alpha=float("nan")), "alpha=nan is not finite"),
    "inf": ("inf.json", _json_state(r=float("-inf")), "r=-inf is not finite"),
    "bigint": ("bigint.json", _json_state(V=10**400), "V=10000000000"),
    "extra": ("extra.json", _json_state(Vx=1.0), "unknown name 'Vx'"),
    "V_zero": ("v_zero.json", _json_state(V=0.0), "V=0.0"),
    "V_negative": ("v_negative.json", _json_state(V=-5.0), "V=-5.0"),
    "alpha": ("alpha.json", _json_state(alpha=4.0), "alpha=4.0"),
    "alpha_negative": ("alpha_negative.json", _json_state(alpha=-3.5), "alpha=-3.5"),
    "beta": ("beta.json", _json_state(beta=2.0), "beta=2.0"),
    "gamma": ("gamma.json", _json_state(gamma=-2.0), "gamma=-2.0"),
    "rate": ("rate.json", _json_state(p=50.0), "p=50.0"),
    "chi": ("chi.json", _json_state(chi=100.0), "chi=100.0"),
    "h_negative": ("h_negative.json", _json_state(h=-100.0), "h=-100.0"),
    "h_zero": ("h_zero.json", _json_state(h=0.0), "h=0.0"),
    "h_huge": ("h_huge.json", _json_state(h=1e6), "h=1000000.0"),
    "deep": ("deep.json", "[" * 100_000, "nested too deeply"),
    "binary": ("binary.json", b"\xff\xfe\x00\x81", "not UTF-8"),
    "csv_nan": ("nan.csv", _csv_state(V="nan"), "V=nan is not finite"),
    "csv_text": ("text.csv", _csv_state(V="abc"), "V='abc' is not a number"),
    "csv_gap": ("gap.csv", _csv_state(alpha=""), "alpha='' is not a number"),
    "csv_twice": ("twice.csv", "V,V,alpha,beta,p,q,r,mu,gamma\n600,600,0.3,0,0,0,0,0,0\n", "appears twice"),
    "csv_unknown": ("unknown.csv", _csv_state(foo="1"), "unknown name 'foo'"),
    "csv_header_only": ("header.csv", "V,alpha\n", "needs a header row and a data row"),
    "csv_short_row": ("short.csv", "V,alpha,beta\n600,0.3\n", "3 header names but 2 values"),
    "suffix": ("state.txt", "V=600", "must end in .json or .csv"),
    "folder": ("folder.json", None, "nor an existing file"),
}

# ----------------------------------------------------------------------------------- bad policy files

#: kind -> a word the error must contain, for a policy file ``.npz`` built by the ``bad_policies`` fixture.
BAD_POLICIES: dict[str, str] = {
    "empty": "empty", "truncated": "truncated", "text": "not a .npz", "missing": "lacks the array",
    "shape": "shape", "nan": "non-finite", "inf": "non-finite", "int": "dtype int32", "nometa": "no 'meta'",
    "version": "format", "pickle": "Python objects", "pickle_meta": "Python objects",
    "meta_json": "'meta' is not valid JSON", "meta_list": "'meta' must be a JSON object",
    "meta_lacks": "meta lacks hidden_sizes", "meta_bool": "hidden_sizes[0] True",
    "meta_huge": "observation_size 1000000000", "meta_flag": "normalize_observations 'yes'",
    "std_zero": "obs_std must be > 0", "count": "obs_count=-1.0", "huge_header": "memory",
    "raw_member": "is not a .npy array",
}  # fmt: skip

#: kind -> a word the error must contain, for a checkpoint built by the ``bad_checkpoints`` fixture
#: (``good`` is intact, with seeds 0 and 1).
BAD_CHECKPOINTS: dict[str, str] = {
    "good@2": "seeds 0 to 1 only", f"good@{HUGE_SEED}": "seeds 0 to 1 only", "empty": "unreadable",
    "truncated": "unreadable", "corrupt": "corrupt", "foreign": "not a harv_jax PPO checkpoint",
    "version": "has version 99", "nan": "holds NaN or inf", "config": "--lr -1.0", "lacks": "incomplete",
}  # fmt: skip

#: name -> ({path in the folder: text}, a word the error must contain) for ``harv-jax train --resume DIR``.
BAD_RESUME_DIRS: dict[str, tuple[dict[str, str], str]] = {
    "bad_json": ({"config.json": "{not json"}, "is unreadable"),
    "no_ppo": ({"config.json": json.dumps({"env": {}})}, "is unreadable (KeyError)"),
    "bad_ppo": ({"config.json": json.dumps({"ppo": {"lr": -1.0}})}, "--lr -1.0"),
    "bad_env": ({"config.json": json.dumps({"ppo": {}, "env": {"episode_steps": 0}})}, "episode_steps = 0"),
    "bad_loop": ({"config.json": json.dumps({"ppo": {}, "env": {"loop": "hybrid:x"}})}, "'hybrid:x'"),
    "env_list": ({"config.json": json.dumps({"ppo": {}, "env": [1]})}, "a table of settings, got [1]"),
    "damaged": ({"checkpoints/ckpt_000001.msgpack": "garbage"}, "none of the 1 checkpoint(s)"),
}  # fmt: skip

# ------------------------------------------------------------------------------------------ the table

# (command and arguments, a word the error line must contain). Placeholders: POL_<kind>[@seed] -> a policy
# file of ``bad_policies``, CKPT_<kind>[@seed] -> a checkpoint of ``bad_checkpoints``, PRESET_<name> -> a
# file of BAD_PRESETS, STATE_<name> -> a file of BAD_STATES, RESUME_<name> -> a folder of BAD_RESUME_DIRS,
# FOREIGN -> a non-empty folder harv-jax did not write, FILE -> an ordinary file, RUN -> a folder with a
# report-able mc run.
CASES: list[tuple[list[str], str]] = [
    # --- simulate
    (["simulate", "--out", "", "--force"], "current directory"),
    (["simulate", "--out", ".", "--force"], "current directory"),
    (["simulate", "--out", "..", "--force"], "contains the current directory"),
    (["simulate", "--out", "FOREIGN", "--force"], "not written by harv-jax"),
    (["simulate", "--out", "FOREIGN"], "not empty"),
    (["simulate", "--out", "~", "--force"], "home directory"),
    (["simulate", "--out", "/", "--force"], "--out '/'"),
    (["simulate", "--out", "FILE/sub"], "is a file"),
    (["simulate", "--out", "FILE"], "is a file"),
    (["simulate", "--duration", "1e7"], "memory"),
    (["simulate", "--duration", "2e7", "--dt", "0.05"], "memory"),
    (["simulate", "--duration", "1e308"], "--duration 1e+308"),
    (["simulate", "--duration", "0"], "--duration"),
    (["simulate", "--duration", "-1"], "--duration"),
    (["simulate", "--duration", "nan"], "--duration"),
    (["simulate", "--duration", "inf"], "--duration inf"),
    (["simulate", "--duration", "abc"], "'--duration': 'abc' is not a number"),
    (["simulate", "--dt", "0.1"], "--dt"),
    (["simulate", "--dt", "0"], "--dt"),
    (["simulate", "--dt", "-0.01"], "--dt -0.01"),
    (["simulate", "--dt", "nan"], "--dt nan"),
    (["simulate", "--dt", "inf"], "--dt inf"),
    (["simulate", "--dt", "1e-300"], "--dt 1e-300"),
    (["simulate", "--state", "V=1e30"], "V=1e+30"),
    (["simulate", "--state", "V=-5"], "V=-5"),
    (["simulate", "--state", "h=1e9"], "h=1000000000.0"),
    (["simulate", "--state", "p=100"], "p=100"),
    (["simulate", "--state", "gamma=3"], "gamma=3"),
    (["simulate", "--state", "foo=1"], "foo"),
    (["simulate", "--state", "V=abc"], "V='abc'"),
    (["simulate", "--state", "V=inf"], "not finite"),
    (["simulate", "--state", "q=nan"], "q=nan is not finite"),
    (["simulate", "--state", "alpha"], "NAME=VALUE"),
    (["simulate", "--controls", "de=5"], "de=5"),
    (["simulate", "--controls", "da=inf"], "da=inf is not finite"),
    (["simulate", "--controls", "dr=abc"], "dr='abc'"),
    (["simulate", "--throttle", "2"], "--throttle"),
    (["simulate", "--throttle", "nan"], "--throttle nan"),
    (["simulate", "--throttle", "-0.5"], "--throttle -0.5"),
    (["simulate", "--bogus"], "--bogus"),
    # --- fly
    (["fly", "--controller", "foo"], "foo"),
    (["fly", "--seed", HUGE_SEED], HUGE_SEED),
    (["fly", "--seed", "-1"], "--seed -1"),
    (["fly", "--seed", "2147483648"], "--seed 2147483648"),
    (["fly", "--seed", "nan"], "'nan' is not a whole number"),
    (["fly", "--seed", "1.5"], "'1.5' is not a whole number"),
    (["fly", "--controller", "rl", "--policy", "POL_sizes"], "allowed: 11 observations -> 3 actions"),
    (["fly", "--controller", "rl", "--policy", "missing.npz"], "does not exist"),
    (["fly", "--controller", "rl", "--policy", "shipped:bogus"], "bogus"),
    (["fly", "--controller", "rl", "--policy", "POL_good@3"], "@SEED is for checkpoints"),
    (["fly", "--controller", "rl", "--policy", "POL_good@x"], "not 'x'"),
    (["fly", "--controller", "hybrid", "--policy", "POL_good@-1"], "not '-1'"),
    (["fly", "--controller", "hybrid", "--zeta", "foo"], "--zeta"),
    (["fly", "--target-alpha", "5"], "--target-alpha"),
    (["fly", "--target-alpha", "inf"], "--target-alpha inf"),
    (["fly", "--target-alpha", "nan"], "--target-alpha nan"),
    (["fly", "--duration", "1e7"], "--duration"),
    (["fly", "--duration", "nan"], "--duration nan"),
    (["fly", "--duration", "abc"], "'--duration': 'abc' is not a number"),
    (["fly", "--duration", "inf"], "--duration inf"),
    (["fly", "--duration", "0"], "--duration 0.0"),
    (["fly", "--duration", "-5"], "--duration -5.0"),
    (["fly", "--duration", "0.005"], "criterion's 10 s hold"),
    (["fly", "--duration", "10"], "--duration 10.0 s: allowed (10, 600] s"),
    (["fly", "--controller", "rl", "--switching", "sign"], "--switching 'sign' applies only to smc,"),
    (["fly", "--controller", "smc", "--policy", "shipped:fast"], "--policy 'shipped:fast' applies only"),
    (["fly", "--controller", "rl", "--zeta", "gated"], "--zeta 'gated' applies only to hybrid"),
    (["fly", "--scenario", "nofile.json"], "nofile.json"),
    (["fly", "--switching", "foo"], "--switching"),
    (["fly", "--spin-s", "-1"], "--spin-s"),
    (["fly", "--spin-s", "nan"], "--spin-s nan"),
    (["fly", "--spin-s", "inf"], "--spin-s inf"),
    (["fly", "--spin-s", "1e9"], "--spin-s 1000000000.0"),
    (["fly", "--out", "FILE/sub"], "is a file"),
    (["fly", "--out", "FILE"], "is a file"),
    (["fly", "--out", ".", "--force"], "current directory"),
    (["fly", "--bogus-flag", "1"], "--bogus-flag"),
    # --- mc
    (["mc", "--runs", "0"], "--runs"),
    (["mc", "--runs", "-1"], "--runs -1"),
    (["mc", "--runs", "nan"], "'nan' is not a whole number"),
    (["mc", "--runs", "1e3"], "'1e3' is not a whole number"),
    (["mc", "--runs", "10000000"], "--runs"),
    (["mc", "--runs", HUGE_SEED], HUGE_SEED),
    (["mc", "--seed", HUGE_SEED], HUGE_SEED),
    (["mc", "--seed", "-1"], "--seed -1"),
    (["mc", "--seed", "2147483648"], "--seed 2147483648"),
    (["mc", "--controller", "smc,smc"], "twice"),
    (["mc", "--controller", ""], "names no controller"),
    (["mc", "--chunk", "0"], "--chunk"),
    (["mc", "--chunk", "-5"], "--chunk -5"),
    (["mc", "--chunk", "inf"], "'inf' is not a whole number"),
    (["mc", "--runs", "1000000", "--chunk", "300000"], "memory"),
    (["mc", "--runs", "1000000", "--chunk", "1000000"], "more than the 2,147,483,647"),
    (["mc", "--duration", "1e7"], "--duration"),
    (["mc", "--duration", "nan"], "--duration nan"),
    (["mc", "--duration", "inf"], "--duration inf"),
    (["mc", "--duration", "0"], "--duration 0.0"),
    (["mc", "--duration", "-60"], "--duration -60.0"),
    (["mc", "--duration", "9"], "longer than the recovery criterion's 10 s hold"),
    (["mc", "--turbulence", "gale"], "--turbulence 'gale': allowed: none, light, moderate, severe"),
    (["mc", "--turbulence", "-1"], "--turbulence '-1': allowed"),
    (["mc", "--turbulence", "nan"], "--turbulence 'nan': allowed"),
    (["mc", "--turbulence", "1e9"], "a sigma in ft/s from 0 to 100"),
    (["fly", "--turbulence", "inf"], "--turbulence 'inf': allowed"),
    (["mc", "--controller", "smc,smc-brake", "--policy", "shipped:fast"], "--controller smc,smc-brake flies"),
    (["mc", "--controller", "smc,rl", "--zeta", "always"], "--zeta 'always' applies only to hybrid"),
    (["mc", "--target-alpha", "nan"], "--target-alpha"),
    (["mc", "--target-alpha", "-inf"], "--target-alpha -inf"),
    (["mc", "--target-alpha", "3"], "--target-alpha 3.0"),
    (["mc", "--controller", "rl", "--policy", "POL_nan"], "non-finite"),
    (["mc", "--controller", "rl", "--policy", "CKPT_corrupt"], "corrupt"),
    (["mc", "--runs", "1000000", "--duration", "600", "--controller", "smc,rl,hybrid"], "memory"),
    (["mc", "--out", "", "--force"], "current directory"),
    (["mc", "--out", "..", "--force"], "contains the current directory"),
    (["mc", "--out", "FILE"], "is a file"),
    (["mc", "--out", "FILE/sub"], "is a file"),
    # --- compare
    (["compare", "--controller", "bogus"], "bogus"),
    (["compare", "--seed", HUGE_SEED], HUGE_SEED),
    (["compare", "--seed", "-1"], "--seed -1"),
    (["compare", "--state", "missing.json"], "missing.json"),
    (["compare", "--state", "STATE_folder"], "is not a file"),
    (["compare", "--state", "STATE_nan"], "alpha=nan is not finite"),
    (["compare", "--state", "STATE_extra"], "unknown name 'Vx'"),
    (["compare", "--state", "STATE_empty"], "is empty"),
    (["compare", "--policy", "POL_truncated"], "truncated"),
    (["compare", "--policy", "CKPT_good@2"], "seeds 0 to 1 only"),
    (["compare", "--duration", "0"], "--duration"),
    (["compare", "--duration", "nan"], "--duration nan"),
    (["compare", "--duration", "inf"], "--duration inf"),
    (["compare", "--duration", "-1"], "--duration -1.0"),
    (["compare", "--duration", "9.5"], "criterion's 10 s hold"),
    (["compare", "--controller", "smc", "--zeta", "gated"], "--zeta 'gated' applies only to hybrid"),
    (["compare", "--spin-s", "-1"], "--spin-s -1.0"),
    (["compare", "--spin-s", "nan"], "--spin-s nan"),
    (["compare", "--target-alpha", "nan"], "--target-alpha nan"),
    (["compare", "--out", ".", "--force"], "current directory"),
    (["compare", "--out", "FOREIGN", "--force"], "not written by harv-jax"),
    (["compare", "--out", "FILE"], "is a file"),
    (["compare", "--out", "FILE/sub"], "is a file"),
    # --- envelope
    (["envelope", "--grid", "alpha0"], "--grid"),
    (["envelope", "--grid", "foo:r0"], "foo"),
    (["envelope", "--grid", "alpha0=1,0:r0"], "LOW < HIGH"),
    (["envelope", "--grid", "alpha0=nan,1:r0"], "'nan' is not finite"),
    (["envelope", "--grid", "alpha0=0,inf:r0"], "'inf' is not finite"),
    (["envelope", "--grid", "alpha0=0,1,2:r0"], "NAME=LOW,HIGH"),
    (["envelope", "--grid", "alpha0:alpha0"], "twice"),
    (["envelope", "--n", "1"], "--n"),
    (["envelope", "--n", "0"], "--n 0"),
    (["envelope", "--n", "-3"], "--n -3"),
    (["envelope", "--n", "nan"], "'nan' is not a whole number"),
    (["envelope", "--n", "100000"], "--n"),
    (["envelope", "--fixed", "V0=abc"], "abc"),
    (["envelope", "--fixed", "V0=nan"], "'nan' is not finite"),
    (["envelope", "--fixed", "foo0=1"], "'foo0=1'"),
    (["envelope", "--fixed", "alpha0=0.1"], "alpha0, which is a grid axis"),
    (["envelope", "--seed", "-5"], "--seed -5"),
    (["envelope", "--seed", "2147483648"], "--seed 2147483648"),
    (["envelope", "--duration", "1e7"], "--duration"),
    (["envelope", "--duration", "nan"], "--duration nan"),
    (["envelope", "--duration", "0"], "--duration 0.0"),
    (["envelope", "--duration", "5"], "criterion's 10 s hold"),
    (["envelope", "--controller", "smc", "--policy", "shipped:fast"], "--policy 'shipped:fast' applies only"),
    (["envelope", "--target-alpha", "inf"], "--target-alpha inf"),
    (["envelope", "--target-alpha", "0.3rad"], "'0.3rad' is not a number"),
    (["envelope", "--chunk", "0"], "--chunk 0"),
    (["envelope", "--chunk", "-1"], "--chunk -1"),
    (["envelope", "--n", "1000", "--chunk", "300000"], "memory"),
    (["envelope", "--out", "..", "--force"], "contains the current directory"),
    (["envelope", "--out", "FILE"], "is a file"),
    (["envelope", "--fixed", "V0=1e30"], "initial V"),
    (["envelope", "--fixed", "h0=-5"], "initial h"),
    # --- report
    (["report", "nonexistent_dir"], "nonexistent_dir"),
    (["report", "FOREIGN"], "holds no summary.json"),
    (["report", "RUN", "--out", ".", "--force"], "contains RUN_DIR"),
    (["report", "RUN", "--out", "FOREIGN", "--force"], "not written by harv-jax"),
    (["report", "RUN", "--out", "FILE"], "is a file"),
    # --- train: flags
    (["train", "--preset", "smoke", "--steps", "1000000000000", "--out", "newrun"], "--steps"),
    (["train", "--steps", "100000000000000000", "--out", "newrun"], "--steps 100000000000000000"),
    (["train", "--steps", "0", "--out", "newrun"], "--steps"),
    (["train", "--steps", "1000000000000", "--out", "newrun"], "past the maximum of 10,000,000,000"),
    (["train", "--steps", "-1", "--out", "newrun"], "--steps -1"),
    (["train", "--steps", "nan", "--out", "newrun"], "'nan' is not a whole number"),
    (["train", "--num-envs", "100000000", "--out", "newrun"], "--num-envs"),
    (["train", "--num-envs", "0", "--out", "newrun"], "--num-envs 0"),
    (["train", "--num-envs", "-8", "--out", "newrun"], "--num-envs -8"),
    (["train", "--unroll", "0", "--out", "newrun"], "--unroll 0"),
    (["train", "--unroll", "1000000000000", "--out", "newrun"], "--unroll 1000000000000"),
    (["train", "--epochs", "0", "--out", "newrun"], "--epochs 0"),
    (["train", "--epochs", "100000", "--out", "newrun"], "--epochs 100000"),
    (["train", "--minibatches", "7", "--out", "newrun"], "--minibatches"),
    (["train", "--minibatches", "0", "--out", "newrun"], "--minibatches 0"),
    (["train", "--seed", HUGE_SEED, "--out", "newrun"], HUGE_SEED),
    (["train", "--seed", "-1", "--out", "newrun"], "--seed -1"),
    (["train", "--seeds", "0", "--out", "newrun"], "--seeds 0"),
    (["train", "--seeds", "-2", "--out", "newrun"], "--seeds -2"),
    (["train", "--seeds", "100000000", "--out", "newrun"], "--seeds 100000000"),
    (["train", "--preset", "bogus", "--out", "newrun"], "bogus"),
    (["train", "--preset", "missing.toml", "--out", "newrun"], "'missing.toml' does not exist"),
    (["train", "--lr", "-1", "--out", "newrun"], "--lr"),
    (["train", "--lr", "0", "--out", "newrun"], "--lr 0.0"),
    (["train", "--lr", "nan", "--out", "newrun"], "--lr nan"),
    (["train", "--lr", "fast", "--out", "newrun"], "'--lr': 'fast' is not a number"),
    (["train", "--lr", "inf", "--out", "newrun"], "--lr inf"),
    (["train", "--lr", "10", "--out", "newrun"], "--lr 10.0"),
    (["train", "--periods", "0", "--out", "newrun"], "--periods 0"),
    (["train", "--periods", "-1", "--out", "newrun"], "--periods -1"),
    (["train", "--periods", "1000000000", "--out", "newrun"], "--periods 1000000000"),
    (["train", "--checkpoint-every", "0", "--out", "newrun"], "--checkpoint-every 0"),
    (["train", "--checkpoint-every", "-4", "--out", "newrun"], "--checkpoint-every -4"),
    (["train", "--watchdog-s", "nan", "--out", "newrun"], "--watchdog-s nan"),
    (["train", "--watchdog-s", "inf", "--out", "newrun"], "--watchdog-s inf"),
    (["train", "--watchdog-s", "-1", "--out", "newrun"], "--watchdog-s -1.0"),
    (["train", "--target-recovery", "nan", "--out", "newrun"], "--target-recovery nan"),
    (["train", "--target-recovery", "0", "--out", "newrun"], "--target-recovery 0.0"),
    (["train", "--target-recovery", "1.5", "--out", "newrun"], "--target-recovery 1.5"),
    (["train", "--target-recovery", "-inf", "--out", "newrun"], "--target-recovery -inf"),
    (["train", "--in-loop", "bogus", "--out", "newrun"], "--in-loop 'bogus'"),
    (["train", "--init-policy", "POL_nan", "--out", "newrun"], "non-finite"),
    (["train", "--init-policy", "POL_pickle", "--out", "newrun"], "Python objects"),
    (["train", "--init-policy", "POL_sizes", "--out", "newrun"], "has 5 observations"),
    (["train", "--init-policy", "CKPT_good@2", "--out", "newrun"], "seeds 0 to 1 only"),
    (["train", "--init-policy", "CKPT_truncated", "--out", "newrun"], "unreadable"),
    # --- train: paths and --resume
    (["train", "--out", ".", "--force"], "current directory"),
    (["train", "--out", "FOREIGN", "--force"], "not written by harv-jax"),
    (["train", "--out", "FOREIGN"], "not empty"),
    (["train", "--out", "FILE"], "is a file"),
    (["train", "--out", "FILE/sub"], "is a file"),
    (["train", "--resume", "nonexistent"], "nonexistent"),
    (["train", "--resume", "FILE"], "is not a directory"),
    (["train", "--resume", "FOREIGN"], "not a harv-jax train run folder"),
    (["train", "--resume", "RUN"], "not a harv-jax train run folder"),
    (["train", "--resume", "RESUME_bad_env", "--steps", "10"], "drop --steps"),
    (["train", "--resume", "RESUME_bad_env", "--out", "elsewhere"], "drop --out"),
    (["train"], "--out"),
    # --- quickstart
    (["quickstart", "--runs", "0"], "--runs"),
    (["quickstart", "--runs", "-1"], "--runs -1"),
    (["quickstart", "--runs", "nan"], "'nan' is not a whole number"),
    (["quickstart", "--runs", "10000000"], "--runs 10000000"),
    (["quickstart", "--seed", HUGE_SEED], HUGE_SEED),
    (["quickstart", "--seed", "-1"], "--seed -1"),
    (["quickstart", "--out", ".", "--force"], "current directory"),
    (["quickstart", "--out", "FILE"], "is a file"),
    (["quickstart", "--policy", "POL_text"], "not a .npz"),
    (["quickstart", "--policy", "CKPT_nan"], "holds NaN or inf"),
    (["quickstart", "--zeta", "bogus"], "--zeta"),
    # --- disturbances (mc) and the robustness sweep
    (["mc", "--disturbances", "wind"], "'wind'"),
    (["mc", "--disturbances", "noise,noise"], "twice"),
    (["mc", "--disturbances", "default,none"], "stand alone"),
    (["mc", "--disturbances", ""], "--disturbances ''"),
    (["mc", "--disturbances", "noise", "--noise-scale", "-1"], "--noise-scale -1"),
    (["mc", "--disturbances", "noise", "--noise-scale", "nan"], "--noise-scale nan"),
    (["mc", "--disturbances", "noise", "--noise-scale", "abc"], "'abc' is not a number"),
    (["mc", "--disturbances", "delay", "--delay-ms", "5000"], "--delay-ms 5000"),
    (["mc", "--disturbances", "gust", "--gust-fps", "inf"], "--gust-fps inf"),
    (["mc", "--disturbances", "model", "--model-error", "9"], "--model-error 9"),
    (["mc", "--disturbances", "lag", "--actuator-lag-s", "-0.1"], "--actuator-lag-s -0.1"),
    (["mc", "--noise-scale", "2"], "noise is off"),
    (["mc", "--disturbances", "noise", "--delay-ms", "50"], "delay is off"),
    (["mc", "--gust-tau-s", "3"], "gust is off"),
    (["mc", "--disturbances", "gust", "--gust-tau-s", "0"], "--gust-tau-s 0"),
    (["mc", "--controller-knows-aircraft"], "randomized aircraft"),
    (["robustness", "--disturbances", "wind"], "--disturbances 'wind'"),
    (["robustness", "--disturbances", "gust,gust"], "each once"),
    (["robustness", "--duration", "3"], "criterion's 10 s hold"),
    (["robustness", "--controller", "smc", "--zeta", "never"], "--zeta 'never' applies only to hybrid"),
    (["robustness", "--noise-levels", "1,x"], "'x' is not a number"),
    (["robustness", "--noise-levels", "-1"], "--noise-levels"),
    (["robustness", "--delay-levels", "0,0"], "twice"),
    (["robustness", "--disturbances", "gust", "--delay-levels", "0,50"], "not in --disturbances"),
    (["robustness", "--runs", "0"], "--runs"),
    (["robustness", "--controller", "bogus"], "bogus"),
    (["robustness", "--turbulence-levels", "0,-5"], "--turbulence-levels"),
    (["robustness", "--turbulence-levels", "0,200"], "from 0 to 100 (ft/s)"),
    (["robustness", "--disturbances", "gust", "--turbulence-levels", "0,5"], "not in --disturbances"),
    (["robustness", "--turbulence", "stormy"], "--turbulence 'stormy'"),
    # --- the root
    (["bogus-command"], "bogus-command"),
]
CASES += [
    (["fly", "--controller", "rl", "--policy", f"POL_{k}"], needle) for k, needle in BAD_POLICIES.items()
]
CASES += [(["fly", "--controller", "rl", "--policy", f"CKPT_{k}"], n) for k, n in BAD_CHECKPOINTS.items()]
CASES += [(["fly", "--scenario", f"STATE_{k}"], needle) for k, (_, _, needle) in BAD_STATES.items()]
CASES += [(["train", "--preset", f"PRESET_{k}", "--out", "newrun"], n) for k, (_, n) in BAD_PRESETS.items()]
CASES += [(["train", "--resume", f"RESUME_{k}"], needle) for k, (_, needle) in BAD_RESUME_DIRS.items()]


def _write_npz(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    with path.open("wb") as f:
        np.savez(f, **arrays)
    return path


def _huge_header_npz(path: Path, good: dict[str, np.ndarray]) -> Path:
    """The good arrays, but ``policy/out/kernel`` declares 10^12 float32 (4 TB) in its header (no data)."""
    _write_npz(path, {k: v for k, v in good.items() if k != "policy/out/kernel"})
    header = {"descr": "<f4", "fortran_order": False, "shape": (10**12,)}
    with zipfile.ZipFile(path, "a") as z, z.open("policy/out/kernel.npy", "w") as f:
        np.lib.format.write_array_header_1_0(f, header)
    return path


@pytest.fixture(scope="module")
def bad_policies(tmp_path_factory) -> dict[str, Path]:
    """One broken variant of the shipped policy per way a policy file can be bad (:data:`BAD_POLICIES`),
    ``good`` (a copy of the shipped one) and ``sizes`` (well-formed, for 5 observations)."""
    d = tmp_path_factory.mktemp("policies")
    with np.load(shipped_path("full"), allow_pickle=False) as z:
        good = {k: z[k] for k in z.files}
    meta = json.loads(str(good["meta"]))
    raw = shipped_path("full").read_bytes()

    without_hidden = {k: v for k, v in meta.items() if k != "hidden_sizes"}

    def with_meta(**changes: Any) -> dict[str, np.ndarray]:
        return {**good, "meta": np.asarray(json.dumps({**meta, **changes}))}

    out = {"empty": d / "empty.npz", "truncated": d / "truncated.npz", "text": d / "text.npz"}
    out["empty"].write_bytes(b"")
    out["truncated"].write_bytes(raw[: len(raw) // 2])
    out["text"].write_text("this is not a policy\n")
    arrays: dict[str, dict[str, np.ndarray]] = {
        "good": good,
        "missing": {k: v for k, v in good.items() if k != "policy/out/kernel"},
        "shape": {**good, "policy/out/kernel": good["policy/out/kernel"][:, :2]},
        "nan": {k: (np.full_like(v, np.nan) if k.startswith("policy/") else v) for k, v in good.items()},
        "inf": {**good, "obs_std": np.full_like(good["obs_std"], np.inf)},
        "int": {**good, "policy/out/kernel": good["policy/out/kernel"].astype(np.int32)},
        "nometa": {k: v for k, v in good.items() if k != "meta"},
        "version": with_meta(format="v0"),
        "meta_json": {**good, "meta": np.asarray("not json{")},
        "meta_list": {**good, "meta": np.asarray("[1, 2]")},
        "meta_lacks": {**good, "meta": np.asarray(json.dumps(without_hidden))},
        "meta_bool": with_meta(hidden_sizes=[True, 128]),
        "meta_huge": with_meta(observation_size=10**9),
        "meta_flag": with_meta(normalize_observations="yes"),
        "std_zero": {**good, "obs_std": np.zeros_like(good["obs_std"])},
        "count": with_meta(obs_count=-1.0),
    }  # fmt: skip
    for kind, a in arrays.items():
        out[kind] = _write_npz(d / f"{kind}.npz", a)
    obj = np.empty(1, dtype=object)
    obj[0] = {"x": 1}
    out["pickle"] = _write_npz(d / "pickle.npz", {**good, "extra": obj})  # loading it would need pickle
    out["pickle_meta"] = _write_npz(d / "pickle_meta.npz", {**good, "meta": obj})
    out["huge_header"] = _huge_header_npz(d / "huge_header.npz", good)
    out["raw_member"] = _write_npz(d / "raw_member.npz", good)
    with zipfile.ZipFile(out["raw_member"], "a") as z:
        z.writestr("notes.txt", "not an array")
    # a well-formed policy for 5 observations: loads, but does not fit this aircraft's controller
    import jax

    from harv_jax.policy import export_npz, make_policy
    from harv_jax.ppo import normalize
    from harv_jax.ppo.networks import make_ppo_networks

    nets = make_ppo_networks(5, 3, (8,))
    pol = make_policy(nets.init(jax.random.key(0)), normalize.init_stats(5), nets)
    out["sizes"] = export_npz(d / "sizes.npz", pol)
    return out


class _LearnerState(NamedTuple):
    """The part of a training state a policy is loaded from (a checkpoint's ``params`` and ``normalizer``)."""

    params: Any
    normalizer: Any


@pytest.fixture(scope="module")
def bad_checkpoints(tmp_path_factory) -> dict[str, Path]:
    """``good``: an intact 2-seed checkpoint of small networks; one damaged variant per way a checkpoint can
    be bad (:data:`BAD_CHECKPOINTS`)."""
    import jax
    from flax import serialization

    from harv_jax.ppo import checkpoint, normalize
    from harv_jax.ppo import config as ppo_config
    from harv_jax.ppo.networks import make_ppo_networks
    from harv_jax.task.spaces import OBSERVATION_SIZE

    d = tmp_path_factory.mktemp("checkpoints")
    small = {
        "hidden_sizes": [8],
        "num_seeds": 2,
        "num_envs": 8,
        "unroll": 4,
        "minibatches": 1,
        "total_steps": 64,
    }
    cfg = ppo_config.from_dict(small)
    nets = make_ppo_networks(OBSERVATION_SIZE, 3, (8,))
    keys = jax.random.split(jax.random.key(0), 2)
    state = _LearnerState(
        jax.vmap(nets.init)(keys), jax.vmap(lambda _: normalize.init_stats(OBSERVATION_SIZE))(keys)
    )
    saved = checkpoint.save(d / "good", state, cfg, 1, [], {})
    out = {"good": saved}
    payload = checkpoint.read(saved)

    def write(kind: str, changes: dict[str, Any], digest: bool = True) -> None:
        p = {**payload, **changes}
        if digest:
            p["sha256"] = checkpoint._digest(p)
        out[kind] = d / f"ckpt_{kind}.msgpack"
        out[kind].write_bytes(serialization.msgpack_serialize(p))

    raw = saved.read_bytes()
    out["empty"] = d / "ckpt_empty.msgpack"
    out["empty"].write_bytes(b"")
    out["truncated"] = d / "ckpt_truncated.msgpack"
    out["truncated"].write_bytes(raw[: len(raw) // 2])
    out["foreign"] = d / "ckpt_foreign.msgpack"
    out["foreign"].write_bytes(serialization.msgpack_serialize({"a": 1}))
    leaves = payload["leaves"]
    write("corrupt", {"leaves": {**leaves, "0": leaves["0"] + 1}}, digest=False)
    write("version", {"version": 99})
    write(
        "nan",
        {"leaves": {k: np.full_like(v, np.nan) if v.dtype.kind == "f" else v for k, v in leaves.items()}},
    )
    write("config", {"config": json.dumps({**json.loads(payload["config"]), "lr": -1.0})})
    write(
        "lacks", {"paths": json.dumps([p for p in json.loads(payload["paths"]) if p != ".normalizer.mean"])}
    )
    return out


@pytest.fixture(scope="module")
def bad_presets(tmp_path_factory) -> dict[str, Path]:
    """Every preset of :data:`BAD_PRESETS` as a file (or a folder) named ``<name>.toml``."""
    d = tmp_path_factory.mktemp("presets")
    out = {}
    for name, (text, _) in BAD_PRESETS.items():
        out[name] = d / f"{name}.toml"
        if text is None:
            out[name].mkdir()
        elif isinstance(text, bytes):
            out[name].write_bytes(text)
        else:
            out[name].write_text(text)
    return out


@pytest.fixture
def sandbox(tmp_path, monkeypatch) -> dict[str, Path]:
    """``root/cwd`` as the working directory, sentinels in root and cwd, a foreign folder, a file, the state
    files of :data:`BAD_STATES`, the folders of :data:`BAD_RESUME_DIRS` and an mc run folder."""
    root = tmp_path / "root"
    cwd = root / "cwd"
    foreign = cwd / "foreign"
    foreign.mkdir(parents=True)
    paths = {
        "root_sentinel": root / "keep_root.txt",
        "cwd_sentinel": cwd / "keep_cwd.txt",
        "foreign_sentinel": foreign / "keep_foreign.txt",
        "file": cwd / "plain.txt",
    }
    for p in paths.values():
        p.write_text("keep me\n")
    state_dir = cwd / "states"
    state_dir.mkdir()
    for file_name, content, _ in BAD_STATES.values():
        f = state_dir / file_name
        if content is None:
            f.mkdir()
        elif isinstance(content, bytes):
            f.write_bytes(content)
        else:
            f.write_text(content)
    resume_dir = cwd / "trainruns"
    for name, (files, _) in BAD_RESUME_DIRS.items():
        for rel, text in files.items():
            (resume_dir / name / rel).parent.mkdir(parents=True, exist_ok=True)
            (resume_dir / name / rel).write_text(text)
    run = cwd / "mcrun"
    run.mkdir()
    (run / "summary.json").write_text(json.dumps({"runs": 1, "controllers": {}}))
    monkeypatch.chdir(cwd)
    home = tmp_path / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))  # "~" and the home-directory guard point into the sandbox
    return {
        **paths,
        "root": root,
        "cwd": cwd,
        "foreign": foreign,
        "states": state_dir,
        "resume": resume_dir,
        "run": run,
        "home": home,
    }


def _substitute(args: list[str], sandbox: dict[str, Path], inputs: dict[str, dict[str, Path]]) -> list[str]:
    out = []
    for a in args:
        kind, _, name = a.partition("_")
        if kind in ("POL", "CKPT") and name:
            name, at, seed = name.partition("@")
            a = str(inputs[kind][name]) + at + seed
        elif kind == "PRESET" and name:
            a = str(inputs["PRESET"][name])
        elif kind == "STATE" and name:
            a = str(sandbox["states"] / BAD_STATES[name][0])
        elif kind == "RESUME" and name:
            a = str(sandbox["resume"] / name)
        elif a == "FOREIGN":
            a = str(sandbox["foreign"])
        elif a == "RUN":
            a = str(sandbox["run"])
        elif a.startswith("FILE"):
            a = str(sandbox["file"]) + a[4:]
        elif a == "~":
            a = str(sandbox["home"])
        out.append(a)
    return out


def _tree(root: Path) -> dict[str, bytes | None]:
    """Every path under ``root`` with its content (None for a folder)."""
    return {str(p.relative_to(root)): (None if p.is_dir() else p.read_bytes()) for p in root.rglob("*")}


@pytest.fixture(scope="module")
def inputs(bad_policies, bad_checkpoints, bad_presets) -> dict[str, dict[str, Path]]:
    return {"POL": bad_policies, "CKPT": bad_checkpoints, "PRESET": bad_presets}


def _assert_one_line_error(code: int, err: str, needle: str) -> None:
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("harv-jax: error:"), err
    assert needle in lines[0], lines[0]
    assert "allow_pickle" not in err


def test_table_covers_every_command_and_input_kind():
    assert len(CASES) >= 350
    assert len({(tuple(a), n) for a, n in CASES}) == len(CASES)  # no case twice
    commands = {args[0] for args, _ in CASES}
    assert {"simulate", "fly", "mc", "compare", "envelope", "report", "train", "quickstart"} <= commands
    used = " ".join(" ".join(args) for args, _ in CASES)
    for prefix, table in (("POL_", BAD_POLICIES), ("CKPT_", BAD_CHECKPOINTS), ("PRESET_", BAD_PRESETS),
                          ("STATE_", BAD_STATES), ("RESUME_", BAD_RESUME_DIRS)):  # fmt: skip
        assert all(f"{prefix}{k}" in used for k in table), prefix


@pytest.mark.parametrize("args, needle", CASES, ids=[" ".join(a)[:70] for a, _ in CASES])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(monkeypatch, capsys, sandbox, inputs, args, needle):
    before = _tree(sandbox["root"])
    code, _, err = cli_run(monkeypatch, capsys, *_substitute(args, sandbox, inputs))
    _assert_one_line_error(code, err, needle)
    assert _tree(sandbox["root"]) == before  # nothing deleted or changed, no half-made output folder


def test_out_in_unwritable_folder_and_unreadable_files(monkeypatch, capsys, sandbox, inputs):
    """--out below a read-only folder, and a preset, state file, policy or checkpoint that cannot be read.

    Skipped where permissions do not stop this process (root, as in the CI container): there a folder of
    mode 0o500 is writable and a file of mode 0o000 readable, so these cases cannot be made.
    """
    locked = sandbox["cwd"] / "locked"
    locked.mkdir(mode=0o500)
    secret = {
        name: sandbox["cwd"] / name for name in ("secret.toml", "secret.json", "secret.npz", "ckpt_s.msgpack")
    }
    secret["secret.toml"].write_text("[ppo]\n")
    secret["secret.json"].write_text(_json_state())
    secret["secret.npz"].write_bytes(inputs["POL"]["good"].read_bytes())
    secret["ckpt_s.msgpack"].write_bytes(inputs["CKPT"]["good"].read_bytes())
    for p in secret.values():
        p.chmod(0o000)
    try:
        if os.access(locked, os.W_OK) or os.access(secret["secret.json"], os.R_OK):
            pytest.skip("permissions do not restrict this process (running as root): no unwritable folder")
        cases = [
            (["simulate", "--out", f"{locked}/run"], "cannot be created"),
            (["simulate", "--out", str(locked)], f"--out {str(locked)!r}"),
            (["mc", "--runs", "1", "--out", f"{locked}/run"], "cannot be created"),
            (["train", "--preset", str(secret["secret.toml"]), "--out", "newrun"], "cannot be read"),
            (["fly", "--scenario", str(secret["secret.json"])], "cannot be read"),
            (["fly", "--controller", "rl", "--policy", str(secret["secret.npz"])], "cannot be read"),
            (["fly", "--controller", "rl", "--policy", str(secret["ckpt_s.msgpack"])], "cannot be read"),
        ]
        for args, needle in cases:
            before = _tree(sandbox["cwd"] / "states")
            code, _, err = cli_run(monkeypatch, capsys, *args)
            _assert_one_line_error(code, err, needle)
            assert _tree(sandbox["cwd"] / "states") == before and not any(locked.iterdir())
            assert not (sandbox["cwd"] / "newrun").exists() and not (sandbox["cwd"] / "runs").exists()
    finally:
        locked.chmod(0o700)
        for p in secret.values():
            p.chmod(0o600)


# ----------------------------------------------------------------------------------- the Python API


@pytest.mark.parametrize("name", list(BAD_PRESETS))
def test_load_preset_raises_one_line_value_error(bad_presets, name):
    from harv_jax.training.presets import load_preset

    with pytest.raises(ValueError, match=re.escape(BAD_PRESETS[name][1])) as e:
        load_preset(str(bad_presets[name]))
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("name", list(BAD_STATES))
def test_load_state_file_raises_one_line_value_error(tmp_path, name):
    from harv_jax.state_file import load_state_file

    file_name, content, needle = BAD_STATES[name]
    f = tmp_path / file_name
    if content is None:
        f.mkdir()
    elif isinstance(content, bytes):
        f.write_bytes(content)
    else:
        f.write_text(content)
    with pytest.raises(ValueError, match=re.escape(needle)) as e:
        load_state_file(f)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("kind", list(BAD_POLICIES))
def test_policy_load_raises_value_error(bad_policies, kind):
    from harv_jax import policy

    with pytest.raises(ValueError, match=re.escape(BAD_POLICIES[kind])) as e:
        policy.load(bad_policies[kind])
    assert "allow_pickle" not in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("kind", list(BAD_CHECKPOINTS))
def test_checkpoint_policy_raises_value_error(bad_checkpoints, kind):
    from harv_jax.policy import resolve_policy

    name, at, seed = kind.partition("@")
    with pytest.raises(ValueError, match=re.escape(BAD_CHECKPOINTS[kind])) as e:
        resolve_policy(str(bad_checkpoints[name]) + at + seed)
    assert "\n" not in str(e.value)


def test_good_inputs_still_load(bad_policies, bad_checkpoints):
    """The shipped and the experiments' presets, a policy copy and both seeds of the checkpoint load."""
    from harv_jax.env.config import EnvConfig
    from harv_jax.env.settings import ENV_RANGES
    from harv_jax.policy import resolve_policy
    from harv_jax.training.presets import available_presets, load_preset

    # every [env] number and switch has its range; the aircraft is a name EnvConfig checks (registry), the
    # turbulence switch follows from [randomization] turbulence
    assert set(ENV_RANGES) == {f.name for f in dataclasses.fields(EnvConfig)} - {"aircraft", "turbulence"}
    for name in available_presets():
        load_preset(name)
    files = sorted((REPO / "experiments").rglob("*.toml"))
    assert files
    for f in files:
        load_preset(str(f))
    assert resolve_policy(str(bad_policies["good"])).networks.observation_size == 11
    for seed in (0, 1):
        assert resolve_policy(f"{bad_checkpoints['good']}@{seed}").meta["seed"] == seed


# ------------------------------------------------------------------------------- --force and the marker


def test_force_replaces_only_a_marked_run_folder(monkeypatch, capsys, sandbox):
    """A folder harv-jax wrote is replaced with --force; cwd, a parent and a foreign folder are not."""
    from harv_jax.outdir import MARKER

    args = ["simulate", "--duration", "0.05", "--out", "run"]
    assert cli_run(monkeypatch, capsys, *args)[0] == 0
    run = sandbox["cwd"] / "run"
    assert (run / MARKER).is_file() and (run / "trajectory.csv").is_file()
    assert cli_run(monkeypatch, capsys, *args)[0] == 2  # not without --force
    from harv_jax.atomic import tmp_path

    (run / tmp_path(run / "old_output.csv").name).write_text("left by a killed run")
    code, _, err = cli_run(monkeypatch, capsys, *args, "--force")
    assert code == 0, err
    assert not (run / tmp_path(run / "old_output.csv").name).exists() and (run / MARKER).is_file()
    assert (run / "trajectory.csv").is_file()
    before = _tree(sandbox["root"])
    for target in (".", "..", str(sandbox["foreign"]), str(sandbox["root"])):
        code, _, err = cli_run(
            monkeypatch, capsys, "simulate", "--duration", "0.05", "--out", target, "--force"
        )
        assert code == 2 and err.count("\n") == 1, err
    assert _tree(sandbox["root"]) == before
    for key in ("root_sentinel", "cwd_sentinel", "foreign_sentinel", "file"):
        assert sandbox[key].read_text() == "keep me\n"


def test_prepare_out_dir_api(tmp_path, monkeypatch):
    from harv_jax.outdir import MARKER, prepare_out_dir

    monkeypatch.chdir(tmp_path)
    from harv_jax.atomic import write_text

    out = prepare_out_dir(tmp_path / "a" / "b")
    assert (out / MARKER).is_file()
    write_text(out / "x.txt", "x")
    with pytest.raises(ValueError, match="not empty"):
        prepare_out_dir(out)
    assert prepare_out_dir(out, force=True) == out and not (out / "x.txt").exists()
    (out / "mine.txt").write_text("mine")
    with pytest.raises(ValueError, match="did not write: mine.txt"):
        prepare_out_dir(out, force=True)
    (out / "mine.txt").unlink()
    (out / MARKER).unlink()
    (out / "y.txt").write_text("y")
    with pytest.raises(ValueError, match="not written by harv-jax"):
        prepare_out_dir(out, force=True)
    assert (out / "y.txt").exists()
    link = tmp_path / "link"
    link.symlink_to(prepare_out_dir(tmp_path / "target"))
    with pytest.raises(ValueError, match="symbolic link"):
        prepare_out_dir(link, force=True)


# ----------------------------------------------------------------------------------- the Python API


def test_dynamics_reject_wrong_shapes_but_jit_and_vmap_work():
    import jax
    import jax.numpy as jnp

    from harv_jax.aircraft import harv
    from harv_jax.dynamics import derivatives, rk4_step, rollout

    p = harv()
    x = jnp.array([600.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 25000.0])
    u = jnp.zeros(3)
    with pytest.raises(ValueError, match=r"state x .*shape \[5\], expected \[10\]"):
        derivatives(x[:5], u, p)
    with pytest.raises(ValueError, match=r"control u .*shape \[2\], expected \[3\]"):
        derivatives(x, u[:2], p)
    with pytest.raises(ValueError, match=r"shape \[5\]"):
        jax.jit(lambda a: derivatives(a, u, p))(x[:5])
    with pytest.raises(ValueError, match=r"control u"):
        rk4_step(x, u[:2], p, 0.01)
    with pytest.raises(ValueError, match=r"u_seq"):
        rollout(x, jnp.zeros((4, 2)), p, 0.01)
    batch = jnp.tile(x, (4, 1))
    xd = jax.jit(jax.vmap(lambda a: derivatives(a, u, p)))(batch)
    assert xd.shape == (4, 10) and bool(jnp.all(jnp.isfinite(xd)))


def test_seed_and_train_guards_raise_before_anything_is_built():
    from harv_jax.guards import check_closed_loop_batch, check_seed, check_simulate
    from harv_jax.ppo import config as ppo_config
    from harv_jax.training.presets import load_preset

    assert check_seed(0) == 0 and check_seed(2**31 - 1) == 2**31 - 1
    for bad in (-1, 2**31, 10**20):
        with pytest.raises(ValueError, match="--seed"):
            check_seed(bad)
    with pytest.raises(ValueError, match="memory"):
        check_simulate(1e7, 0.01)
    check_simulate(60.0, 0.01)
    check_closed_loop_batch(1000, 6000, 10, 250, 3)
    with pytest.raises(ValueError, match="past the maximum"):
        ppo_config.from_dict({"total_steps": 10**12})
    with pytest.raises(ValueError, match="optimizer steps"):
        big = {"total_steps": 10**10, "num_envs": 8, "unroll": 8, "minibatches": 1, "epochs": 100}
        ppo_config.from_dict(big)
    with pytest.raises(ValueError, match="--num-envs"):
        ppo_config.from_dict({"num_envs": 10**8})
    for name in ("smoke", "paper-partial", "paper-full"):
        load_preset(name)  # the shipped presets pass the guards


def test_version(monkeypatch, capsys):
    from harv_jax import __version__

    code, out, err = cli_run(monkeypatch, capsys, "--version")
    assert code == 0 and out.strip() == f"harv-jax {__version__}" and not err


def test_hybrid_config_default_is_the_cli_default():
    from harv_jax.cli_options import controller_options, zeta_option
    from harv_jax.control.hybrid.law import HybridConfig
    from harv_jax.control.hybrid.settings import DEFAULT_ZETA
    from harv_jax.control.registry import ControllerOptions

    assert HybridConfig().schedule == DEFAULT_ZETA == ControllerOptions().zeta
    assert zeta_option().default is None and controller_options(["hybrid"], None, None).zeta == DEFAULT_ZETA
    assert DEFAULT_ZETA == "simplex"


def test_policy_help_shows_the_seed_suffix():
    from typer.testing import CliRunner

    from harv_jax import cli

    for command, flag in (("fly", "--policy"), ("train", "--init-policy")):
        text = CliRunner().invoke(cli.app, [command, "--help"], env={"COLUMNS": "200"}).output
        line = next(ln for ln in text.splitlines() if flag in ln)
        assert "[@seed]" in line, line
