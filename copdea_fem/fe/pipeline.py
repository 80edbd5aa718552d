"""The FE pipeline of a study: mesh -> prestress -> (dry | coupled) modes.

The engine of the study (``mesh.engine``) is resolved once by the caller
(:func:`copdea_fem.fe.engines.engine_for`: the API, a sweep's point, the diagnosis's FE
solve) and passed in: ``engine`` is a required argument of every function here.  Its band
solves are configured once from ``study.eigen`` (:class:`copdea_fem.fe.bands.BandSolver`).
Nothing here writes a file: the result objects of :mod:`copdea_fem.api` do
(:meth:`copdea_fem.api.Solution.write`).

Entry points used by the API, the sweeps, the diagnosis, the benchmarks and the tests:
:func:`prepare_mesh`, :func:`make_prestress_solver`, :func:`dry_modes`,
:func:`coupled_modes`, :func:`run_solve`, :func:`run_force`.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from copdea_fem.fe.airbox import check_air_lift
from copdea_fem.fe.bands import BandSolver
from copdea_fem.fe.engines import Engine
from copdea_fem.fe.solution import CoupledSolution
from copdea_fem.progress import Timings
from copdea_fem.study import Study, StudyError

if TYPE_CHECKING:
    from copdea_fem.fe.eigen import BandResult, SectorBandResults
    from copdea_fem.fe.modes import Mode
    from copdea_fem.fe.prestress import PrestressedState

__all__ = ["CoupledSolution", "SolveResult", "Timings", "coupled_modes", "dry_modes",
           "make_prestress_solver", "prepare_mesh", "require_backend", "run_force",
           "run_solve"]


@dataclass
class SolveResult:
    """What :func:`run_solve` returns: the engine, the prestress and the modes."""

    study: Study
    engine: Engine
    state: PrestressedState
    modes: list[Mode]
    timings: Timings
    eigen: BandResult | SectorBandResults
    coupled: CoupledSolution | None = None     # with air.enabled


def require_backend(study: Study) -> None:
    """Reject an ``eigen.backend`` this machine cannot run, before any meshing."""
    from copdea_fem.fe.eigen import available_backends, backend_available
    backend = study.eigen.backend
    if not backend_available(backend):
        raise StudyError(f"eigen.backend = {backend!r} is not available on this machine "
                         f"(pardiso needs Intel MKL: pip install mkl); allowed here: "
                         f"{', '.join(available_backends())}")


def prepare_mesh(study: Study, with_air: bool | None = None, cache_dir=None, *,
                 engine: Engine):
    """The mesh of the study's engine: the meridian (r, z) mesh of the axisymmetric engine
    (it always holds the air; not cached), else the (cached) 3-D mesh; ``cache_dir=None``:
    the default mesh cache (:data:`copdea_fem.fe.engines.MESH_CACHE_VARIABLE`)."""
    return engine.prepare_mesh(study, with_air=with_air, cache_dir=cache_dir)


def make_prestress_solver(study: Study, mesh, *, engine: Engine):
    """The Newton solver of the study's engine on ``mesh`` (:func:`prepare_mesh`)."""
    return engine.prestress_solver(study, mesh)


def _meshed(study, mesh, with_air, timings, cache_dir, engine):
    """``mesh``, or the study's mesh made now (timed as the "mesh" stage)."""
    if mesh is None:
        with timings.stage("mesh"):
            mesh = engine.prepare_mesh(study, with_air=with_air, cache_dir=cache_dir)
    return mesh


logger = logging.getLogger(__name__)

#: A root whose oscillation frequency |Re f| is below this share of |f| does not oscillate
#: (damping ratio -Im f / |f| within 5e-13 of 1): an overdamped or critically damped motion
#: (Rayleigh C = alpha M + beta K with c_k >= 2 omega_k gives the roots
#: omega = (-i c_k +- sqrt(4 omega_k^2 - c_k^2)) / 2 on the imaginary axis), not a mode.
OVERDAMPED_SHARE = 1e-6


