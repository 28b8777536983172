"""No import cycles between modules: checked statically over every module of retarget, drivers and sim.

Every import counts, wherever it stands: at the top, inside a function, or under ``TYPE_CHECKING`` (a cycle
hidden there is still a cycle in the design).  A module importing its own package's ``__init__`` while that
``__init__`` imports it back is a cycle too: siblings import each other by their module path.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
PACKAGES = ("retarget", "drivers", "sim")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def all_modules() -> dict[str, Path]:
    return {module_name(p): p for package in PACKAGES for p in sorted((REPO / package).rglob("*.py"))}


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The project modules ``name`` imports, anywhere in its source; ``from a import b`` counts as ``a.b``
    when that is a module, else as ``a``."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base)
    return {m for m in found if m in modules and m != name}


def cycles(graph: dict[str, set[str]]) -> Iterator[list[str]]:
    """Strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()

    def visit(v: str) -> Iterator[list[str]]:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                yield from visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                yield sorted(component)

    for v in sorted(graph):
        if v not in index:
            yield from visit(v)


def import_graph() -> dict[str, set[str]]:
    modules = all_modules()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def test_no_module_takes_part_in_an_import_cycle():
    found = list(cycles(import_graph()))
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in found)


def test_the_graph_sees_every_layer():
    graph = import_graph()
    layers = {"retarget.bvh", "retarget.arm", "retarget.ik", "retarget.mapping", "retarget.control", "retarget.teleop"}
    assert layers | {"retarget.cli", "drivers.dynamixel_bus", "sim.bus"} <= set(graph)
    assert "retarget.arm.kinematics" in graph["retarget.arm.model"]  # a top-level import
    assert "retarget.arm.model" in graph["retarget.mapping.targets"]


@pytest.mark.parametrize(
    ("sources", "expected"),
    [
        ({"a": "import b\n", "b": "def f():\n    import a\n"}, [["a", "b"]]),
        ({"a": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import b\n", "b": "import a\n"}, [["a", "b"]]),
        ({"a": "import b\n", "b": "import c\n", "c": ""}, []),
    ],
    ids=["inside-a-function", "type-checking-only", "a-chain"],
)
def test_the_check_sees_a_cycle_however_it_is_hidden(tmp_path, sources, expected):
    modules = {}
    for name, text in sources.items():
        (tmp_path / f"{name}.py").write_text(text)
        modules[name] = tmp_path / f"{name}.py"
    graph = {name: imports_of(name, path, modules) for name, path in modules.items()}
    assert list(cycles(graph)) == expected
