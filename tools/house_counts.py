"""Counts of the house: what the package holds and how its code is arranged.

Run from the repository root (``python tools/house_counts.py [--out FILE]``); it reads the source only
(no jax import, nothing is run). The counts:

- preset keys: every key a preset may set (``[ppo]`` fields, ``[env]`` settings and wrapper keys,
  ``[reward]``, ``[randomization]``, ``[spin]``, ``[eval]``) and those that no shipped preset sets;
- ``make_train``'s feature switches (local booleans named ``use_*`` and the ``demo`` argument) and length;
  ``ppo_loss``'s parameters;
- modules and lines of ``harv_jax/``; files and MB of ``experiments/`` (its committed files); the longest
  study README;
- import loops (strongly connected components of the module import graph, imports inside functions
  included), re-exports (names imported from another ``harv_jax`` module and listed in ``__all__`` or marked
  ``noqa: F401``) and the imports elsewhere that go through them; imports inside functions.
"""

from __future__ import annotations

import argparse
import ast
import json
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "harv_jax"


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def package_modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PKG.rglob("*.py"))}


def _dataclass_fields(tree: ast.Module, cls: str) -> list[str]:
    for node in tree.body:
        if isinstance(node, ast.ClassDef) and node.name == cls:
            return [
                s.target.id
                for s in node.body
                if isinstance(s, ast.AnnAssign)
                and isinstance(s.target, ast.Name)
                and not s.target.id.startswith("_")
            ]
    return []


def _dict_keys(tree: ast.Module, name: str) -> list[str]:
    for node in ast.walk(tree):
        target = None
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            target, value = node.target.id, node.value
        elif (
            isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
        ):
            target, value = node.targets[0].id, node.value
        if target == name and isinstance(value, ast.Dict):
            return [k.value for k in value.keys if isinstance(k, ast.Constant)]
    return []


def _parse(rel: str) -> ast.Module:
    return ast.parse((ROOT / rel).read_text())


def preset_keys() -> dict[str, list[str]]:
    """Every key a preset may set, by table (read from the source of the package)."""
    keys: dict[str, list[str]] = {}
    keys["ppo"] = _dataclass_fields(_parse("harv_jax/ppo/config.py"), "PPOConfig")
    settings = _parse("harv_jax/env/settings.py")
    env = _dict_keys(settings, "ENV_RANGES")
    wrappers = ["loop", "teacher"]
    for key, rel in (
        ("teacher_model", "harv_jax/training/teacher.py"),
        ("measurement_path", "harv_jax/training/measured_env.py"),
        ("critic", "harv_jax/training/measured_env.py"),
    ):
        source = ROOT / rel
        if source.exists() and f'"{key}"' in source.read_text():
            wrappers.append(key)
    ttg = ROOT / "harv_jax/training/time_to_go.py"
    if ttg.exists():
        for node in ast.walk(ast.parse(ttg.read_text())):
            if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "KEYS":
                wrappers += [e.value for e in node.value.elts if isinstance(e, ast.Constant)]
    keys["env"] = env + wrappers
    keys["reward"] = _dataclass_fields(_parse("harv_jax/env/reward_params.py"), "RewardParams")
    config = _parse("harv_jax/env/config.py")
    aircraft = _dataclass_fields(_parse("harv_jax/aircraft/randomize.py"), "AircraftRandomization")
    # added_max holds the keys of the disturbances a table row adds (none in the shipped table), not a key
    rand = [k for k in _dataclass_fields(config, "RandomizationParams") if k != "added_max"]
    keys["randomization"] = aircraft + rand
    keys["spin"] = _dataclass_fields(settings, "SpinSettings")
    keys["eval"] = _dataclass_fields(settings, "EvalSettings")
    return keys


def _toml_keys(path: Path) -> set[tuple[str, str]]:
    data = tomllib.loads(path.read_text())
    out: set[tuple[str, str]] = set()
    base = data.get("base")
    if isinstance(base, str) and (path.parent / base).is_file():
        out |= _toml_keys(path.parent / base)
    for table, values in data.items():
        if isinstance(values, dict):
            out |= {(table, k) for k in values}
    return out


def preset_counts() -> dict[str, object]:
    keys = preset_keys()
    shipped: set[tuple[str, str]] = set()
    for f in sorted((PKG / "training" / "presets").glob("*.toml")):
        shipped |= _toml_keys(f)
    experiment: set[tuple[str, str]] = set()
    for f in sorted((ROOT / "experiments").rglob("*.toml")):
        try:
            experiment |= _toml_keys(f)
        except (tomllib.TOMLDecodeError, OSError):
            continue
    every = [(t, k) for t, ks in keys.items() for k in ks]
    unused = [f"{t}.{k}" for t, k in every if (t, k) not in shipped]
    only_experiments = [f"{t}.{k}" for t, k in every if (t, k) not in shipped and (t, k) in experiment]
    return {
        "preset_keys": len(every),
        "preset_keys_by_table": {t: len(ks) for t, ks in keys.items()},
        "preset_keys_not_in_shipped_presets": len(unused),
        "preset_keys_only_in_experiment_tomls": len(only_experiments),
        "preset_keys_unused_listing": unused,
    }


def _function(tree: ast.Module, name: str) -> ast.FunctionDef | None:
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef) and node.name == name:
            return node
    return None