def oscillates(mode: Mode) -> bool:
    """``|Re f| > OVERDAMPED_SHARE |f|``: the root is a mode, not an overdamped motion."""
    return abs(mode.freq_hz) > OVERDAMPED_SHARE * float(np.hypot(mode.freq_hz, mode.freq_im_hz))


def _oscillating(modes: list) -> list[int]:
    """Indices of the modes that oscillate; one line says how many roots were left out."""
    kept = [k for k, mode in enumerate(modes) if oscillates(mode)]
    if len(kept) < len(modes):
        logger.warning(f"{len(modes) - len(kept)} overdamped root(s) left out of the modes "
                       f"(no oscillation: |Re f| <= {OVERDAMPED_SHARE:g} |f|, damping ratio 1; "
                       "the damping keys damp them beyond a resonance)")
    return kept


def dry_modes(study: Study, mesh=None, timings: Timings | None = None, cache_dir=None,
              solver=None, initial_shifts=None, *, engine: Engine):
    """Prestress and dry (in-vacuo) modes in the study's band: (state, modes, eigen result).

    Sweeps pass ``solver`` (a :class:`copdea_fem.fe.prestress.MembraneSolver` on
    ``mesh``: the prestress continues from its current equilibrium) and
    ``initial_shifts`` (``[(sigma [rad^2/s^2], k), ...]``, see
    :func:`copdea_fem.fe.eigen.solve_band`); the defaults solve from scratch.
    """
    timings = timings or Timings()
    require_backend(study)
    mesh = _meshed(study, mesh, study.air.enabled, timings, cache_dir, engine)
    state, modes, result = engine.dry_modes(study, mesh, timings, solver, initial_shifts,
                                            BandSolver.from_study(study))
    return state, [modes[k] for k in _oscillating(modes)], result


def coupled_modes(study: Study, mesh=None, timings: Timings | None = None, cache_dir=None,
                  solver=None, initial_shifts=None, *,
                  engine: Engine) -> CoupledSolution:
    """Prestress, dry modes and fully-coupled membrane-air modes (Sect. 3.1.3).

    On a quadrant mesh (``mesh.symmetry: quarter``, :mod:`copdea_fem.fe.symmetry`)
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
    mesh = _meshed(study, mesh, True, timings, cache_dir, engine)
    solution = engine.coupled_modes(study, mesh, timings, solver, initial_shifts,
                                    BandSolver.from_study(study))
    kept = _oscillating(solution.modes)
    if len(kept) == len(solution.modes):
        return solution
    position = {k: j for j, k in enumerate(kept)}
    return dataclasses.replace(
        solution, modes=[solution.modes[k] for k in kept],
        pressures=[solution.pressures[k] for k in kept],
        dry_partner_hz={position[k]: hz for k, hz in solution.dry_partner_hz.items()
                        if k in position})


def run_solve(study: Study, *, cache_dir=None, engine: Engine) -> SolveResult:
    """Prestress and modes of ``copdea-fem solve`` (coupled when ``air.enabled``)."""
    timings = Timings()
    coupled = None
    if study.air.enabled:
        coupled = coupled_modes(study, timings=timings, cache_dir=cache_dir, engine=engine)
        state, modes, eigen_result = coupled.state, coupled.modes, coupled.eigen
    else:
        state, modes, eigen_result = dry_modes(study, timings=timings, cache_dir=cache_dir,
                                               engine=engine)
    return SolveResult(study, engine, state, modes, timings, eigen_result, coupled)


def run_force(study: Study, z_values, voltages, *, cache_dir=None,
              engine: Engine) -> np.ndarray:
    """Static disc force F(z) [N] at each voltage [V] and z [m] (Fig. 4b):
    ``forces[i, j]`` at ``voltages[i]``, ``z_values[j]``."""
    from copdea_fem.fe.prestress import force_displacement

    with engine.threads():
        mesh = engine.prepare_mesh(study, with_air=False, cache_dir=cache_dir)
        return force_displacement(study, mesh, z_values, voltages,
                                  new_solver=lambda study, mesh: engine.prestress_solver(
                                      study, mesh))
