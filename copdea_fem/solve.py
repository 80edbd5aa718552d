"""The pipeline of ``copdea-fem solve``: study -> mesh -> prestress -> modes -> files.

The engine of the study (``mesh.engine``) is chosen once (:func:`copdea_fem.engines.engine_for`):
the 3-D quadrant (:mod:`copdea_fem.engine3d`) or the axisymmetric engine
(:mod:`copdea_fem.axisymmetric.engine`); its band solves are configured once from
``study["eigen"]`` (:class:`copdea_fem.bands.BandSolver`).  Every file is written by
:mod:`output`.

Library entry points used by the CLI, the benchmarks and the tests:
:func:`prepare_mesh`, :func:`dry_modes`, :func:`coupled_modes`, :func:`run_solve`,
:func:`run_force`, :func:`make_prestress_solver`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import output

from .bands import BandSolver
from .engines import engine_for
from .pipeline import CoupledSolution, Timings, quiet as _quiet  # noqa: F401
from .pipeline import single_threaded_blas as _single_threaded_blas  # noqa: F401
from .prestress import force_displacement
from .study import Study, StudyError, check_air_lift

__all__ = ["CoupledSolution", "SolveResult", "Timings", "coupled_modes", "dry_modes",
           "make_prestress_solver", "prepare_mesh", "require_backend", "run_force",
           "run_solve"]


logger = logging.getLogger(__name__)


@dataclass
class SolveResult:
    study: Study
    state: object
    modes: list
    rows: list
    timings: Timings
    eigen: object
    out_dir: Path | None = None
    coupled: object = None          # CoupledSolution when air.enabled


def require_backend(study: Study) -> None:
    """Reject an ``eigen.backend`` this machine cannot run, before any meshing."""
    from .eigen import available_backends, backend_available
    backend = study["eigen"]["backend"]
    if not backend_available(backend):
        raise StudyError(f"eigen.backend = {backend!r} is not available on this machine "
                         f"(pardiso needs Intel MKL: pip install mkl); allowed here: "
                         f"{', '.join(available_backends())}")


def prepare_mesh(study: Study, with_air: bool | None = None, cache_dir=None):
    """The mesh of the study's engine: the meridian (r, z) mesh of the axisymmetric engine
    (it always holds the air; not cached), else the (cached) 3-D mesh; ``cache_dir=None``:
    :func:`geometry.mesh_cache_dir`."""
    return engine_for(study).prepare_mesh(study, with_air=with_air, cache_dir=cache_dir)


def make_prestress_solver(study: Study, mesh):
    """The Newton solver of the study's engine on ``mesh`` (:func:`prepare_mesh`)."""
    return engine_for(study).prestress_solver(study, mesh)


def _meshed(study, mesh, with_air, timings, cache_dir):
    """``mesh``, or the study's mesh made now (timed as the "mesh" stage)."""
    if mesh is None:
        with timings.stage("mesh"):
            mesh = prepare_mesh(study, with_air=with_air, cache_dir=cache_dir)
    return mesh


def dry_modes(study: Study, mesh=None, timings: Timings | None = None,
              cache_dir=None, solver=None, initial_shifts=None):
    """Prestress and dry (in-vacuo) modes in the study's band: (state, modes, eigen result).

    Sweeps pass ``solver`` (a :class:`copdea_fem.prestress.MembraneSolver` on
    ``mesh``: the prestress continues from its current equilibrium) and
    ``initial_shifts`` (``[(sigma [rad^2/s^2], k), ...]``, see
    :func:`copdea_fem.eigen.solve_band`); the defaults solve from scratch.
    """
    timings = timings or Timings()
    require_backend(study)
    engine = engine_for(study)        # its modules imported here, not in the mesh stage
    mesh = _meshed(study, mesh, study["air"]["enabled"], timings, cache_dir)
    return engine.dry_modes(study, mesh, timings, solver, initial_shifts,
                            BandSolver.from_study(study))


def coupled_modes(study: Study, mesh=None, timings: Timings | None = None,
                  cache_dir=None, solver=None, initial_shifts=None) -> CoupledSolution:
    """Prestress, dry modes and fully-coupled membrane-air modes (Sect. 3.1.3).

    On a quadrant mesh (``mesh.symmetry: quarter``, :mod:`copdea_fem.symmetry`)
    the dry and coupled bands are solved per mirror-symmetry sector and merged.
    ``solver`` and ``initial_shifts`` are the sweep's reuse hooks, as in
    :func:`dry_modes`: the prestress continues from ``solver``'s equilibrium,
    and the coupled band solves start at ``initial_shifts`` (a neighbouring
    point's coupled shifts and mode counts, per sector: ``{sector name or
    "all": shifts}``); the dry partner solves start afresh.
    """
    timings = timings or Timings()
    require_backend(study)
    check_air_lift(study)
    engine = engine_for(study)        # its modules imported here, not in the mesh stage
    mesh = _meshed(study, mesh, True, timings, cache_dir)
    return engine.coupled_modes(study, mesh, timings, solver, initial_shifts,
                                BandSolver.from_study(study))


def run_solve(study: Study, out_dir: str | Path | None = None, cache_dir=None) -> SolveResult:
    """Full ``solve``: prestress, modes (coupled when ``air.enabled``), result files."""
    timings = Timings()
    coupled = None
    if study["air"]["enabled"]:
        coupled = coupled_modes(study, timings=timings, cache_dir=cache_dir)
        state, modes, eigen_result = coupled.state, coupled.modes, coupled.eigen
        rows = output.mode_rows(modes, coupled.dry_partner_hz)
    else:
        state, modes, eigen_result = dry_modes(study, timings=timings, cache_dir=cache_dir)
        rows = output.mode_rows(modes)
    result = SolveResult(study, state, modes, rows, timings, eigen_result, coupled=coupled)
    if out_dir is not None:
        with timings.stage("output"), engine_for(study).threads():
            logger.info("writing results ...")
            output.write_results(result, Path(out_dir))
        result.out_dir = Path(out_dir)
    return result


def run_force(study: Study, z_values, voltages, out_dir: str | Path | None = None,
              cache_dir=None) -> np.ndarray:
    """Static F(z) [N] at each voltage (Fig. 4b); writes force_displacement.csv/.png."""
    with engine_for(study).threads():
        mesh = prepare_mesh(study, with_air=False, cache_dir=cache_dir)
        forces = force_displacement(study, mesh, z_values, voltages,
                                    new_solver=make_prestress_solver)
    if out_dir is not None:
        output.write_force_results(study, Path(out_dir), z_values, voltages, forces)
    return forces