def trainer_counts() -> dict[str, object]:
    tree = _parse("harv_jax/ppo/train.py")
    make_train = _function(tree, "make_train")
    switches: set[str] = set()
    if make_train is not None:
        for node in ast.walk(make_train):
            if isinstance(node, ast.Assign):
                for t in node.targets:
                    if isinstance(t, ast.Name) and t.id.startswith("use_"):
                        switches.add(t.id)
        if "demos" in [a.arg for a in make_train.args.args]:
            switches.add("demos (argument)")
    loss_file = ROOT / "harv_jax/ppo/losses.py"
    loss = _function(ast.parse(loss_file.read_text()), "ppo_loss")
    n_loss = 0 if loss is None else len(loss.args.args) + len(loss.args.kwonlyargs)
    return {
        "make_train_feature_switches": sorted(switches),
        "make_train_feature_switch_count": len(switches),
        "make_train_lines": 0 if make_train is None else make_train.end_lineno - make_train.lineno + 1,
        "ppo_loss_parameters": n_loss,
    }


def _imports(tree: ast.Module, mod: str, is_pkg: bool) -> list[tuple[str, list[str], bool, int]]:
    """(imported module, names, inside a function, line) of every harv_jax import."""
    out = []
    top_level = set(map(id, tree.body))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = mod.split(".")
                base = base if is_pkg else base[:-1]
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            names = [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            target, names = node.names[0].name, []
        else:
            continue
        if target.split(".")[0] != "harv_jax":
            continue
        out.append((target, names, id(node) not in top_level, node.lineno))
    return out


def _inside_function_imports(tree: ast.Module) -> int:
    count = 0

    def visit(node: ast.AST, in_function: bool) -> None:
        nonlocal count
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import | ast.ImportFrom) and in_function:
                count += 1
            visit(child, in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef))

    visit(tree, False)
    return count


def _sccs(graph: dict[str, set[str]]) -> list[list[str]]:
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    sys.setrecursionlimit(10000)

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return out


def code_counts() -> dict[str, object]:
    modules = package_modules()
    trees = {m: ast.parse(p.read_text()) for m, p in modules.items()}
    lines = sum(len(p.read_text().splitlines()) for p in modules.values())
    graph: dict[str, set[str]] = {m: set() for m in modules}
    reexported: dict[str, set[str]] = {}
    inside = 0
    for m, tree in trees.items():
        is_pkg = modules[m].name == "__init__.py"
        inside += _inside_function_imports(tree)
        all_names: set[str] = set()
        for node in tree.body:
            if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "__all__":
                all_names = {e.value for e in getattr(node.value, "elts", []) if isinstance(e, ast.Constant)}
        src = modules[m].read_text().splitlines()
        for target, names, _, line in _imports(tree, m, is_pkg):
            dep = target
            while dep not in modules and "." in dep:
                dep = dep.rsplit(".", 1)[0]
            if dep in modules and dep != m and not (is_pkg and dep.startswith(m + ".")):
                graph[m].add(dep)
            if is_pkg:
                continue  # a package's __init__ exposing its modules is not a re-export of an old path
            for n in names:
                if n in all_names or "noqa: F401" in src[line - 1]:
                    reexported.setdefault(m, set()).add(n)
    through = 0
    for m, tree in trees.items():
        for target, names, _, _ in _imports(tree, m, modules[m].name == "__init__.py"):
            if target in reexported and set(names) & reexported[target]:
                through += 1
    loops = _sccs(graph)
    return {
        "modules": len(modules),
        "lines": lines,
        "largest_modules": sorted(
            ((len(p.read_text().splitlines()), m) for m, p in modules.items()), reverse=True
        )[:5],
        "import_loops": len(loops),
        "import_loop_members": loops,
        "reexporting_modules": len(reexported),
        "reexported_names": sum(len(v) for v in reexported.values()),
        "imports_through_reexports": through,
        "imports_inside_functions": inside,
    }


def experiment_counts() -> dict[str, object]:
    exp = ROOT / "experiments"
    listed = subprocess.run(
        ["git", "ls-files", "experiments"], cwd=ROOT, capture_output=True, text=True, check=False
    ).stdout.split()
    # the committed files (as a clean clone has them); the folder's files where git is not at hand
    files = [ROOT / f for f in listed] if listed else [p for p in exp.rglob("*") if p.is_file()]
    files = [p for p in files if p.is_file()]
    readmes = sorted(
        ((len(p.read_text().splitlines()), str(p.relative_to(ROOT))) for p in files if p.name == "README.md"),
        reverse=True,
    )
    return {
        "experiment_files": len(files),
        "experiment_mb": round(sum(p.stat().st_size for p in files) / 1e6, 2),
        "largest_study_readme": readmes[0] if readmes else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="write the counts as JSON here")
    args = parser.parse_args()

    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True).stdout.strip()

    head = {
        "head": git("rev-parse", "--short", "HEAD"),
        "uncommitted_changes": bool(git("status", "--short")),
    }
    counts = {**head, **preset_counts(), **trainer_counts(), **code_counts(), **experiment_counts()}
    text = json.dumps(counts, indent=1)
    if args.out:
        args.out.write_text(text + "\n")
    short = {k: v for k, v in counts.items() if not k.endswith(("_listing", "_members"))}
    print(json.dumps(short, indent=1))


if __name__ == "__main__":
    main()
