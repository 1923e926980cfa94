"""experiments/results_bundle.py: a study's JSON results packed into one file and written back out."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

_SPEC = importlib.util.spec_from_file_location(
    "results_bundle", Path(__file__).resolve().parents[1] / "experiments" / "results_bundle.py"
)
results_bundle = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(results_bundle)


def _write(path: Path, doc: object) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=2) + "\n")


def test_pack_then_unpack_gives_the_files_back(tmp_path):
    src = tmp_path / "results"
    docs = {"mc_a.json": {"x": 1.5, "y": [1, 2]}, "seed7/mc_b.json": {"z": None}, "keep.json": {"k": 0}}
    for key, doc in docs.items():
        _write(src / key, doc)
    bundle = src / "summaries.json"
    packed = results_bundle.pack(src, bundle, "*mc_*.json", "what it holds")
    assert sorted(packed) == ["mc_a.json", "seed7/mc_b.json"]
    assert not (src / "mc_a.json").exists() and not (src / "seed7").exists()  # moved, empty folder gone
    assert (src / "keep.json").exists()  # not matched: left alone
    assert results_bundle.select(bundle, "seed7/*") == {"seed7/mc_b.json": {"z": None}}
    assert json.loads(bundle.read_text())["about"] == "what it holds"
    out = tmp_path / "out"
    results_bundle.unpack(bundle, out)
    for key in packed:
        assert (out / key).read_text() == json.dumps(docs[key], indent=2) + "\n"


def test_add_replaces_an_entry_and_keeps_the_about(tmp_path):
    bundle = tmp_path / "b.json"
    results_bundle.add(bundle, "k.json", {"v": 1}, about="first")
    results_bundle.add(bundle, "k.json", {"v": 2})
    assert results_bundle.load(bundle) == {"k.json": {"v": 2}}
    assert json.loads(bundle.read_text())["about"] == "first"


def test_refusals_write_nothing(tmp_path):
    src = tmp_path / "results"
    _write(src / "a.json", {"v": 1})
    bundle = tmp_path / "b.json"
    results_bundle.add(bundle, "a.json", {"v": 0})
    with pytest.raises(SystemExit, match="already holds a.json"):
        results_bundle.pack(src, bundle, "*", None)
    assert (src / "a.json").exists() and results_bundle.load(bundle) == {"a.json": {"v": 0}}
    out = tmp_path / "out"
    _write(out / "a.json", {"mine": True})
    with pytest.raises(SystemExit, match="exists"):
        results_bundle.unpack(bundle, out)
    assert json.loads((out / "a.json").read_text()) == {"mine": True}
    (tmp_path / "not_a_bundle.json").write_text("[1, 2]")
    with pytest.raises(ValueError, match="not a results bundle"):
        results_bundle.load(tmp_path / "not_a_bundle.json")
