"""The FE engine interface: everything the rest of the package asks of an engine.

:class:`Engine` is what the pipeline (:mod:`copdea_fem.fe.pipeline`), the forced response
(:mod:`copdea_fem.forced_response`: the driven problem, the parts an electrode drives, their
forcing, the fields at scan points), the sweeps (the mesh and FE-space keys, the tracking
arrays), the output (the result fields) and the resource guard (:func:`check_size`) ask of
an engine.  :func:`engine_for` picks the implementation of a study
(:func:`copdea_fem.study.engine_of`): the 3-D quadrant
(:class:`copdea_fem.fe.quadrant.engine.QuadrantEngine`) or the axisymmetric one
(:class:`copdea_fem.fe.axisymmetric.engine.AxisymmetricEngine`).  An engine is one folder
of :mod:`copdea_fem.fe` whose engine class implements every method of :class:`Engine`; no
module outside :mod:`copdea_fem.fe` imports an engine's folder (an import-linter contract).

The API's functions, the sweeps' points and the diagnosis's FE solves resolve the engine
once (:func:`engine_for`) and pass it down: below them ``engine`` is a required argument
(a :class:`copdea_fem.fe.pipeline.SolveResult` carries it).  The band solves of a study are
configured once (:class:`copdea_fem.fe.bands.BandSolver`) and handed to the engine; the
rules both engines share (dry partner band, coupled start count, order stop rule) live in
:mod:`copdea_fem.fe.bands`, the labels in :mod:`copdea_fem.fe.modes`.  No module but this
one and the study's schema tests the engine's name.
"""

from __future__ import annotations

import logging
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any, Protocol

from copdea_fem.fe.quadrant.geometry import CACHE_VARIABLE
from copdea_fem.study import Study, StudyError, engine_of
from copdea_fem.study.imperfections import imperfection_keys_given, perturbation_refusal

if TYPE_CHECKING:
    import numpy as np

    from copdea_fem.fe.bands import BandSolver
    from copdea_fem.fe.forced.electrode import ElectrodeImperfection, SegmentWeight
    from copdea_fem.fe.forced.problem import DrivenPart, DrivenSector, OrderZero
    from copdea_fem.fe.modes import Mode
    from copdea_fem.fe.points import PointSampler
    from copdea_fem.fe.prestress import MembraneSolver, PrestressedState
    from copdea_fem.fe.solution import CoupledSolution
    from copdea_fem.progress import Timings

logger = logging.getLogger(__name__)


class Engine(Protocol):
    """One FE engine: mesh, prestress solver, dry and coupled modes, threading."""

    name: str

    def mesh_key(self, study: Study, with_air: bool) -> tuple:
        """A hashable key of what the mesh depends on (the sweeps' mesh reuse)."""

    def space_key(self, study: Study, with_air: bool) -> str:
        """The FE space the modes' vectors live in: points of a sweep with equal keys
        compare their vectors directly (:mod:`copdea_fem.sweeps.tracking`)."""

    def prepare_mesh(self, study: Study, with_air: bool | None = None, cache_dir=None) -> Any:
        """The mesh of the study (``cache_dir``: the 3-D mesh cache)."""

    def prestress_solver(self, study: Study, mesh) -> MembraneSolver:
        """The Newton solver on ``mesh``."""

    def dry_modes(self, study: Study, mesh, timings: Timings | None = None,
                  solver: MembraneSolver | None = None, initial_shifts=None,
                  band: BandSolver | None = None) -> tuple[PrestressedState, list[Mode], Any]:
        """Prestress and dry modes in the band: (state, modes, eigen result)."""

    def coupled_modes(self, study: Study, mesh, timings: Timings | None = None,
                      solver: MembraneSolver | None = None, initial_shifts=None,
                      band: BandSolver | None = None) -> CoupledSolution:
        """Prestress, dry partners and coupled modes."""

    def threads(self) -> AbstractContextManager:
        """Context manager for the output and force stages (NGSolve's TaskManager or none)."""

    def estimate_size(self, study: Study) -> tuple[float, float]:
        """(elements, unknowns) the study's mesh will have, estimated before meshing (the
        resource guard, :func:`check_size`)."""

    def forced_problem(self, study: Study) -> OrderZero:
        """Mesh, prestress and the forced-response operators of the part of the problem a
        uniform electrode drives; its ``sector``
        (:class:`copdea_fem.fe.forced.problem.DrivenSector`) describes it."""

    def driven_sector(self) -> DrivenSector:
        """What the forced response needs to know of the part a uniform electrode drives
        (:class:`copdea_fem.fe.forced.problem.DrivenSector`: its observers, its Kirchhoff
        sphere), without building the problem (:meth:`forced_problem` builds it with it)."""

    def driven_parts(self, solution, study: Study) -> list[DrivenPart]:
        """The independently solved parts of ``solution`` (a
        :class:`copdea_fem.fe.pipeline.SolveResult`: sectors, orders or the whole mesh) with
        their pencils and band results, in solve order: what an electrode drives
        (:mod:`copdea_fem.forced_response.scan`)."""

    def electrode_forcing(self, state: PrestressedState, part: DrivenPart,
                          electrode: ElectrodeImperfection | SegmentWeight) -> np.ndarray:
        """The forcing [N/V] of ``electrode``'s drive weight on ``part``'s membrane unknowns
        (:mod:`copdea_fem.fe.forced.electrode`; the factors of an order's families:
        :meth:`copdea_fem.fe.forced.problem.DrivenPart.families`).

        ``electrode`` is any object of the weight protocol of
        :mod:`copdea_fem.fe.forced.electrode`, a weight
        ``w(r, theta) = rho(r) sum_m (c_m cos m theta + s_m sin m theta)`` on the co-energy:
        ``family_weights(m) -> (c_m, s_m)``, ``radial_weight(r) -> rho`` (None: 1),
        ``weight(x, y)`` and ``sector_weight(sector, x, y)`` (its fold on a 3-D symmetry
        sector).  The axisymmetric engine returns the forcing of ``rho(R) cos(m theta)`` on
        the order's cos family (the caller multiplies by ``c_m``, ``s_m`` per family); the
        3-D engine the forcing of the folded weight itself (factor 1).  Linear in the
        weight: a drive of several segments is the sum of their forcings times their
        complex AC volts (:func:`copdea_fem.fe.forced.electrode.segment_weights`)."""

    def point_sampler(self, state: PrestressedState, positions) -> PointSampler:
        """The fields of ``state`` at points (P, 3) [m] of the prestressed device
        (:class:`copdea_fem.fe.points.PointSampler`)."""

    def prestressed_positions(self, state: PrestressedState, reference_xy,
                              disc_z: float) -> np.ndarray:
        """Where points (P, 2) [m] of the flat reference device lie on the prestressed one:
        (P, 3) [m] (:meth:`copdea_fem.fe.points.PointSampler.prestressed_positions`)."""

    def tracking_arrays(self, state: PrestressedState, modes: list[Mode],
                        needs_sampling: bool) -> dict:
        """What the sweeps track a point's modes by (:mod:`copdea_fem.sweeps.tracking`)."""

    def output(self, state: PrestressedState, modes: list[Mode] = ()) -> Any:
        """The result fields of a prestress ``state`` for ParaView and the API: an object with
        ``symmetry`` (modes.json), ``prestress_mesh()``, ``mode_meshes(modes)`` and
        ``air_meshes(operators, modes, pressures)`` (:class:`copdea_fem.vtu.VtuMesh` meshes);
        ``modes``: the structural modes written together."""


