"""Fingerprints of the code that computes a cached result: part of every cache key.

A cache entry (a mesh, an FE result of the diagnosis, a finished sweep point) is keyed
by what made it: the inputs *and* the sources of the code that computed it, hashed
here once per process.  A change to those sources gives new keys, so an old entry is
never reused after a physics change (no hand-bumped version to forget).  Each cache
hashes only the code that computes its numbers, so unrelated edits (the CLI, the
output files, the docs, docstrings and comments) keep it warm.
"""

from __future__ import annotations

import ast
import functools
import hashlib
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent

#: The 3-D mesh: the shapes and the meshing.
MESH_SOURCES = ("fe/quadrant/geometry.py", "fe/quadrant/mirrored.py", "fe/airbox.py")

#: What in the FE core computes no modes: the orchestration and its result type, the forced
#: response, the ParaView fields and the fields at points.  Left out of :data:`FE_SOURCES`,
#: so an edit there keeps the FE cache.
NOT_FE_SOURCES = ("fe/pipeline.py", "fe/solution.py", "fe/engines.py", "fe/fields.py",
                  "fe/points.py", "fe/forced", "fe/axisymmetric/forced.py",
                  "fe/axisymmetric/forcing.py", "fe/axisymmetric/fields.py",
                  "fe/axisymmetric/points.py", "fe/quadrant/forced.py", "fe/quadrant/fields.py",
                  "fe/quadrant/points.py")


def _modules_of(folder: str, left_out: tuple[str, ...]) -> tuple[str, ...]:
    """The ``*.py`` below ``folder`` (paths from the package) but those ``left_out`` (files,
    or folders and all below them)."""
    names = (path.relative_to(PACKAGE).as_posix() for path in (PACKAGE / folder).rglob("*.py"))
    return tuple(sorted(name for name in names
                        if not any(name == out or name.startswith(out + "/")
                                   for out in left_out)))


#: FE modes (frequencies, damping, kinds, labels): every module of :mod:`copdea_fem.fe` but
#: :data:`NOT_FE_SOURCES` (a new file is in without editing a list); not the study schema:
#: a changed default changes the resolved study, which every key already hashes.
FE_SOURCES = _modules_of("fe", NOT_FE_SOURCES)

#: The reduced (ring) model of the sweeps and the diagnosis.
REDUCED_SOURCES = ("fe/materials.py", "reduced")


class _Prose(ast.NodeTransformer):
    """Drops every bare string statement: docstrings of modules, classes and functions, and
    the attribute docstrings below assignments (they compute nothing)."""

    def visit_Expr(self, node):
        if isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            return None
        return node


def _code(source: bytes) -> bytes:
    """The code of a module without its docstrings and comments: the dump of its syntax
    tree (a docstring or comment edit keeps the caches; any change of code does not)."""
    return ast.dump(_Prose().visit(ast.parse(source)), annotate_fields=False).encode()


@functools.lru_cache(maxsize=None)
def code_fingerprint(sources: tuple[str, ...]) -> str:
    """SHA-256 (first 16 hex digits) of the named package files and folders (every
    ``*.py`` below a folder): their paths and their code (:func:`_code`)."""
    digest = hashlib.sha256()
    for name in sorted(sources):
        path = PACKAGE / name
        if not path.exists():
            raise FileNotFoundError(f"fingerprint source {name} is not in {PACKAGE}")
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for file in files:
            digest.update(file.relative_to(PACKAGE).as_posix().encode())
            digest.update(b"\0")
            digest.update(_code(file.read_bytes()))
            digest.update(b"\0")
    return digest.hexdigest()[:16]


def mesh_fingerprint() -> str:
    return code_fingerprint(MESH_SOURCES)


def fe_fingerprint() -> str:
    return code_fingerprint(FE_SOURCES)


def model_fingerprint(model: str) -> str:
    """The fingerprint of a sweep model's code: ``reduced`` or an FE model."""
    return code_fingerprint(REDUCED_SOURCES if model == "reduced" else FE_SOURCES)
