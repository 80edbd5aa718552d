"""The FE engines behind one interface, chosen once from ``mesh.engine``.

:class:`Engine` is what the pipeline (:mod:`copdea_fem.solve`), the sweeps and the
resource guard ask of an engine; :func:`engine_for` picks the implementation of a
study (:func:`copdea_fem.study.engine_of`): the 3-D quadrant
(:class:`copdea_fem.engine3d.QuadrantEngine`) or the axisymmetric one
(:class:`copdea_fem.axisymmetric.engine.AxisymmetricEngine`).  The band solves of a
study are configured once (:class:`copdea_fem.bands.BandSolver`) and handed to the
engine; the rules both engines share (dry partner band, coupled start count, order
stop rule) live in :mod:`copdea_fem.bands`, the labels in :mod:`copdea_fem.modes`.
What the forced response (:mod:`copdea_fem.response`), the sweeps' mode tracking and the
resource guard (:func:`check_size`) need of an engine is asked of it too: no module but
this one and the study's schema tests the engine's name (``tests/test_imports.py``; the
output sampling of :mod:`copdea_fem.output` excepted, for now).
"""

from __future__ import annotations

from typing import Protocol

from .study import engine_of


class Engine(Protocol):
    """One FE engine: mesh, prestress solver, dry and coupled modes, threading."""

    name: str

    def mesh_key(self, study, with_air: bool):
        """A hashable key of what the mesh depends on (the sweeps' mesh reuse)."""

    def prepare_mesh(self, study, with_air=None, cache_dir=None):
        """The mesh of the study (``cache_dir``: the 3-D mesh cache)."""

    def prestress_solver(self, study, mesh):
        """The Newton solver on ``mesh`` (:class:`copdea_fem.prestress.MembraneSolver`)."""

    def dry_modes(self, study, mesh, timings=None, solver=None,
                  initial_shifts=None, band=None):
        """Prestress and dry modes in the band: (state, modes, eigen result)."""

    def coupled_modes(self, study, mesh, timings=None, solver=None,
                      initial_shifts=None, band=None):
        """Prestress, dry partners and coupled modes: a
        :class:`copdea_fem.pipeline.CoupledSolution`."""

    def threads(self):
        """Context manager for the output and force stages (NGSolve's TaskManager or none)."""

    def estimate_size(self, study):
        """(elements, unknowns) the study's mesh will have, estimated before meshing (the
        resource guard, :func:`check_size`)."""

    def forced_problem(self, study):
        """Mesh, prestress and the forced-response operators of the part of the problem a
        uniform electrode drives: a :class:`copdea_fem.forced.problem.OrderZero` whose
        ``sector`` (:class:`copdea_fem.forced.problem.DrivenSector`) describes it."""

    def tracking_arrays(self, state, modes, needs_sampling: bool) -> dict:
        """What the sweeps track a point's modes by (:mod:`copdea_fem.tracking`)."""

    def output(self, state, modes=()):
        """The result fields of a prestress ``state`` for ParaView and the API: an object with
        ``symmetry`` (modes.json), ``prestress_mesh()``, ``mode_meshes(modes)`` and
        ``air_meshes(operators, modes, pressures)`` (meshio meshes, see
        :mod:`copdea_fem.output`); ``modes``: the structural modes written together."""


def engine_for(study) -> Engine:
    """The engine of the study (``mesh.engine``, ``auto`` resolved by the frame)."""
    if engine_of(study) == "axisymmetric":
        from .axisymmetric.engine import AxisymmetricEngine
        return AxisymmetricEngine()
    from .engine3d import QuadrantEngine
    return QuadrantEngine()


def check_size(study, limit: float | None = None) -> None:
    """The resource guard: refuse (StudyError) a study whose engine estimates more unknowns
    than ``limit`` (default :data:`copdea_fem.geometry.MAX_UNKNOWNS`), before meshing."""
    from .geometry import MAX_UNKNOWNS, refuse_size
    elements, unknowns = engine_for(study).estimate_size(study)
    refuse_size(study, elements, unknowns, MAX_UNKNOWNS if limit is None else limit)


def engine_of_state(state) -> Engine:
    """The engine that computed a prestress ``state`` (the axisymmetric engine's states say
    so in ``state.engine``; the 3-D engine's have no such attribute)."""
    if getattr(state, "engine", "3d") == "axisymmetric":
        from .axisymmetric.engine import AxisymmetricEngine
        return AxisymmetricEngine()
    from .engine3d import QuadrantEngine
    return QuadrantEngine()
