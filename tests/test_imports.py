"""The package's modules import each other without a circle (issue 21).

Reads every module's imports with ``ast`` (those inside functions too: a lazy import
that runs back up is still a circle) and fails naming the modules of any circle.
A package's ``__init__`` is an edge only where it is imported by name (``from . import
x``, ``import copdea_fem.sweeps``), not merely as the parent of a submodule.
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
    assert len(graph) > 50 and "copdea_fem.fe.axisymmetric.engine" in graph["copdea_fem.fe.engines"]
    assert circles(graph) == []


def planted_package(tmp_path, files: dict) -> Path:
    """A package ``pkg`` under ``tmp_path`` holding ``files`` (relative path -> source)."""
    package = tmp_path / "pkg"
    for name, source in files.items():
        path = package / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(source)
    return package


def test_a_circle_is_found(tmp_path):
    package = planted_package(tmp_path, {
        "__init__.py": "", "sub/__init__.py": "", "a.py": "from .sub.b import thing\n",
        "sub/b.py": "def thing():\n    from ..a import other\n", "c.py": "from . import a\n"})
    graph = import_graph(package)
    assert graph["pkg.c"] == {"pkg.a"}
    assert circles(graph) == [["pkg.a", "pkg.sub.b"]]


#: Where the engine's name may still be read (issue 21): where it is chosen, the study's
#: schema (which frames an engine allows) and api.py's ``Solution.axisymmetric`` (a public
#: property that reports it; no branch).
ENGINE_NAME_ALLOWED = {"engines.py", "study.py", "api.py"}


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
    (:class:`copdea_fem.fe.engines.Engine`), they do not test its name."""
    assert engine_name_tests() == []


def test_an_engine_name_branch_is_found(tmp_path):
    package = planted_package(tmp_path, {
        "a.py": 'def f(p):\n    return 1 if p.engine == "axisymmetric" else 2\n',
        "b.py": "def g(s, m):\n    return engine_of(s), m.kind == '3d'\n",
        "engines.py": 'def h(s):\n    return engine_of(s) == "3d"\n'})
    assert engine_name_tests(package) == ["a.py:2", "b.py:2"]


#: The package's layers, lowest first (issue 21): a module imports only modules of its own
#: layer or of a lower one (function-local imports included), so no import runs back up.
#: A name is a module or a package (all of its modules); the longest name that matches
#: places a module.  Pure physics and file plumbing at the bottom, the band solver and the
#: study above them, then prestress, linearisation, modes, the forced-response parts both
#: engines share, each engine's own pieces (its forced problem, its field sampling), the
#: engines, the interface that chooses one, and the orchestration on top: a solve's result
#: folder, the ``solve`` and ``response`` pipelines, sweeps, diagnosis, the API, the CLI.
LAYERS = (
    ("units", "materials", "symmetry", "airbox", "fingerprint", "folders", "inputs",
     "pipeline", "tracking", "acoustics", "assignment"),
    ("study", "membrane", "ale", "eigen", "paraview"),
    ("prestress", "geometry", "bands"),
    ("linearise", "reduced"),
    ("modes", "coupled"),
    ("forced",),
    ("axisymmetric", "quadrant"),
    ("engine3d",),
    ("engines",),
    ("output",),
    ("solve", "response"),
    ("damping_fit", "bench", "sweep"),
    ("diagnose",),
    ("api",),
    ("cli", ""),
)


def layer_of(module: str, layers=LAYERS, package: str = PACKAGE.name) -> int | None:
    """The index in ``layers`` of the longest name that matches ``module`` (``""``: the
    package's own ``__init__``), or None where none does."""
    relative = "" if module == package else module.removeprefix(package + ".")
    best, found = -1, None
    for index, names in enumerate(layers):
        for name in names:
            matches = relative == name if name == "" else \
                relative == name or relative.startswith(name + ".")
            if matches and len(name) > best:
                best, found = len(name), index
    return found


def back_up_imports(graph: dict[str, set[str]], layers=LAYERS,
                    package: str = PACKAGE.name) -> list[str]:
    """``A -> B`` of every import from a lower layer to a higher one, and ``A: no layer``
    of every module that no name of ``layers`` places."""
    found = [f"{module}: no layer" for module in sorted(graph)
             if layer_of(module, layers, package) is None]
    for module in sorted(graph):
        here = layer_of(module, layers, package)
        for target in sorted(graph[module]):
            there = layer_of(target, layers, package)
            if here is not None and there is not None and there > here:
                found.append(f"{module} -> {target}")
    return found


def rooms(graph: dict[str, set[str]], package: str = PACKAGE.name) -> dict[str, set[str]]:
    """The import graph with each folder of the package as one node (a module of a folder
    importing another folder's module is an edge between the two folders)."""
    def room(module):
        parts = module.split(".")
        if len(parts) > 2 or module in graph and any(other.startswith(module + ".")
                                                    for other in graph):
            return ".".join(parts[:2])
        return module

    collapsed: dict[str, set[str]] = {}
    for module, targets in graph.items():
        collapsed.setdefault(room(module), set()).update(
            room(target) for target in targets if room(target) != room(module))
    return collapsed


def test_no_import_runs_back_up_the_layers():
    graph = import_graph()
    assert "copdea_fem.fe.axisymmetric.forced" in graph["copdea_fem.fe.axisymmetric.engine"]
    assert back_up_imports(graph) == []


def test_no_circle_between_folders():
    """A folder counts as one room: a module of ``axisymmetric/`` importing ``forced/``
    while ``forced/`` imports ``axisymmetric/`` is a circle though no module is in one."""
    collapsed = rooms(import_graph())
    assert "copdea_fem.fe.forced" in collapsed["copdea_fem.fe.axisymmetric"]
    assert circles(collapsed) == []


def test_an_import_running_back_up_is_found(tmp_path):
    package = planted_package(tmp_path, {
        "__init__.py": "", "low/__init__.py": "",
        "low/a.py": "def f():\n    from .. import high\n", "low/b.py": "from . import a\n", "high.py": "from .low.a import f\n", "stray.py": ""})
    graph = import_graph(package)
    layers = (("low",), ("high", ""))
    assert back_up_imports(graph, layers, "pkg") == ["pkg.stray: no layer",
                                                     "pkg.low.a -> pkg.high"]
    assert back_up_imports(graph, (("low", "high", "stray", ""),), "pkg") == []


def test_a_circle_between_folders_is_found(tmp_path):
    package = planted_package(tmp_path, {
        "__init__.py": "", "sub/__init__.py": "", "a.py": "from .sub.b import thing\n",
        "sub/b.py": "thing = 1\n", "sub/c.py": "def g():\n    from ..a import thing\n"})
    graph = import_graph(package)
    assert circles(graph) == []
    collapsed = rooms(graph, "pkg")
    assert collapsed["pkg.a"] == {"pkg.sub"}
    assert circles(collapsed) == [["pkg.a", "pkg.sub"]]
