"""`harv-jax evaluate`: the acceptance criteria at each bar and just past it, the per-seed numbers from
hand-made cells, the traced-parameter rollout against the Monte Carlo's, resume, and bad input."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from cli_util import cli_run

from harv_jax.evaluation.seeds.acceptance import CRITERIA, judge, passes
from harv_jax.evaluation.seeds.report import build_document, seed_metrics

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("c", CRITERIA, ids=[c.name for c in CRITERIA])
def test_each_criterion_at_its_bar_and_just_past_it(c):
    eps = 1e-9
    good = c.bar - eps if c.op == "<=" else c.bar + eps
    bad = c.bar + eps if c.op == "<=" else c.bar - eps
    assert c.judge({c.metric: c.bar}) is True  # at the bar passes
    assert c.judge({c.metric: good}) is True
    assert c.judge({c.metric: bad}) is False
    assert c.judge({}) is None and c.judge({c.metric: float("nan")}) is None  # missing: not judged


def test_a_seed_passes_when_every_judged_required_criterion_does():
    at_bars = {c.metric: c.bar for c in CRITERIA}
    v = judge(at_bars)
    assert all(v.values()) and passes(v) is True
    stretch = next(c for c in CRITERIA if c.stretch)
    v = judge({**at_bars, stretch.metric: stretch.bar + 1.0})
    assert v[stretch.name] is False and passes(v) is True  # a stretch bar is reported, not required
    required = next(c for c in CRITERIA if not c.stretch)
    v = judge({**at_bars, required.metric: required.bar + (1.0 if required.op == "<=" else -1.0)})
    assert passes(v) is False
    assert passes(judge({})) is None


def _cell(rec, t, tv=1.0, chatter=1e-4):
    rec = np.asarray(rec, bool)
    return {
        "recovered": rec,
        "t_recover_s": np.where(rec, np.asarray(t, float), np.nan),
        "tv_rad": np.full(rec.shape, tv),
        "chatter_rad2": np.full(rec.shape, chatter),
    }


def test_seed_metrics_from_hand_made_cells():
    """Two runs: the SMC recovers at 20 and 30 s; the policy at 10 s and not at all (60 s)."""
    smc = _cell([True, True], [20.0, 30.0], tv=8.0)
    rl = _cell([True, False], [10.0, 0.0], tv=8.8)
    zoom = _cell([True, True], [10.0, 20.0])
    cells = {
        "clean": {"smc": smc, "smc-brake-zoom": zoom, "rl_seed0": rl, "hybrid_seed0": smc},
        "disturbed": {"smc+lp2": smc, "smc-brake-zoom": zoom, "rl_seed0": _cell([1, 1], [12, 12], tv=13.2)},
        "spin": {
            "smc": _cell([True], [9.0]),
            "smc-brake-zoom": _cell([True], [8.0]),
            "rl_seed0": _cell([True], [9.5]),
        },
    }
    m = seed_metrics(cells, 0, 60.0)
    assert m["clean.rl.recovered"] == 0.5
    assert m["clean.rl.mean_s"] == pytest.approx(35.0)  # (10 + 60) / 2
    assert m["clean.rl.mean_over_ref"] == pytest.approx(35.0 / 25.0)
    assert m["clean.rl.slower_than_ref"] == 0.5  # 60 > 30 + 1
    assert m["clean.rl.tv_over_ref"] == pytest.approx(1.1)
    assert m["clean.rl.mean_over_smc_brake_zoom"] == pytest.approx(35.0 / 15.0)
    assert m["disturbed.rl.tv_over_clean"] == pytest.approx(1.5)
    assert m["spin.rl.time_minus_ref_s"] == pytest.approx(0.5)
    v = judge(m)
    assert v["clean_rl_tv"] is True and v["spin_rl"] is True and v["disturbed_rl_tv"] is True
    assert v["clean_rl_recovered"] is False and v["randomized_rl_recovered"] is None
    # a spin the policy does not recover fails, whatever the SMC does
    cells["spin"]["rl_seed0"] = _cell([False], [0.0])
    assert judge(seed_metrics(cells, 0, 60.0))["spin_rl"] is False
    doc = build_document(
        {"runs": 2, "mc_seed": 0, "duration_s": 60.0, "conditions": ["clean", "disturbed", "spin"]},
        [{"seed": 0, "policy": "p.npz", "sha256": "x"}],
        cells,
        60.0,
    )
    assert doc["all_seeds_pass"] is False
    row = next(c for c in doc["criteria"] if c["name"] == "clean_rl_tv")
    assert row["seeds_passing"] == 1 and row["all_seeds_pass"] is True


def _run(monkeypatch, capsys, argv):
    code, out, err = cli_run(monkeypatch, capsys, *argv)
    return code, out + err


@pytest.fixture
def fake_run(tmp_path):
    """A training run folder with two seeds (the shipped teacher and fast policies: one network size)."""
    run = tmp_path / "run"
    (run / "policy").mkdir(parents=True)
    (run / "config.json").write_text("{}\n")
    shutil.copy(REPO / "harv_jax/policies/teacher.npz", run / "policy/policy_seed0.npz")
    shutil.copy(REPO / "harv_jax/policies/fast.npz", run / "policy/policy_seed1.npz")
    return run


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["{tmp}/nothing"], "is not a folder"),
        (["{tmp}"], "is not a training run (no config.json)"),
        (["{run}", "--conditions", "clean,windy"], "unknown condition 'windy'"),
        (["{run}", "--runs", "0"], "--runs 0"),
        (["{run}", "--duration", "5"], "--duration"),
        (["{run}", "--resume"], "holds no evaluation to continue"),
        (["{run}", "--resume", "--force"], "give one of them"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(fake_run, tmp_path, args, message, monkeypatch, capsys):
    out = tmp_path / "ev"
    argv = ["evaluate", *(a.format(tmp=tmp_path, run=fake_run) for a in args), "--out", str(out)]
    code, text = _run(monkeypatch, capsys, argv)
    assert code == 2 and message in text and len(text.strip().splitlines()) == 1, text
    assert not out.exists()


def test_a_run_without_policies_is_refused(fake_run, tmp_path, monkeypatch, capsys):
    for p in (fake_run / "policy").iterdir():
        p.unlink()
    code, text = _run(monkeypatch, capsys, ["evaluate", str(fake_run), "--out", str(tmp_path / "ev")])
    assert code == 2 and "has no policies" in text


@pytest.mark.slow  # ~2 min on the 2-core CPU: four rollouts compiled, two reference controllers
def test_evaluate_flies_the_monte_carlos_runs_and_resumes(fake_run, tmp_path, monkeypatch, capsys):
    """The policy's rollout with traced parameters, behind the measurement path the policies carry, gives
    the Monte Carlo's per-run results (``harv-jax mc`` on the same seed), the seeds share one compile, and
    ``--resume`` reuses every stored cell."""
    from harv_jax.evaluation.seeds.conditions import cell_path

    for f in (fake_run / "policy").iterdir():  # both seeds trained behind the 0.3 Hz observer
        with np.load(f, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        meta = json.loads(str(arrays["meta"]))
        arrays["meta"] = np.asarray(
            json.dumps({**meta, "measurement_path": {"kind": "obs", "bandwidth_hz": 0.3}})
        )
        np.savez(f, **arrays)

    out = tmp_path / "ev"
    argv = [
        "evaluate",
        str(fake_run),
        "--runs",
        "6",
        "--duration",
        "30",
        "--conditions",
        "clean",
        "--out",
        str(out),
    ]
    code, text = _run(monkeypatch, capsys, argv)
    assert code == 0, text
    doc = json.loads((out / "evaluate.json").read_text())
    assert [r["seed"] for r in doc["seeds"]] == [0, 1] and doc["cells_flown"] == 6
    assert (out / "evaluate.md").is_file() and (out / "evaluate.png").is_file()
    mc = tmp_path / "mc"
    code, text = _run(monkeypatch, capsys,
        ["mc", "--controller", "rl", "--policy", str(fake_run / "policy/policy_seed1.npz"), "--runs", "6",
         "--duration", "30", "--seed", "0", "--out", str(mc)]
    )  # fmt: skip
    assert code == 0, text
    rows = [line.split(",") for line in (mc / "runs.csv").read_text().splitlines()]
    head = rows[0]
    rec_mc = np.array([r[head.index("recovered")] == "True" for r in rows[1:]])
    t_mc = np.array([float(r[head.index("t_recover_s")]) for r in rows[1:]])
    with np.load(cell_path(out, "clean", "rl_seed1")) as z:
        rec, t = z["recovered"], z["t_recover_s"]
    np.testing.assert_array_equal(rec, rec_mc)
    np.testing.assert_allclose(t[rec], t_mc[rec_mc], atol=0.011)
    code, text = _run(monkeypatch, capsys, [*argv[:-2], "--out", str(out), "--resume"])
    assert code == 0, text
    again = json.loads((out / "evaluate.json").read_text())
    assert again["cells_flown"] == 0 and again["cells_reused"] == 6
    assert again["seeds"] == doc["seeds"]
    code, text = _run(monkeypatch, capsys, [*argv[:-2], "--runs", "7", "--out", str(out), "--resume"])
    assert code == 2 and "runs differ" in text


def test_an_interrupted_evaluation_names_resume(fake_run, tmp_path, monkeypatch, capsys):
    from harv_jax import atomic, manifest

    out = tmp_path / "ev"
    out.mkdir()
    atomic.write_text(out / manifest.MARKER, "written by harv-jax\n")
    manifest.start(out, f"harv-jax evaluate {fake_run} --out {out}")
    manifest.set_status(out, manifest.INTERRUPTED)
    code, text = _run(monkeypatch, capsys, ["evaluate", str(fake_run), "--out", str(out)])
    assert code == 2 and "interrupted" in text and "--resume" in text and len(text.strip().splitlines()) == 1


def test_a_run_record_naming_an_unknown_aircraft_is_refused(fake_run, tmp_path, monkeypatch, capsys):
    (fake_run / "config.json").write_text(json.dumps({"env": {"aircraft": "zeppelin"}}))
    code, text = _run(monkeypatch, capsys, ["evaluate", str(fake_run), "--out", str(tmp_path / "ev")])
    assert code == 2 and "unknown aircraft 'zeppelin'" in text and len(text.strip().splitlines()) == 1
    assert not (tmp_path / "ev").exists()
