"""The package's shape: import directions, module sizes, package docstrings, each paper constant once.

These tests read the source (``ast``), they import nothing of the package, so they run in milliseconds.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "harv_jax"
MAX_MODULE_LINES = 400


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """Absolute names of every module a file imports (relative imports resolved; any nesting level)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = _module_name(path) if path.name == "__init__.py" else _module_name(path).rpartition(".")[0]
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            names.add(mod)
            names.update(f"{mod}.{alias.name}" for alias in node.names)  # `from harv_jax import env`
    return names


MODULES = sorted(PKG.rglob("*.py"))
GRAPH = {_module_name(p): _imports(p) for p in MODULES}


def _under(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def _violations(src_pkg: str, forbidden: tuple[str, ...]) -> list[str]:
    return sorted(
        f"{mod} imports {dep}"
        for mod, deps in GRAPH.items()
        if _under(mod, src_pkg)
        for dep in deps
        if any(_under(dep, f) for f in forbidden)
    )


def test_the_scan_sees_the_package() -> None:
    """Guard against a vacuous pass: the graph holds known edges."""
    assert len(GRAPH) > 40
    assert any(_under(d, "harv_jax.dynamics") for d in GRAPH["harv_jax.env.recovery"])
    assert any(_under(d, "harv_jax.task") for d in GRAPH["harv_jax.control.hybrid.law"])


@pytest.mark.parametrize(
    ("package", "forbidden"),
    [
        ("harv_jax.control", ("harv_jax.env", "harv_jax.evaluation", "harv_jax.ppo")),
        ("harv_jax.evaluation", ("harv_jax.env", "harv_jax.ppo")),
        ("harv_jax.env", ("harv_jax.control", "harv_jax.evaluation", "harv_jax.ppo")),
        ("harv_jax.task", ("harv_jax.env", "harv_jax.control", "harv_jax.evaluation", "harv_jax.ppo")),
        ("harv_jax.dynamics", ("harv_jax.task", "harv_jax.env", "harv_jax.control", "harv_jax.evaluation")),
        ("harv_jax.aircraft", ("harv_jax.dynamics", "harv_jax.task", "harv_jax.env", "harv_jax.control")),
    ],
)
def test_layers_import_downward(package: str, forbidden: tuple[str, ...]) -> None:
    assert _violations(package, forbidden) == []


#: The layers, top to bottom (README "Layout"): a module imports only from its own layer or below.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("harv_jax.cli", "harv_jax.commands"),
    ("harv_jax.cli_options", "harv_jax.study_options", "harv_jax.state_file"),
    ("harv_jax.report",),
    ("harv_jax.training",),
    ("harv_jax.evaluation", "harv_jax.optimal"),
    ("harv_jax.plots",),
    ("harv_jax.env", "harv_jax.control"),
    ("harv_jax.policy", "harv_jax.policy_stablehlo", "harv_jax.policies"),
    ("harv_jax.ppo",),
    ("harv_jax.task",),
    ("harv_jax.dynamics",),
    ("harv_jax.aircraft",),
    (
        "harv_jax.units",
        "harv_jax.errors",
        "harv_jax.machine",
        "harv_jax.guards",
        "harv_jax.numfmt",
        "harv_jax.outdir",
        "harv_jax.runlock",
        "harv_jax.smooth",
        "harv_jax",
    ),
)


def _layer(module: str) -> int:
    """Index in LAYERS of the longest prefix that names ``module``'s package."""
    hits = [(len(p), i) for i, names in enumerate(LAYERS) for p in names if _under(module, p)]
    assert hits, f"{module} is in no layer: add it to LAYERS (and to the README's Layout)"
    return max(hits)[1]


def test_no_import_goes_up_the_layers() -> None:
    bad = sorted(
        f"{mod} imports {dep}"
        for mod, deps in GRAPH.items()
        for dep in deps
        if _under(dep, "harv_jax") and _layer(dep) < _layer(mod)
    )
    assert bad == []


HARV_SPECIFIC = (
    "harv_jax.aircraft", "harv_jax.dynamics", "harv_jax.task", "harv_jax.env", "harv_jax.control",
    "harv_jax.evaluation", "harv_jax.units", "harv_jax.training", "harv_jax.policies",
)  # fmt: skip


