"""`harv-jax report`: Markdown and standalone HTML of synthetic mc / compare / envelope / quickstart dirs."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import numpy as np
import pytest
from cli_util import cli_run

from harv_jax.report import markdown_to_html

MC_COMMAND = "harv-jax mc --controller smc,hybrid --runs 1000 --seed 7 --out runs/mc"


def _png(path: Path, value: float) -> bytes:
    """A tiny real PNG (4 x 4 grey) written to ``path``; returns its bytes."""
    import matplotlib.pyplot as plt

    plt.imsave(path, np.full((4, 4), value), cmap="gray", vmin=0.0, vmax=1.0)
    return path.read_bytes()


def _terminal(mean: float) -> dict:
    return {
        "mean": mean,
        "std": 0.5,
        "p5": -1.25,
        "p50": 0.125,
        "p95": 1.5,
        "within_0p5": 0.9,
        "within_2": 1.0,
    }


def _controller(rate: float, t_mean: float | None, compile_s: float, hybrid: dict | None) -> dict:
    t = None if t_mean is None else {"mean": t_mean, "p50": t_mean - 1.0, "p95": t_mean + 10.0}
    recovered = int(round(1000 * rate))
    return {
        "recovery_rate": rate,
        "recovery_time_s": t or {"mean": None, "p50": None, "p95": None},
        "terminal_error_deg": {"alpha": _terminal(0.25), "beta": _terminal(-0.5), "mu": _terminal(2.0)},
        "altitude_loss_ft": {"mean": 1673.2, "p95": 5927.6},
        "control_tv": {"mean": 7.5088, "unit": "rad"},
        "chatter_index": {"mean": 3.83e-06, "unit": "rad^2"},
        "saturation_fraction": 0.0734,
        "rate_saturation_fraction": 0.0199,
        "safety_interventions": 2.5,
        "safety_interventions_unit": "steps with an intervention per run",
        "hybrid": hybrid
        or {
            "zeta_active_fraction": None,
            "zeta_switches_per_run": None,
            "fallback_fraction": None,
            "fallbacks_per_run": None,
        },
        "outcomes": {"recovered": recovered, "departed": 1000 - recovered, "nonfinite": 0, "timeout": 0},
        "ground_hits_in_departed": 0,
        "left_envelope_fraction": 0.164,
        "wall_time_s": {"compile": compile_s, "run": 1.7354},
    }


def _summary() -> dict:
    return {
        "runs": 1000,
        "target_alpha_rad": 0.349,
        "duration_s": 60.0,
        "seed": 7,
        "randomize": False,
        "dt_s": 0.01,
        "policy": "shipped:full",
        "devices": ["cpu:0", "cpu:1"],
        "command": MC_COMMAND,
        "controllers": {
            "smc": _controller(0.998, 18.4569, 10.33, None),
            "hybrid": _controller(
                0.0,
                None,
                21.0,
                {
                    "zeta_active_fraction": 0.25,
                    "zeta_switches_per_run": 3.0,
                    "fallback_fraction": 0.0,
                    "fallbacks_per_run": 0.0,
                },
            ),  # fmt: skip
        },
    }


def make_mc_dir(d: Path) -> dict[str, bytes]:
    """An `mc` output dir: summary.json, bands_*.png, terminal_errors.png, runs.csv."""
    d.mkdir(parents=True, exist_ok=True)
    (d / "summary.json").write_text(json.dumps(_summary(), indent=2))
    pngs = {n: _png(d / n, v) for n, v in (("bands_smc.png", 0.1), ("bands_hybrid.png", 0.5),
                                            ("terminal_errors.png", 0.9))}  # fmt: skip
    (d / "runs.csv").write_text("controller,run\nsmc,0\n")
    return pngs


def _run(monkeypatch, capsys, *args):
    return cli_run(monkeypatch, capsys, "report", *args)


def _md_table_rows(md: str, header_start: str) -> dict[str, list[str]]:
    """Rows (first cell -> other cells) of the first Markdown table whose header starts so."""
    lines = md.splitlines()
    i = next(k for k, line in enumerate(lines) if line.startswith(header_start))
    rows = {}
    for line in lines[i + 2 :]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows[cells[0]] = cells[1:]
    return rows


def test_mc_report_tables_commands_and_embedded_figures(monkeypatch, capsys, tmp_path):
    run = tmp_path / "mc"
    pngs = make_mc_dir(run)
    code, out, err = _run(monkeypatch, capsys, run)
    assert code == 0, err
    md = (run / "report.md").read_text()
    page = (run / "report.html").read_text()

    # the exact command and seed that produced the run
    assert f"```\n{MC_COMMAND}\n```" in md and "seed: 7" in md
    assert MC_COMMAND in page

    rows = _md_table_rows(md, "| metric | smc | hybrid |")  # one column per controller
    assert rows["recovery rate"] == ["99.8%", "0.0%"]
    assert rows["recovery time mean [s]"] == ["18.46", "–"]  # nothing recovered -> no time
    assert rows["recovery time p95 [s]"] == ["28.46", "–"]
    assert rows["altitude loss mean [ft]"] == ["1,673", "1,673"]
    assert rows["chatter index mean [rad²]"] == ["3.83e-06", "3.83e-06"]
    assert rows["safety-filter interventions [steps with an intervention per run]"] == ["2.5", "2.5"]
    assert rows["ζ mean (over steps and channels)"] == ["–", "0.250"]
    term = _md_table_rows(md.split("Terminal tracking errors")[1], "| metric | smc | hybrid |")
    assert term["α mean"] == ["0.250", "0.250"] and term["μ mean"] == ["2.000", "2.000"]
    assert term["β p5 / p50 / p95"][0] == "-1.250 / 0.125 / 1.500"
    assert term["α within 0.5° / 2°"][0] == "90.0% / 100.0%"
    outcomes = _md_table_rows(md.split("Outcomes [runs]")[1], "| metric | smc | hybrid |")
    assert outcomes["recovered"] == ["998", "0"] and outcomes["departed"] == ["2", "1,000"]
    wall = _md_table_rows(md.split("Wall time")[1], "| metric | smc | hybrid |")
    assert wall["compile [s]"] == ["10.3", "21.0"] and wall["run [s]"] == ["1.74", "1.74"]

    # figures: linked in Markdown (known order: bands first), embedded in HTML byte for byte
    links = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert links == ["bands_hybrid.png", "bands_smc.png", "terminal_errors.png"]
    embedded = re.findall(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)" alt="([^"]+)"', page)
    assert {alt: base64.b64decode(b) for b, alt in embedded} == pngs
    assert "<table" in page and "<td>99.8%</td>" in page and 'src="bands' not in page  # standalone
    assert "runs.csv" in md


def test_compare_dir_report_to_other_out_dir(monkeypatch, capsys, tmp_path):
    run = tmp_path / "cmp"
    run.mkdir()
    table = (
        "| metric | rl | smc | hybrid |\n|---|---:|---:|---:|\n"
        "| recovery time [s] | 12.5 | 18.2 | 9.1 |\n| constraint violations \\| <max> | 3 | 0 | 0 |\n"
    )
    (run / "compare_metrics.md").write_text("# spin scenario\n\n" + table)
    (run / "compare_metrics.csv").write_text("metric,rl,smc,hybrid\n")
    png = _png(run / "compare_spin.png", 0.3)
    (run / "compare.json").write_text(json.dumps({"command": "harv-jax compare --seed 3", "seed": 3}))
    out = tmp_path / "rep"
    code, _, err = _run(monkeypatch, capsys, run, "--out", out)
    assert code == 0, err
    assert not (run / "report.md").exists()  # the run dir is left alone with --out
    md = (out / "report.md").read_text()
    page = (out / "report.html").read_text()
    assert "controller comparison" in md and table.strip() in md  # included as it is
    assert "harv-jax compare --seed 3" in md
    (link,) = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md)
    assert (out / link).resolve() == (run / "compare_spin.png").resolve()
    assert "<td>recovery time [s]</td><td>12.5</td>" in page
    assert "<td>constraint violations | &lt;max&gt;</td>" in page  # escaped pipe and HTML
    assert base64.b64encode(png).decode() in page
    # an older compare.json records no aircraft: the settings table says so
    assert _md_table_rows(md, "| setting | value |") == {"seed": ["3"], "aircraft": ["–"]}


def _robustness(aircraft: str | None) -> dict:
    """A robustness.json of one controller and one disturbance swept over two levels."""
    rows = [
        {"level": lv, "recovery_rate": r, "t_recover_mean_nr_at_run_s": 20.0, "control_tv_mean_rad": 7.0}
        for lv, r in ((0.5, 1.0), (1.0, 0.5))
    ]
    doc = {
        "runs": 64, "seed": 2, "duration_s": 60.0, "target_alpha_rad": 0.349, "margin_recovery": 0.9,
        "controllers": ["smc"], "command": "harv-jax robustness --runs 64 --seed 2",
        "disturbances": {"noise": {"option": "--noise-scale", "unit": "x", "levels": [0.5, 1.0],
                                   "controllers": {"smc": {"margin": 0.5, "rows": rows}}}},
    }  # fmt: skip
    return doc if aircraft is None else {**doc, "aircraft": aircraft}


def test_compare_and_robustness_sections_name_the_aircraft(monkeypatch, capsys, tmp_path):
    """compare.json and robustness.json record the aircraft: the report states it (older files: not)."""
    run = tmp_path / "study"
    cmp_dir, rob_dir, old_dir = run / "compare", run / "robustness", run / "robustness_old"
    for d in (cmp_dir, rob_dir, old_dir):
        d.mkdir(parents=True)
    table = "| metric | smc |\n|---|---:|\n| recovery time [s] | 18.2 |\n"
    (cmp_dir / "compare_metrics.md").write_text(table)
    cmp_doc = {
        "command": "harv-jax compare --aircraft harv-heavy", "controllers": ["smc", "hybrid"],
        "target_alpha_rad": 0.349, "duration_s": 60.0, "spin_s": 30.0, "seed": 0, "aircraft": "harv-heavy",
        "disturbances": {"active": []}, "rows": [],
    }  # fmt: skip
    (cmp_dir / "compare.json").write_text(json.dumps(cmp_doc))
    (rob_dir / "robustness.json").write_text(json.dumps(_robustness("harv-heavy")))
    (old_dir / "robustness.json").write_text(json.dumps(_robustness(None)))
    code, _, err = _run(monkeypatch, capsys, run)
    assert code == 0, err
    md = (run / "report.md").read_text()
    cmp_md = md.split("## compare: controller comparison")[1].split("\n## ")[0]
    assert _md_table_rows(cmp_md, "| setting | value |") == {
        "controllers": ["smc, hybrid"],
        "target alpha [rad]": ["0.349"],
        "duration [s]": ["60"],
        "spin before engagement [s]": ["30"],
        "seed": ["0"],
        "aircraft": ["harv-heavy"],
        "disturbances": ["none"],
    }
    assert "| recovery time [s] | 18.2 |" in cmp_md  # compare_metrics.md follows, as it is
    rob_md = md.split("## robustness: robustness margins")[1].split("\n## ")[0]
    assert "Aircraft harv-heavy; 64 runs per level, seed 2, 60 s;" in rob_md
    old_md = md.split("## robustness_old: robustness margins")[1].split("\n## ")[0]
    assert "\n64 runs per level, seed 2, 60 s;" in old_md and "ircraft" not in old_md


def test_quickstart_dir_with_subdirs_and_envelope(monkeypatch, capsys, tmp_path):
    qs = tmp_path / "quickstart"
    make_mc_dir(qs / "mc")
    spin = qs / "spin"
    spin.mkdir()
    _png(spin / "trajectory.png", 0.2)
    metrics = {"outcome": 0, "outcome_name": "RECOVERED", "recovered": True, "t_recover_s": 9.5,
               "overshoot_rad": [0.1, 0.0, 0.02]}  # fmt: skip
    meta = {"controller": "smc", "switching": "sat", "scenario": "spin", "seed": 0, "duration_s": 60.0,
            "dt_s": 0.01, "reference_rad": [0.349, 0.0, 0.0], "spin_s": 30.0}  # fmt: skip
    (spin / "metrics.json").write_text(json.dumps({**meta, "metrics": metrics}))
    env = qs / "envelope"
    env.mkdir()
    _png(env / "envelope_recovery.png", 0.4)
    env_doc = {
        "grid": {
            "x": {"name": "alpha0", "low": 0.0, "high": 1.0, "n": 100, "display_unit": "deg",
                  "display_scale": 57.29577951308232},
            "y": {"name": "r0", "low": -0.5, "high": 0.5, "n": 100, "display_unit": "deg/s",
                  "display_scale": 57.29577951308232},
            "fixed_state": {"V": 800.0, "h": 25000.0},
        },
        "runs_per_controller": 10000, "duration_s": 60.0, "seed": 5,
        "command": "harv-jax envelope --n 100 --seed 5",
        "controllers": {"smc": {"recovery_rate": 0.75,
                                "outcome_counts": {"RECOVERED": 7500, "TIMEOUT": 2500},
                                "wall_time_s": {"compile": 12.0, "run": 300.0}}},
    }  # fmt: skip
    (env / "envelope.json").write_text(json.dumps(env_doc))
    code, _, err = _run(monkeypatch, capsys, qs)
    assert code == 0, err
    md = (qs / "report.md").read_text()
    for heading in (
        "## envelope: recovery envelope map",
        "## mc: Monte Carlo",
        "## spin: closed-loop flight",
    ):
        assert heading in md
    prov = _md_table_rows(md, "| directory | command | seed |")
    assert prov["mc"] == [MC_COMMAND, "7"]
    assert prov["envelope"] == ["harv-jax envelope --n 100 --seed 5", "5"]
    assert prov["spin"][0].startswith("harv-jax fly --controller smc --scenario spin --target-alpha 0.349")
    assert prov["spin"][0].endswith("(reconstructed)")
    env_rows = _md_table_rows(md, "| metric | smc |")
    assert env_rows["recovery rate"] == ["75.0%"] and env_rows["outcome recovered"] == ["7,500"]
    assert env_rows["run [s]"] == ["300.00"]
    assert "| x: alpha0 | 0 .. 57.3 deg (100 points) |" in md
    assert "| outcome | RECOVERED |" in md and "| overshoot_rad | 0.1, 0, 0.02 |" in md
    assert "![trajectory.png](spin/trajectory.png)" in md
    assert (qs / "report.html").read_text().count("data:image/png;base64,") == 5


def test_existing_report_is_not_overwritten_without_force(monkeypatch, capsys, tmp_path):
    run = tmp_path / "mc"
    make_mc_dir(run)
    assert _run(monkeypatch, capsys, run)[0] == 0
    (run / "report.md").write_text("mine")
    code, _, err = _run(monkeypatch, capsys, run)
    assert code == 2 and "--force" in err and err.count("\n") == 1
    assert (run / "report.md").read_text() == "mine"
    assert _run(monkeypatch, capsys, run, "--force")[0] == 0
    assert (run / "report.md").read_text() != "mine"
    # a non-empty --out directory is refused too, and kept
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("x")
    code, _, err = _run(monkeypatch, capsys, run, "--out", other)
    assert code == 2 and "already exists and is not empty" in err
    assert (other / "keep.txt").exists()


@pytest.mark.parametrize(
    "setup, extra, needle",
    [
        (None, [], "is not a directory"),
        ("empty", [], "holds no summary.json"),
        ("mc", ["--out", "PARENT"], "contains RUN_DIR"),
    ],
)
def test_bad_input_one_line_errors(monkeypatch, capsys, tmp_path, setup, extra, needle):
    run = tmp_path / "run"
    if setup == "empty":
        run.mkdir()
        (run / "notes.txt").write_text("nothing to report")
    elif setup == "mc":
        make_mc_dir(run)
    args = [str(tmp_path) if a == "PARENT" else a for a in extra]
    code, _, err = _run(monkeypatch, capsys, run, *args, "--force")
    assert code == 2 and needle in err
    assert err.startswith("harv-jax: error:") and err.count("\n") == 1
    assert run.exists() or setup is None  # --force never deletes the run directory


def test_markdown_to_html_tables_headings_code():
    page = markdown_to_html(
        "## Title <x>\n\ntext & more\n\n| a | b |\n|---|---|\n| 1 | <2> |\n\n```\nx < y\n```"
    )
    assert "<h4>Title &lt;x&gt;</h4>" in page
    assert "<p>text &amp; more</p>" in page
    assert (
        "<table><thead><tr><th>a</th><th>b</th></tr></thead><tbody><tr><td>1</td><td>&lt;2&gt;</td></tr>"
        in page
    )
    assert "<pre><code>x &lt; y</code></pre>" in page


def test_build_report_api_in_place_and_nested_out(tmp_path):
    """The API ``harv-jax quickstart`` uses: ``build_report(run_dir, run_dir)`` writes into the run dir; a
    report dir inside the run dir is not reported on as part of the run."""
    from harv_jax.report import build_report

    run = tmp_path / "mc"
    make_mc_dir(run)
    md, page = build_report(run, run)
    assert (md, page) == (run / "report.md", run / "report.html")
    assert "This report: harv-jax report " in md.read_text()
    nested = run / "rep"
    build_report(run, nested)
    md2, _ = build_report(run, nested, force=True)  # rep/ exists now and must be skipped by the scan
    text = md2.read_text()
    assert "## rep" not in text and "](../bands_smc.png)" in text


def test_controllers_are_introduced_and_identical_flights_explained():
    from harv_jax.report.document import Doc, to_html, to_markdown
    from harv_jax.report.sections import controllers_section, identical_flights

    same = {"outcome": "RECOVERED", "recovery_time_s": 23.52, "control_tv_rad": 19.3}
    rows = [
        {"scenario": "spin", "controller": "smc", **same, "recovery_time_vs_smc": 1.0},
        {"scenario": "spin", "controller": "smc-brake", **same, "recovery_time_vs_smc": 1.0},
        {"scenario": "spin", "controller": "rl", **same, "control_tv_rad": 5.0},
        {"scenario": "fixed", "controller": "smc", **same},
        {"scenario": "fixed", "controller": "smc-brake", **same, "recovery_time_s": 20.0},
    ]
    lines = identical_flights(rows)
    assert lines == [
        "On spin, smc-brake flew exactly as smc (every metric equal): what they add to it (see Controllers "
        "above) did not engage on this flight."
    ]
    doc = Doc()
    controllers_section(doc, ["smc", "smc-brake-zoom", "rl+lp2", "mine"])
    md = to_markdown(doc, Path("."))
    assert "| smc-brake-zoom | smc-brake while" in md and "lp at 2 Hz" in md
    assert "| mine | a controller registered by the user |" in md
    page = to_html(doc, "t")
    assert '<div class="table"><table class="text">' in page and "overflow-wrap:anywhere" in page


def test_quickstart_like_report_introduces_every_controller_before_its_tables(tmp_path):
    """A run folder with a compare and a Monte Carlo: the Controllers table comes before any result."""
    from harv_jax.report.build import build_document, report_controllers
    from harv_jax.report.document import to_markdown
    from harv_jax.report.scan import scan

    run = tmp_path / "mc"
    make_mc_dir(run)
    sections = scan(run)
    assert report_controllers(sections) == ["smc", "hybrid"]
    md = to_markdown(build_document(run, sections, "harv-jax report mc"), run)
    intro = md.index("## Controllers")
    assert intro < md.index("| metric | smc | hybrid |")
    assert "| hybrid | policy + SMC feedback" in md
