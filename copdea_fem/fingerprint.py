"""Fingerprints of the code that computes a cached result: part of every cache key.

A cache entry (a mesh, an FE result of the diagnosis, a finished sweep point) is keyed
by what made it: the inputs *and* the sources of the code that computed it, hashed
here once per process.  A change to those sources gives new keys, so an old entry is
never reused after a physics change (no hand-bumped version to forget).  Each cache
hashes only the sources that compute its numbers, so unrelated edits (the CLI, the
output files, the docs) keep it warm.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent

#: The 3-D mesh: the shapes and the meshing (:mod:`copdea_fem.geometry`).
MESH_SOURCES = ("geometry.py", "airbox.py")

#: Modules of an engine's folder that compute no modes: the axisymmetric engine's forced
#: problem, its voltage forcing and its ParaView fields (beside the engine, below it:
#: issue 21).  Left out of :data:`FE_SOURCES`, so an edit of the forced response or of the
#: output files keeps the FE cache; every other module of the folder is in, a new one too.
NOT_FE_SOURCES = ("axisymmetric/forced.py", "axisymmetric/forcing.py",
                  "axisymmetric/fields.py")


def _modules_of(folder: str, left_out: tuple[str, ...]) -> tuple[str, ...]:
    """The ``*.py`` below ``folder`` (paths from the package) but those ``left_out``; the
    fingerprint of the tuple equals the folder's without them (same names, same order)."""
    names = (path.relative_to(PACKAGE).as_posix() for path in (PACKAGE / folder).rglob("*.py"))
    return tuple(sorted(name for name in names if name not in left_out))


#: FE modes (frequencies, damping, kinds, labels): the physics, the assembly, the band
#: solves, the classification and labels of both engines.  Not the orchestration
#: (solve.py, engines.py, pipeline.py), the forced response and the output
#: (:data:`NOT_FE_SOURCES`), nor the study schema: a changed default changes the resolved
#: study, which every key already hashes.
FE_SOURCES = ("materials.py", "membrane.py", "prestress.py", "linearise.py", "coupled.py",
              "acoustics.py", "ale.py", "airbox.py", "geometry.py", "symmetry.py", "modes.py",
              "bands.py", "engine3d.py", "eigen", "assignment.py") \
    + _modules_of("axisymmetric", NOT_FE_SOURCES)

#: The reduced (ring) model of the sweeps and the diagnosis.
REDUCED_SOURCES = ("materials.py", "reduced")


@functools.lru_cache(maxsize=None)
def code_fingerprint(sources: tuple[str, ...]) -> str:
    """SHA-256 (first 16 hex digits) of the named package files and folders (every
    ``*.py`` below a folder): their paths and contents, line endings normalised."""
    digest = hashlib.sha256()
    for name in sorted(sources):
        path = PACKAGE / name
        if not path.exists():
            raise FileNotFoundError(f"fingerprint source {name} is not in {PACKAGE}")
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for file in files:
            digest.update(file.relative_to(PACKAGE).as_posix().encode())
            digest.update(b"\0")
            digest.update(file.read_bytes().replace(b"\r\n", b"\n"))
            digest.update(b"\0")
    return digest.hexdigest()[:16]


def mesh_fingerprint() -> str:
    return code_fingerprint(MESH_SOURCES)


def fe_fingerprint() -> str:
    return code_fingerprint(FE_SOURCES)


def model_fingerprint(model: str) -> str:
    """The fingerprint of a sweep model's code: ``reduced`` or an FE model."""
    return code_fingerprint(REDUCED_SOURCES if model == "reduced" else FE_SOURCES)
