"""The FE core: the physics, both engines and the eigen step.

Applications import the names below from here (``from copdea_fem.fe import run_solve``);
each is loaded on first use (PEP 562), so ``import copdea_fem.fe`` loads no NGSolve:

- the engine interface (:mod:`.engines`): :class:`Engine`, :func:`engine_for` (resolve it
  once, then pass it down: every function below the API takes ``engine``),
  :func:`check_size` (the resource guard), :data:`MAX_UNKNOWNS`,
  :data:`MESH_CACHE_VARIABLE`;
- the pipeline (:mod:`.pipeline`): :func:`run_solve` and its :class:`SolveResult`,
  :func:`dry_modes`, :func:`coupled_modes` and their :class:`CoupledSolution`,
  :func:`run_force`, :func:`prepare_mesh`, :func:`make_prestress_solver`,
  :func:`require_backend`, :func:`check_air_lift`;
- what the results hold: :class:`Mode` and its kinds (:data:`AIR`, :data:`OUT_OF_PLANE`,
  :data:`IN_PLANE`, :data:`PUMPING`), :class:`PrestressedState`, :class:`Membrane`;
- the forced response's inputs (:mod:`.forced`): :class:`OrderZero`, :class:`DrivenPart`,
  :class:`ElectrodeImperfection`; fields at points of the device: :class:`PointSampler`;
- the errors a solve raises: :class:`PrestressError`, :class:`MeshMotionError`,
  :class:`EigenSolverError` (with :class:`EigenResidualError`, :class:`TooManyModesError`).

Shared physics at this level, one module per stage of the pipeline:

- :mod:`.materials` (eq. 20) and :mod:`.membrane` (the membrane energy, eqs. 2-7);
- :mod:`.prestress`: the nonlinear electro-hyperelastic equilibrium (Newton, load steps);
- :mod:`.linearise`: the tangent, mass and damping operators at that equilibrium;
- :mod:`.acoustics`, :mod:`.airbox`, :mod:`.ale`, :mod:`.coupled`: the air, its PML, the
  moving air mesh and the coupled membrane-air pencil (Sect. 3.1);
- :mod:`.symmetry`: the mirror-symmetry sectors of the quadrant;
- :mod:`.eigen`: the shift-invert band eigensolver; :mod:`.bands`: the band rules both
  engines share; :mod:`.modes`: classification and labels;
- :mod:`.forced`: the forced harmonic response's parts both engines share (the driven
  problem, the parts an electrode drives, the electrode's weight);
- :mod:`.fields`: the ParaView fields' plumbing both engines share; :mod:`.points`: the
  mapping of points of the prestressed device to the reference membrane;
- :mod:`.engines`: the engine interface, :mod:`.pipeline`: mesh -> prestress -> modes.

The engines: :mod:`.quadrant` (the 3-D quadrant mesh: any frame) and :mod:`.axisymmetric`
(the meridian (r, z) mesh, one 2-D problem per circumferential order m), each one folder
whose engine class implements :class:`Engine`: its mesh and mesh keys, prestress, modes,
forced problem, electrode forcing, fields at points and output fields.  Nothing outside
this package imports them (an import-linter contract); a third engine is a third folder
and a line in :func:`engine_for`.

Everything that computes modes here is in the FE code fingerprint
(:data:`copdea_fem.fingerprint.FE_SOURCES`): a new file is covered without a list to edit.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:   # the names for type checkers, and the package's imports for import-linter
    from copdea_fem.fe.airbox import check_air_lift
    from copdea_fem.fe.ale import MeshMotionError
    from copdea_fem.fe.eigen import EigenResidualError, EigenSolverError, TooManyModesError
    from copdea_fem.fe.engines import (
        MAX_UNKNOWNS,
        MESH_CACHE_VARIABLE,
        Engine,
        check_size,
        engine_for,
    )
    from copdea_fem.fe.forced.electrode import (
        ElectrodeImperfection,
        SegmentWeight,
        segment_weights,
    )
    from copdea_fem.fe.forced.problem import DrivenPart, OrderZero
    from copdea_fem.fe.materials import Membrane
    from copdea_fem.fe.modes import AIR, IN_PLANE, OUT_OF_PLANE, PUMPING, Mode
    from copdea_fem.fe.pipeline import (
        SolveResult,
        coupled_modes,
        dry_modes,
        make_prestress_solver,
        prepare_mesh,
        require_backend,
        run_force,
        run_solve,
    )
    from copdea_fem.fe.points import PointSampler
    from copdea_fem.fe.prestress import PrestressedState, PrestressError
    from copdea_fem.fe.solution import CoupledSolution

#: Public name -> the module of this package that defines it.
_HOMES = {
    "Engine": "engines", "engine_for": "engines", "check_size": "engines",
    "MAX_UNKNOWNS": "engines", "MESH_CACHE_VARIABLE": "engines",
    "SolveResult": "pipeline", "run_solve": "pipeline", "run_force": "pipeline",
    "dry_modes": "pipeline", "coupled_modes": "pipeline", "prepare_mesh": "pipeline",
    "make_prestress_solver": "pipeline", "require_backend": "pipeline",
    "CoupledSolution": "solution",
    "Mode": "modes", "AIR": "modes", "OUT_OF_PLANE": "modes", "IN_PLANE": "modes",
    "PUMPING": "modes",
    "PrestressedState": "prestress", "PrestressError": "prestress",
    "Membrane": "materials",
    "OrderZero": "forced.problem", "DrivenPart": "forced.problem",
    "ElectrodeImperfection": "forced.electrode", "SegmentWeight": "forced.electrode",
    "segment_weights": "forced.electrode",
    "PointSampler": "points",
    "MeshMotionError": "ale", "check_air_lift": "airbox",
    "EigenSolverError": "eigen", "EigenResidualError": "eigen", "TooManyModesError": "eigen",
}

__all__ = ["AIR", "IN_PLANE", "MAX_UNKNOWNS", "MESH_CACHE_VARIABLE", "OUT_OF_PLANE", "PUMPING",
           "CoupledSolution", "DrivenPart", "EigenResidualError", "EigenSolverError",
           "ElectrodeImperfection", "Engine", "Membrane", "MeshMotionError", "Mode", "OrderZero",
           "PointSampler", "PrestressError", "PrestressedState", "SegmentWeight", "SolveResult",
           "TooManyModesError", "check_air_lift", "check_size", "coupled_modes", "dry_modes",
           "engine_for", "make_prestress_solver", "prepare_mesh", "require_backend",
           "run_force", "run_solve", "segment_weights"]


def __getattr__(name):
    # looked up in its module on every access (not kept here): one definition, which a
    # test's monkeypatch of that module reaches too
    if name in _HOMES:
        return getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
