"""The package's import structure, and where the FE engine's name may be read.

The layers of the package and of its FE core, and the absence of import circles, are
import-linter contracts in ``pyproject.toml`` (``[tool.importlinter]``); this module runs
``lint-imports`` on them and fails with its report.  Every import counts, those inside
functions (a lazy import that runs back up is still an upward import) and those under
``TYPE_CHECKING`` too.  A planted upward import in a copy of the package proves that the
contracts catch one.
"""

from __future__ import annotations

import ast
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

REPOSITORY = Path(__file__).resolve().parent.parent
PACKAGE = REPOSITORY / "copdea_fem"
CONFIG = REPOSITORY / "pyproject.toml"

#: ``lint-imports`` in a fresh interpreter: import-linter configures logging and puts the
#: working directory first on ``sys.path``, so the package it reads is the one there.
LINT_IMPORTS = "import sys; from importlinter.cli import lint_imports_command; " \
    "sys.exit(lint_imports_command())"


def lint_imports(root: Path) -> subprocess.CompletedProcess:
    """``lint-imports`` on the contracts of :data:`CONFIG`, reading the ``copdea_fem``
    below ``root`` (no cache written)."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    return subprocess.run([sys.executable, "-c", LINT_IMPORTS, "--no-cache", "--no-logo",
                           str(CONFIG)], check=False, cwd=root, env=env, capture_output=True,
                          text=True, timeout=300)


def test_the_import_contracts_hold():
    run = lint_imports(REPOSITORY)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 broken" in run.stdout


def test_a_lazy_upward_import_breaks_the_contracts(tmp_path):
    """The FE core importing the API inside a function breaks the package's layers, the
    FE core's (through the API, ``fe.bands`` reaches ``fe.pipeline``), the API's (through
    the FE, what the API's functions share reaches their results) and makes a circle
    (``fe`` -> ``api`` -> ``fe``)."""
    shutil.copytree(PACKAGE, tmp_path / "copdea_fem",
                    ignore=shutil.ignore_patterns("__pycache__"))
    bands = tmp_path / "copdea_fem" / "fe" / "bands.py"
    bands.write_text(bands.read_text(encoding="utf-8")
                     + "\n\ndef _planted():\n    import copdea_fem.api\n", encoding="utf-8")
    run = lint_imports(tmp_path)
    assert run.returncode == 1, run.stdout + run.stderr
    assert "copdea_fem.fe.bands -> copdea_fem.api" in run.stdout
    broken = [line.removesuffix(" BROKEN") for line in run.stdout.splitlines()
              if line.endswith(" BROKEN")]
    assert broken == ["The package's layers: no import runs back up",
                      "The FE core's layers: pipeline, engine interface, engines, shared physics",
                      "The API's layers: the functions with their results, then what they share",
                      "No import circle between the modules or sub-packages of any package"]


def test_an_engines_folder_imported_from_outside_the_fe_core_breaks_its_contract(tmp_path):
    """The rest of the package asks an engine through :mod:`copdea_fem.fe`; a sweep module
    importing the 3-D engine's geometry breaks that contract alone."""
    shutil.copytree(PACKAGE, tmp_path / "copdea_fem",
                    ignore=shutil.ignore_patterns("__pycache__"))
    grid = tmp_path / "copdea_fem" / "sweeps" / "grid.py"
    grid.write_text(grid.read_text(encoding="utf-8")
                    + "\n\ndef _planted():\n    import copdea_fem.fe.quadrant.geometry\n",
                    encoding="utf-8")
    run = lint_imports(tmp_path)
    assert run.returncode == 1, run.stdout + run.stderr
    broken = [line.removesuffix(" BROKEN") for line in run.stdout.splitlines()
              if line.endswith(" BROKEN")]
    assert broken == ["Only the FE core imports an engine's folder"], run.stdout
    assert "copdea_fem.sweeps.grid -> copdea_fem.fe.quadrant.geometry" in run.stdout


#: Where the engine's name may still be read: where it is chosen, the study's
#: checks (which frames an engine allows) and the API's ``Solution.axisymmetric`` (a public
#: property that reports it; no branch).
ENGINE_NAME_ALLOWED = {"fe/engines.py", "study/checks.py", "api/fe_results.py"}


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
    package = tmp_path / "pkg"
    (package / "fe").mkdir(parents=True)
    for name, source in {
            "a.py": 'def f(p):\n    return 1 if p.engine == "axisymmetric" else 2\n',
            "b.py": "def g(s, m):\n    return engine_of(s), m.kind == '3d'\n",
            "fe/engines.py": 'def h(s):\n    return engine_of(s) == "3d"\n'}.items():
        (package / name).write_text(source)
    assert engine_name_tests(package) == ["a.py:2", "b.py:2"]


HISTORY = re.compile(r"\bissue[s]?[ -]?#?\d+", re.IGNORECASE)


def test_the_package_carries_no_history_and_no_benchmark():
    """Docstrings and comments say what the code does and why; issue numbers belong in the
    git log.  The benchmarks live in ``benchmarks/`` at the repository root; the one
    ``__main__`` is the study's (``python -m copdea_fem.study`` prints the README's table)."""
    history = [f"{path.relative_to(REPOSITORY)}:{number}"
               for path in sorted(PACKAGE.rglob("*.py"))
               for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
               if HISTORY.search(line)]
    assert history == []
    assert not [path for path in PACKAGE.rglob("*.py")
                if "bench" in path.stem or (path.name == "__main__.py"
                                            and path != PACKAGE / "study" / "__main__.py")]
    assert HISTORY.search("see Issue 25 for the timings") and not HISTORY.search("tissue 3")


def cli_imports(path: Path = PACKAGE / "cli.py") -> list[str]:
    """Every module the command line imports (``ast`` over the whole module: the imports
    inside functions too), ``from copdea_fem import api`` read as ``copdea_fem.api``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            module = "." * node.level + (node.module or "")
            found += ([f"{module}.{alias.name}" for alias in node.names]
                      if module == "copdea_fem" else [module])
    return found


def test_the_cli_imports_the_api_and_the_standard_library_only():
    """The command line is thin: each command one call of :mod:`copdea_fem.api`, which
    holds the checks; it imports nothing else of the package (nor a third-party module)."""
    others = [name for name in cli_imports()
              if name != "copdea_fem.api" and name.split(".")[0] not in sys.stdlib_module_names]
    assert others == []
    assert "copdea_fem.api" in cli_imports()


def test_a_cli_import_of_another_module_is_found(tmp_path):
    source = tmp_path / "cli.py"
    source.write_text("import os\nfrom copdea_fem import api\n\ndef f():\n"
                      "    from copdea_fem.study import load_study\n    import numpy\n"
                      "    from . import folders\n")
    assert cli_imports(source) == ["os", "copdea_fem.api", "copdea_fem.study", "numpy", "."]