def engine_for(study: Study, forced_response: bool = False) -> Engine:
    """The engine of the study (``mesh.engine``, ``auto`` resolved by the frame and the
    imperfections, :func:`copdea_fem.study.engine_of`): ``auto`` sends an imperfect device
    to the axisymmetric engine's first-order perturbation path where
    :func:`copdea_fem.study.imperfections.perturbation_refusal` allows it (within its
    range; dry or in air) and the caller asks for modes only, else to the 3-D engine; either
    way logged with the reason.  ``forced_response``: the caller drives the device (the
    perturbation path makes modes only)."""
    imperfect = imperfection_keys_given(study.membrane, study.imperfections)
    engine = engine_of(study, forced_response)
    if study.mesh.engine == "auto" and imperfect:
        beyond = perturbation_refusal(study.membrane, study.imperfections, study.geometry)
        if engine == "axisymmetric":
            reason = ("within the range of its first-order perturbation path ("
                      + ("coupled" if study.air.enabled else "dry") + " modes)")
        elif beyond:
            reason = (f"not the axisymmetric engine's perturbation path: {beyond[0]} = "
                      f"{beyond[1]}, allowed there: {beyond[2]}")
        elif forced_response:
            reason = ("not the axisymmetric engine's perturbation path: a forced response, "
                      "which it does not make (modes only)")
        else:
            reason = (f"geometry.frame = {study.geometry.frame!r} with geometry.enclosure = "
                      f"{study.geometry.enclosure!r} is not round")
        name = "axisymmetric" if engine == "axisymmetric" else "3-D"
        logger.info(f"mesh.engine = auto: the {name} engine for {imperfect} ({reason})")
    elif imperfect and engine == "axisymmetric":
        logger.info(f"mesh.engine = axisymmetric: {imperfect} by first-order perturbation "
                    "(" + ("coupled" if study.air.enabled else "dry") + " modes)")
    if engine == "axisymmetric":
        from copdea_fem.fe.axisymmetric.engine import AxisymmetricEngine
        return AxisymmetricEngine()
    from copdea_fem.fe.quadrant.engine import QuadrantEngine
    return QuadrantEngine()


#: Largest problem the CLI starts without --allow-large: estimated unknowns of the
#: membrane plus, with air, the pressure (the default coupled G1 study: ~16 000 per sector).
MAX_UNKNOWNS = 2_000_000

#: The environment variable naming the folder of the engines' mesh cache (the CLI's
#: ``--mesh-cache`` sets it, so that worker processes see it too;
#: :func:`copdea_fem.fe.quadrant.geometry.mesh_cache_dir`).
MESH_CACHE_VARIABLE = CACHE_VARIABLE


def check_size(study: Study, limit: float | None = None, *, engine: Engine) -> None:
    """The resource guard: refuse (StudyError) a study whose engine estimates more unknowns
    than ``limit`` (default :data:`MAX_UNKNOWNS`), before meshing."""
    elements, unknowns = engine.estimate_size(study)
    refuse_size(study, elements, unknowns, MAX_UNKNOWNS if limit is None else limit)


def refuse_size(study, elements: float, unknowns: float, limit: float = MAX_UNKNOWNS) -> None:
    """Refuse (StudyError) a study whose estimated unknowns (the engine's estimate:
    :func:`copdea_fem.fe.engines.check_size`) exceed ``limit``, before meshing."""
    with_air = study.air.enabled
    mesh = study.mesh
    if unknowns > limit:
        coarser = "a larger mesh.membrane_size" + (" or mesh.air_size" if with_air else "")
        lower = "a lower mesh.order" + (" or mesh.pressure_order" if with_air else "")
        raise StudyError(
            f"mesh.membrane_size = {mesh.membrane_size:g} m (mesh.order = {mesh.order}) "
            f"gives about {elements:.3g} elements and {unknowns:.3g} unknowns, more than the "
            f"limit of {limit:.3g}; allowed: {coarser}, {lower}, or --allow-large")