def test_trainer_is_generic() -> None:
    """``harv_jax.ppo`` knows nothing of the aircraft or the task: metrics come in as a function."""
    assert _violations("harv_jax.ppo", HARV_SPECIFIC) == []


def test_library_never_imports_commands_or_experiments() -> None:
    bad = sorted(
        f"{mod} imports {dep}"
        for mod, deps in GRAPH.items()
        if not _under(mod, "harv_jax.commands") and mod != "harv_jax.cli"
        for dep in deps
        if _under(dep, "harv_jax.commands") or _under(dep, "experiments")
    )
    assert bad == []


def test_commands_do_not_import_each_other() -> None:
    commands = {m for m in GRAPH if _under(m, "harv_jax.commands") and m != "harv_jax.commands"}
    bad = sorted(f"{m} imports {d}" for m in commands for d in GRAPH[m] if d in commands)
    assert commands and bad == []


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PKG)))
def test_module_size(path: Path) -> None:
    n = len(path.read_text().splitlines())
    assert n <= MAX_MODULE_LINES, f"{path.relative_to(PKG)} has {n} lines (max {MAX_MODULE_LINES})"


@pytest.mark.parametrize(
    "init", sorted(PKG.rglob("__init__.py")), ids=lambda p: str(p.parent.relative_to(PKG))
)
def test_package_docstring(init: Path) -> None:
    doc = ast.get_docstring(ast.parse(init.read_text()))
    assert doc and len(doc) > 40, f"{init.relative_to(PKG)} needs a docstring saying what the package owns"


# Each paper constant, as it could be written in code, and its one home.
SPEC = "task/spec.py"
CONSTANTS = {
    "alpha envelope low (-0.244 rad)": (r"(?<![\d.])0\.244(?!\d)", SPEC),
    "alpha envelope high (1.571 rad)": (r"(?<![\d.])1\.571(?!\d)", SPEC),
    "initial altitude (25,000 ft)": (r"(?<![\d.])25_?000(\.0*)?(?![\d_])", SPEC),
    "target alpha (0.349 rad)": (r"(?<![\d.])0\.349(?!\d)", SPEC),
    "gamma envelope (1.745 rad)": (r"(?<![\d.])1\.745(?!\d)", SPEC),
    "reset bound of V (1500 ft/s)": (r"(?<![\d.])1_?500\.0(?!\d)", SPEC),
    "alpha_d bounds (-0.085, 0.68)": (r"(?<![\d.])(0\.085|0\.68)(?!\d)", SPEC),
}


def _code_lines(path: Path) -> list[tuple[int, str]]:
    """Lines of code with comments and docstrings removed (prose may quote the paper's numbers)."""
    src = path.read_text()
    tree = ast.parse(src)
    doc_lines: set[int] = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr):
            v = body[0].value
            if isinstance(v, ast.Constant) and isinstance(v.value, str):
                doc_lines.update(range(v.lineno, v.end_lineno + 1))
    out = []
    for i, line in enumerate(src.splitlines(), 1):
        if i in doc_lines:
            continue
        code = line.split("#", 1)[0]
        code = re.sub(r"(help|description)=\"[^\"]*\"", "", code)
        out.append((i, code))
    return out


def _code_hits(rx: re.Pattern[str], home: str) -> list[str]:
    """``file:line: code`` of every code line outside ``home`` that ``rx`` matches."""
    return [
        f"{p.relative_to(PKG)}:{i}: {code.strip()}"
        for p in MODULES
        if str(p.relative_to(PKG)) != home
        for i, code in _code_lines(p)
        if rx.search(code)
    ]


@pytest.mark.parametrize("name", sorted(CONSTANTS))
def test_paper_constant_defined_once(name: str) -> None:
    pattern, home = CONSTANTS[name]
    rx = re.compile(pattern)
    assert _code_hits(rx, home) == [], f"{name} written outside {home}"
    assert any(rx.search(code) for _, code in _code_lines(PKG / home)), f"{name} missing from {home}"


def test_dt_literal_only_in_spec() -> None:
    """``0.01`` as a step size (``dt``/``DT`` on the line) lives in task/spec.py only."""
    rx = re.compile(r"dt\w*\s*[:=].*(?<![\d.])0\.01(?!\d)", re.IGNORECASE)
    assert _code_hits(rx, SPEC) == []
