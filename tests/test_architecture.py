"""Architecture rules of the core: contin/ never imports problems/, and its modules import
each other without a circle (checked on every import statement, function-level ones too, so a
circle cannot be hidden by moving an import into a function body)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "contin"


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(ROOT.rglob("*.py")):
        parts = path.relative_to(ROOT.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _imports(path: Path, name: str) -> set[str]:
    """Every module named by an import statement anywhere in the file (relative ones resolved),
    function bodies included; only ``if TYPE_CHECKING:`` blocks are left out."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):  # `if TYPE_CHECKING:` imports are for annotations only, never run
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", "")) == "TYPE_CHECKING":
            node.body = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            found.add(base)
            found.update(f"{base}.{a.name}" for a in node.names)  # `from contin import io` names a module
    return found


MODULES = _modules()


@pytest.mark.parametrize("name", sorted(MODULES))
def test_no_module_of_contin_imports_problems(name):
    bad = sorted(m for m in _imports(MODULES[name], name) if m == "problems" or m.startswith("problems."))
    assert not bad, f"{name} imports {bad}: contin/ knows no concrete problem"


def _graph() -> dict[str, set[str]]:
    """Module -> the contin modules it imports (the package itself, 'contin', left out: its
    __init__ only re-exports, and `from contin import __version__` is not a dependency circle)."""
    return {name: {m for m in _imports(path, name) if m in MODULES and m not in (name, "contin")}
            for name, path in MODULES.items() if name != "contin"}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(v: str) -> list[str] | None:
        state[v] = 1
        stack.append(v)
        for w in sorted(graph.get(v, ())):
            if state.get(w) == 1:
                return stack[stack.index(w):] + [w]
            if w not in state and (c := visit(w)):
                return c
        stack.pop()
        state[v] = 2
        return None

    for v in sorted(graph):
        if v not in state and (c := visit(v)):
            return c
    return None


def test_cycle_finder_finds_a_circle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None


def test_no_import_circle_in_contin():
    graph = {k: v for k, v in _graph().items() if not k.startswith("contin.cli")}
    assert "contin.switching" in graph["contin.continuation"]  # the tracer uses the switching module
    assert "contin.continuation" not in graph["contin.switching"]
    cycle = _cycle(graph)
    assert cycle is None, " -> ".join(cycle)


@pytest.mark.parametrize("name", ["contin.continuation", "contin.switching", "contin.foldcurve"])
def test_each_module_imports_alone(name):
    r = subprocess.run([sys.executable, "-c", f"import {name}"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
