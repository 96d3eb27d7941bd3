"""The package's layout: which way its imports run (docs/development.md, "Layout").

The runtime import graph is read from the sources with ``ast``: every ``import`` and ``from ...
import`` of a poekin module, at module level and inside functions, except under ``if
TYPE_CHECKING:``. Importing ``poekin.a.b`` from a module outside ``poekin.a`` runs
``poekin/a/__init__.py`` too, so that package is an edge as well; ``poekin/__init__.py`` (the
public names, run before any module) is not.
"""

from __future__ import annotations

import ast
import functools
import pathlib
import subprocess
import sys
from collections.abc import Collection

import pytest

import poekin

SRC = pathlib.Path(poekin.__file__).parent
MODEL = ("poekin.chain", "poekin.tree", "poekin.dh")  # the model classes
SOLVERS = "poekin.ik"


def _modules() -> dict[str, pathlib.Path]:
    out = {}
    for path in SRC.rglob("*.py"):
        parts = ["poekin", *path.relative_to(SRC).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(tree: ast.AST, package: str, modules: Collection[str]) -> list[tuple[str, bool]]:
    """``(name, at module level)`` of every import outside ``if TYPE_CHECKING:`` blocks; for
    ``from m import x``, ``m.x`` where that is a module, else ``m``."""
    found: list[tuple[str, bool]] = []

    def visit(node: ast.AST, top: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking(child):
                for other in child.orelse:
                    visit(other, top)
                continue
            if isinstance(child, ast.Import):
                found.extend((alias.name, top) for alias in child.names)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    parent = package.split(".")[: len(package.split(".")) - child.level + 1]
                    base = ".".join([*parent, base] if base else parent)
                for alias in child.names:
                    name = f"{base}.{alias.name}"
                    found.append((name if name in modules else base, top))
            inner = isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
            visit(child, top and not inner)

    visit(tree, True)
    return found


@functools.cache
def _read() -> tuple[dict[str, pathlib.Path], dict[str, list[tuple[str, bool]]]]:
    """The modules, and each one's imports (:func:`_imports`): read once, for every test."""
    modules = _modules()
    found = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        found[name] = _imports(ast.parse(path.read_text()), package, modules)
    return modules, found


def import_graph(*, module_level_only: bool = False) -> dict[str, set[str]]:
    """Each poekin module's runtime imports of poekin modules (see the module docstring)."""
    modules, imports = _read()
    graph: dict[str, set[str]] = {}
    for name in modules:
        edges: set[str] = set()
        for target, top in imports[name]:
            if target not in modules or (module_level_only and not top):
                continue
            parts = target.split(".")
            for k in range(2, len(parts) + 1):
                prefix = ".".join(parts[:k])
                if k == len(parts) or not (name == prefix or name.startswith(prefix + ".")):
                    edges.add(prefix)  # the module, and its packages the importer is not in
        edges.discard(name)
        graph[name] = edges
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    """One cycle of ``graph`` (its modules in order, the first repeated at the end), or []."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str]:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        state[node] = 2
        path.pop()
        return []

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return []


# docs/development.md's picture, bottom row first: a module imports from its own row and those
# below it only (prefixes of module names; the package's __init__, the public names, is none)
LAYERS = (
    (
        "poekin.errors",
        "poekin._extras",
        "poekin._blas",
        "poekin.arrays",
        "poekin._pose",
        "poekin.lie",
    ),
    ("poekin.kernel",),
    ("poekin._poe", "poekin._levels"),
    ("poekin.ik", "poekin.wholebody", "poekin.motion", "poekin.collision"),
    ("poekin.chain", "poekin.tree", "poekin.dh"),
    ("poekin.io",),
    ("poekin.verification",),
    ("poekin.calibration",),
    ("poekin.cli", "poekin.viewer", "poekin.__main__"),
)


def _row(module: str) -> int:
    rows = [
        k
        for k, row in enumerate(LAYERS)
        for prefix in row
        if module == prefix or module.startswith(prefix + ".")
    ]
    assert len(rows) == 1, f"{module} is in no row of LAYERS (or in several): add it"
    return rows[0]


def test_the_graph_sees_function_level_imports_and_skips_type_checking() -> None:
    """The reader itself: chain.ik's import of the solver is inside a method (seen at run
    time, not at module level); ik's import of Chain is for type checking only (not seen)."""
    graph, top = import_graph(), import_graph(module_level_only=True)
    assert "poekin.ik.numerical" in graph["poekin.chain"]
    assert "poekin.ik.numerical" not in top["poekin.chain"]
    assert "poekin.chain" not in graph["poekin.ik.analytic"]
    assert "poekin.kernel._fast" in top["poekin.chain"]
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]


def test_runtime_imports_have_no_cycle() -> None:
    """No circle anywhere: not the model and its solvers (chain, tree <-> ik), not a package's
    __init__ and its modules (calibration <-> calibration.plan), not the library and the CLI
    (calibration.files <-> cli)."""
    assert _cycle(import_graph()) == []


def test_solvers_do_not_import_the_model() -> None:
    """ik/ imports what it shares with the model from below it (poekin._poe), never the model
    classes (only for type checking)."""
    graph = import_graph()
    wrong = {
        (name, target)
        for name, targets in graph.items()
        if name.startswith(SOLVERS)
        for target in targets
        if target in MODEL
    }
    assert wrong == set()


@pytest.mark.parametrize("model", MODEL)
def test_the_model_imports_its_solvers_only_when_called(model: str) -> None:
    top = import_graph(module_level_only=True)[model]
    assert sorted(t for t in top if t == SOLVERS or t.startswith(SOLVERS + ".")) == []


def test_imports_run_down_the_layers() -> None:
    """Every runtime import goes to its own row of LAYERS or one below (chain.ik's import of
    the solver goes down: ik/ sits below the model it solves)."""
    up = sorted(
        (name, target)
        for name, targets in import_graph().items()
        if name != "poekin"
        for target in targets
        if _row(target) > _row(name)
    )
    assert up == []


@pytest.mark.parametrize("library", ["ik", "io", "verification", "calibration", "kernel"])
def test_the_library_does_not_import_the_cli_or_the_viewer(library: str) -> None:
    graph = import_graph()
    edges = {
        t
        for name, targets in graph.items()
        if name.startswith(f"poekin.{library}")
        for t in targets
        if t.startswith(("poekin.cli", "poekin.viewer"))
    }
    assert edges == set()


@pytest.mark.parametrize("module", ["poekin", "poekin.chain", "poekin.tree"])
def test_importing_the_model_loads_no_solver(module: str) -> None:
    """``import poekin.chain`` (which builds the UR5e's named parameter set on the way, in
    poekin.io.params) loads nothing of poekin.ik: a chain computes what its solvers need of it
    (poekin._poe.ChainTerms) without them."""
    code = (
        f"import sys, {module}\nprint(sorted(m for m in sys.modules if m.startswith('poekin.ik')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
