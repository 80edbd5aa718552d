"""The package's modules import each other without a circle (issue 21).

Reads every module's imports with ``ast`` (those inside functions too: a lazy import
that runs back up is still a circle) and fails naming the modules of any circle.
A package's ``__init__`` is an edge only where it is imported by name (``from . import
x``, ``import copdea_fem.sweep``), not merely as the parent of a submodule.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "copdea_fem"


def module_name(path: Path, root: Path = PACKAGE) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(root: Path = PACKAGE) -> dict[str, set[str]]:
    """module -> the package's modules it imports (anywhere in its body)."""
    paths = {module_name(path, root): path for path in root.rglob("*.py")}
    packages = {module_name(path, root) for path in root.rglob("__init__.py")}
    graph: dict[str, set[str]] = {}
    for name, path in paths.items():
        here = name if name in packages else name.rpartition(".")[0]
        edges = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here.rsplit(".", node.level - 1)[0] if node.level > 1 else here
                    base = f"{base}.{node.module}" if node.module else base
                else:
                    base = node.module or ""
                targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in paths else base
                           for alias in node.names]
            else:
                continue
            edges |= {target for target in targets if target in paths and target != name}
        graph[name] = edges
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(node):
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for other in sorted(graph.get(node, ())):
            if other not in index:
                visit(other)
                low[node] = min(low[node], low[other])
            elif other in on_stack:
                low[node] = min(low[node], index[other])
        if low[node] == index[node]:
            component = []
            while True:
                other = stack.pop()
                on_stack.discard(other)
                component.append(other)
                if other == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return found


def test_the_package_has_no_import_circle():
    graph = import_graph()
    assert len(graph) > 50 and "copdea_fem.axisymmetric.engine" in graph["copdea_fem.engines"]
    assert circles(graph) == []


def test_a_circle_is_found(tmp_path):
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "sub" / "__init__.py").write_text("")
    (package / "a.py").write_text("from .sub.b import thing\n")
    (package / "sub" / "b.py").write_text("def thing():\n    from ..a import other\n")
    (package / "c.py").write_text("from . import a\n")
    graph = import_graph(package)
    assert graph["pkg.c"] == {"pkg.a"}
    assert circles(graph) == [["pkg.a", "pkg.sub.b"]]


#: Where the engine's name may still be read (issue 21): where it is chosen, the study's
#: schema (which frames an engine allows), and the output sampling (output.py, api.py's
#: Solution: issue 25 moves it behind the engine interface).
ENGINE_NAME_ALLOWED = {"engines.py", "study.py", "output.py", "api.py"}


def engine_name_tests(root: Path = PACKAGE) -> list[str]:
    """``file:line`` of every comparison with the engine's name (``== "axisymmetric"``,
    ``engine_of(...)``) outside :data:`ENGINE_NAME_ALLOWED`."""
    found = []
    for path in sorted(root.rglob("*.py")):
        name = path.relative_to(root).as_posix()
        if name in ENGINE_NAME_ALLOWED:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call):
                hit = ast.unparse(node.func).rpartition(".")[2] == "engine_of"
            elif isinstance(node, ast.Compare):
                texts = [ast.unparse(part) for part in (node.left, *node.comparators)]
                hit = any(text in ("'axisymmetric'", "'3d'") for text in texts) and \
                    any("engine" in text for text in texts)
            else:
                continue
            if hit and f"{name}:{node.lineno}" not in found:
                found.append(f"{name}:{node.lineno}")
    return found


def test_no_engine_name_branch_outside_the_engine_interface():
    """The response, the sweeps, the resource guard and the diagnosis ask the engine
    (:class:`copdea_fem.engines.Engine`), they do not test its name."""
    assert engine_name_tests() == []


def test_an_engine_name_branch_is_found(tmp_path):
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "a.py").write_text('def f(p):\n    return 1 if p.engine == "axisymmetric" else 2\n')
    (package / "b.py").write_text("def g(s, m):\n    return engine_of(s), m.kind == '3d'\n")
    (package / "engines.py").write_text('def h(s):\n    return engine_of(s) == "3d"\n')
    assert engine_name_tests(package) == ["a.py:2", "b.py:2"]
