"""Issue 14: every bad input of every command is one line on stderr, exit code 2, no traceback, and deletes
nothing outside a harv-jax run folder. The table covers every case the issue lists.

Each case runs in-process in a fresh working directory ``root/cwd`` with sentinel files in ``root``, in
``cwd`` and in a foreign non-empty folder; after the command they must all still be there, and no new
output folder may have appeared. Bad inputs are rejected before any compile, so the table is fast.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from cli_util import cli_run

from harv_jax.policy import shipped_path

HUGE_SEED = "99999999999999999999"

# (command and arguments, a word the error line must contain). Placeholders: POL_<kind> -> a bad policy
# file (see ``bad_policies``), FOREIGN -> a non-empty folder harv-jax did not write, FILE -> an ordinary
# file, STATE_<kind> -> a state file, RUN -> a folder with a report-able mc run.
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
    (["simulate", "--duration", "0"], "--duration"),
    (["simulate", "--duration", "-1"], "--duration"),
    (["simulate", "--duration", "nan"], "--duration"),
    (["simulate", "--duration", "abc"], "--duration"),
    (["simulate", "--dt", "0.1"], "--dt"),
    (["simulate", "--dt", "0"], "--dt"),
    (["simulate", "--state", "V=1e30"], "V=1e+30"),
    (["simulate", "--state", "V=-5"], "V=-5"),
    (["simulate", "--state", "h=1e9"], "h=1000000000.0"),
    (["simulate", "--state", "p=100"], "p=100"),
    (["simulate", "--state", "gamma=3"], "gamma=3"),
    (["simulate", "--state", "foo=1"], "foo"),
    (["simulate", "--state", "V=abc"], "V='abc'"),
    (["simulate", "--state", "V=inf"], "not finite"),
    (["simulate", "--state", "alpha"], "NAME=VALUE"),
    (["simulate", "--controls", "de=5"], "de=5"),
    (["simulate", "--throttle", "2"], "--throttle"),
    (["simulate", "--bogus"], "--bogus"),
    # --- fly
    (["fly", "--controller", "foo"], "foo"),
    (["fly", "--seed", HUGE_SEED], HUGE_SEED),
    (["fly", "--seed", "-1"], "--seed -1"),
    (["fly", "--controller", "rl", "--policy", "POL_empty"], "empty"),
    (["fly", "--controller", "rl", "--policy", "POL_truncated"], "truncated"),
    (["fly", "--controller", "rl", "--policy", "POL_text"], "not a .npz"),
    (["fly", "--controller", "rl", "--policy", "POL_missing"], "lacks the array"),
    (["fly", "--controller", "rl", "--policy", "POL_shape"], "shape"),
    (["fly", "--controller", "rl", "--policy", "POL_nan"], "non-finite"),
    (["fly", "--controller", "rl", "--policy", "POL_nometa"], "no 'meta'"),
    (["fly", "--controller", "rl", "--policy", "POL_version"], "format"),
    (["fly", "--controller", "rl", "--policy", "POL_pickle"], "Python objects"),
    (["fly", "--controller", "rl", "--policy", "POL_sizes"], "this aircraft's controller needs"),
    (["fly", "--controller", "rl", "--policy", "missing.npz"], "does not exist"),
    (["fly", "--controller", "rl", "--policy", "shipped:bogus"], "bogus"),
    (["fly", "--controller", "hybrid", "--zeta", "foo"], "--zeta"),
    (["fly", "--target-alpha", "5"], "--target-alpha"),
    (["fly", "--duration", "1e7"], "--duration"),
    (["fly", "--scenario", "nofile.json"], "nofile.json"),
    (["fly", "--scenario", "STATE_bad"], "not valid JSON"),
    (["fly", "--scenario", "STATE_huge"], "V=1e+30"),
    (["fly", "--scenario", "STATE_missing"], "lacks"),
    (["fly", "--switching", "foo"], "--switching"),
    (["fly", "--spin-s", "-1"], "--spin-s"),
    (["fly", "--out", "FILE/sub"], "is a file"),
    (["fly", "--out", ".", "--force"], "current directory"),
    # --- mc
    (["mc", "--runs", "0"], "--runs"),
    (["mc", "--runs", "10000000"], "--runs"),
    (["mc", "--seed", HUGE_SEED], HUGE_SEED),
    (["mc", "--controller", "smc,smc"], "twice"),
    (["mc", "--controller", ""], "names no controller"),
    (["mc", "--chunk", "0"], "--chunk"),
    (["mc", "--runs", "1000000", "--chunk", "300000"], "memory"),
    (["mc", "--runs", "1000000", "--chunk", "1000000"], "more than the 2,147,483,647"),
    (["mc", "--duration", "1e7"], "--duration"),
    (["mc", "--target-alpha", "nan"], "--target-alpha"),
    (["mc", "--controller", "rl", "--policy", "POL_nan"], "non-finite"),
    (["mc", "--runs", "1000000", "--duration", "600", "--controller", "smc,rl,hybrid"], "memory"),
    (["mc", "--out", "", "--force"], "current directory"),
    (["mc", "--out", "..", "--force"], "contains the current directory"),
    # --- compare
    (["compare", "--controller", "bogus"], "bogus"),
    (["compare", "--seed", HUGE_SEED], HUGE_SEED),
    (["compare", "--state", "missing.json"], "missing.json"),
    (["compare", "--policy", "POL_truncated"], "truncated"),
    (["compare", "--duration", "0"], "--duration"),
    (["compare", "--out", ".", "--force"], "current directory"),
    (["compare", "--out", "FOREIGN", "--force"], "not written by harv-jax"),
    # --- envelope
    (["envelope", "--grid", "alpha0"], "--grid"),
    (["envelope", "--grid", "foo:r0"], "foo"),
    (["envelope", "--grid", "alpha0=1,0:r0"], "LOW < HIGH"),
    (["envelope", "--n", "1"], "--n"),
    (["envelope", "--n", "100000"], "--n"),
    (["envelope", "--fixed", "V0=abc"], "abc"),
    (["envelope", "--seed", "-5"], "--seed -5"),
    (["envelope", "--duration", "1e7"], "--duration"),
    (["envelope", "--n", "1000", "--chunk", "300000"], "memory"),
    (["envelope", "--out", "..", "--force"], "contains the current directory"),
    (["envelope", "--fixed", "V0=1e30"], "initial V"),
    (["envelope", "--fixed", "h0=-5"], "initial h"),
    # --- report
    (["report", "nonexistent_dir"], "nonexistent_dir"),
    (["report", "FOREIGN"], "holds no summary.json"),
    (["report", "RUN", "--out", ".", "--force"], "contains RUN_DIR"),
    (["report", "RUN", "--out", "FOREIGN", "--force"], "not written by harv-jax"),
    # --- train
    (["train", "--steps", "1000000000000", "--out", "newrun"], "--steps"),
    (["train", "--num-envs", "100000000", "--out", "newrun"], "--num-envs"),
    (["train", "--steps", "0", "--out", "newrun"], "--steps"),
    (["train", "--seed", HUGE_SEED, "--out", "newrun"], HUGE_SEED),
    (["train", "--preset", "bogus", "--out", "newrun"], "bogus"),
    (["train", "--lr", "-1", "--out", "newrun"], "--lr"),
    (["train", "--minibatches", "7", "--out", "newrun"], "--minibatches"),
    (["train", "--init-policy", "POL_nan", "--out", "newrun"], "non-finite"),
    (["train", "--out", ".", "--force"], "current directory"),
    (["train", "--out", "FOREIGN", "--force"], "not written by harv-jax"),
    (["train", "--resume", "nonexistent"], "nonexistent"),
    (["train"], "--out"),
    # --- quickstart
    (["quickstart", "--runs", "0"], "--runs"),
    (["quickstart", "--seed", HUGE_SEED], HUGE_SEED),
    (["quickstart", "--out", ".", "--force"], "current directory"),
    (["quickstart", "--policy", "POL_text"], "not a .npz"),
    (["quickstart", "--zeta", "bogus"], "--zeta"),
    # --- the root
    (["bogus-command"], "bogus-command"),
]


def _write_npz(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    with path.open("wb") as f:
        np.savez(f, **arrays)
    return path


@pytest.fixture(scope="module")
def bad_policies(tmp_path_factory) -> dict[str, Path]:
    """One broken variant of the shipped policy per way a policy file can be bad."""
    d = tmp_path_factory.mktemp("policies")
    with np.load(shipped_path("full"), allow_pickle=False) as z:
        good = {k: z[k] for k in z.files}
    meta = json.loads(str(good["meta"]))
    raw = shipped_path("full").read_bytes()
    out = {"empty": d / "empty.npz", "truncated": d / "truncated.npz", "text": d / "text.npz"}
    out["empty"].write_bytes(b"")
    out["truncated"].write_bytes(raw[: len(raw) // 2])
    out["text"].write_text("this is not a policy\n")
    out["missing"] = _write_npz(
        d / "missing.npz", {k: v for k, v in good.items() if k != "policy/out/kernel"}
    )
    out["shape"] = _write_npz(
        d / "shape.npz", {**good, "policy/out/kernel": good["policy/out/kernel"][:, :2]}
    )
    out["nan"] = _write_npz(d / "nan.npz", {k: (np.full_like(v, np.nan) if k.startswith("policy/") else v)
                                            for k, v in good.items()})  # fmt: skip
    out["nometa"] = _write_npz(d / "nometa.npz", {k: v for k, v in good.items() if k != "meta"})
    out["version"] = _write_npz(
        d / "version.npz", {**good, "meta": np.asarray(json.dumps({**meta, "format": "v0"}))}
    )
    obj = np.empty(1, dtype=object)
    obj[0] = {"x": 1}
    with (d / "pickle.npz").open("wb") as f:
        np.savez(f, **good, extra=obj)  # an object array: loading it would need pickle
    out["pickle"] = d / "pickle.npz"
    # a well-formed policy for 5 observations: loads, but does not fit this aircraft's controller
    import jax

    from harv_jax.policy import export_npz, make_policy
    from harv_jax.ppo import normalize
    from harv_jax.ppo.networks import make_ppo_networks

    nets = make_ppo_networks(5, 3, (8,))
    pol = make_policy(nets.init(jax.random.key(0)), normalize.init_stats(5), nets)
    out["sizes"] = export_npz(d / "sizes.npz", pol)
    return out


@pytest.fixture
def sandbox(tmp_path, monkeypatch) -> dict[str, Path]:
    """``root/cwd`` as the working directory, sentinels in root and cwd, a foreign folder and a file."""
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
    (state_dir / "bad.json").write_text("{not json")
    base = {"V": 600.0, "alpha": 0.3, "beta": 0.0, "p": 0.0, "q": 0.0, "r": 0.0, "mu": 0.0, "gamma": 0.0}
    (state_dir / "huge.json").write_text(json.dumps({**base, "V": 1e30}))
    (state_dir / "missing.json").write_text(json.dumps({"V": 600.0}))
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
        "run": run,
        "home": home,
    }


def _substitute(args: list[str], sandbox: dict[str, Path], policies: dict[str, Path]) -> list[str]:
    out = []
    for a in args:
        if a.startswith("POL_"):
            a = str(policies[a[4:]])
        elif a.startswith("STATE_"):
            a = str(sandbox["states"] / f"{a[6:]}.json")
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


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def test_table_has_at_least_60_cases_over_every_command():
    assert len(CASES) >= 60
    commands = {args[0] for args, _ in CASES}
    assert {"simulate", "fly", "mc", "compare", "envelope", "report", "train", "quickstart"} <= commands


@pytest.mark.parametrize("args, needle", CASES, ids=[" ".join(a)[:60] for a, _ in CASES])
def test_bad_input_is_one_line_exit_2_and_deletes_nothing(
    monkeypatch, capsys, sandbox, bad_policies, args, needle
):
    before = _tree(sandbox["root"])
    code, _, err = cli_run(monkeypatch, capsys, *_substitute(args, sandbox, bad_policies))
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("harv-jax: error:"), err
    assert needle in lines[0], lines[0]
    assert "allow_pickle" not in err
    assert _tree(sandbox["root"]) == before  # nothing deleted, no half-made output folder


# ------------------------------------------------------------------------------- --force and the marker


def test_force_replaces_only_a_marked_run_folder(monkeypatch, capsys, sandbox):
    """A folder harv-jax wrote is replaced with --force; cwd, a parent and a foreign folder are not."""
    from harv_jax.outdir import MARKER

    args = ["simulate", "--duration", "0.05", "--out", "run"]
    assert cli_run(monkeypatch, capsys, *args)[0] == 0
    run = sandbox["cwd"] / "run"
    assert (run / MARKER).is_file() and (run / "trajectory.csv").is_file()
    (run / "old_output.txt").write_text("from the first run")
    assert cli_run(monkeypatch, capsys, *args)[0] == 2  # not without --force
    assert (run / "old_output.txt").exists()
    code, _, err = cli_run(monkeypatch, capsys, *args, "--force")
    assert code == 0, err
    assert not (run / "old_output.txt").exists() and (run / MARKER).is_file()
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
    out = prepare_out_dir(tmp_path / "a" / "b")
    assert (out / MARKER).is_file()
    (out / "x.txt").write_text("x")
    with pytest.raises(ValueError, match="not empty"):
        prepare_out_dir(out)
    assert prepare_out_dir(out, force=True) == out and not (out / "x.txt").exists()
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


POLICY_API_CASES = [("empty", "empty"), ("truncated", "truncated"), ("text", "not a .npz"),
                    ("missing", "lacks"), ("shape", "shape"), ("nan", "non-finite"), ("version", "format"),
                    ("pickle", "Python objects")]  # fmt: skip


@pytest.mark.parametrize("kind, needle", POLICY_API_CASES)
def test_policy_load_raises_value_error(bad_policies, kind, needle):
    from harv_jax import policy

    with pytest.raises(ValueError, match=needle) as e:
        policy.load(bad_policies[kind])
    assert "allow_pickle" not in str(e.value) and "\n" not in str(e.value)


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
    with pytest.raises(ValueError, match="optimizer steps"):
        ppo_config.from_dict({"total_steps": 10**12})
    with pytest.raises(ValueError, match="--num-envs"):
        ppo_config.from_dict({"num_envs": 10**8})
    for name in ("smoke", "paper-partial", "paper-full"):
        load_preset(name)  # the shipped presets pass the guards


def test_version(monkeypatch, capsys):
    from harv_jax import __version__

    code, out, err = cli_run(monkeypatch, capsys, "--version")
    assert code == 0 and out.strip() == f"harv-jax {__version__}" and not err


def test_hybrid_config_default_is_the_cli_default():
    from harv_jax.cli_options import zeta_option
    from harv_jax.control.hybrid import HybridConfig
    from harv_jax.control.registry import DEFAULT_ZETA, ControllerOptions

    assert HybridConfig().schedule == DEFAULT_ZETA == zeta_option().default == ControllerOptions().zeta
    assert DEFAULT_ZETA == "simplex"


def test_policy_help_shows_the_seed_suffix():
    from typer.testing import CliRunner

    from harv_jax import cli

    for command, flag in (("fly", "--policy"), ("train", "--init-policy")):
        text = CliRunner().invoke(cli.app, [command, "--help"], env={"COLUMNS": "200"}).output
        line = next(ln for ln in text.splitlines() if flag in ln)
        assert "[@seed]" in line, line
