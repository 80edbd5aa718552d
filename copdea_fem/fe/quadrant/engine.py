"""The 3-D engine (``mesh.engine: 3d``) behind :class:`copdea_fem.fe.engines.Engine`.

A 3-D mesh of the membrane (and the air): the whole plane for dry modes, a quadrant
for coupled ones (``mesh.symmetry: quarter``, :mod:`copdea_fem.fe.symmetry`: the four
mirror-symmetry sectors are solved apart, side by side on the cores, and merged).
Assembly lives in :mod:`copdea_fem.fe.coupled` / :mod:`copdea_fem.fe.linearise`, the band
solves in :mod:`copdea_fem.fe.eigen` (configured once: :class:`copdea_fem.fe.bands.BandSolver`),
classification, labels and dry matching in :mod:`copdea_fem.fe.modes`.
"""

from __future__ import annotations

import ctypes
import logging
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from copdea_fem.fe.bands import BandSolver, coupled_start_modes
from copdea_fem.fe.cavity import without_static_solution
from copdea_fem.fe.forced.problem import DrivenPart, band_parts
from copdea_fem.fe.linearise import linearised_operators, operator_damping
from copdea_fem.fe.modes import ModeSampler, assign_labels, classify_modes
from copdea_fem.fe.prestress import solve_prestress
from copdea_fem.fe.quadrant.geometry import GeometrySpec, estimate_size, study_mesh
from copdea_fem.fe.quadrant.labels import label_cavity_orders, name_coupled_modes
from copdea_fem.fe.solution import CoupledSolution
from copdea_fem.progress import Timings, carried, single_threaded_blas, tagged, tagging

logger = logging.getLogger(__name__)

def _say(message: str) -> None:
    """A progress line with the thread's prefix (:func:`copdea_fem.progress.tagging`)."""
    logger.info(tagged(message))


def task_manager():
    import ngsolve as ngs
    return ngs.TaskManager()


def return_freed_memory() -> None:
    """Hand the heap's freed pages back to the system (glibc ``malloc_trim``; a no-op where
    there is none).  Cutting the sector pencils out of the whole-space matrices leaves
    ~175 MB of freed temporaries in the heap on the 0.65 m drum, under the LU factors
    that come next."""
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):
        pass


def sector_workers(pencils: list, memory_gb: float) -> int:
    """Worker threads for independent sector solves of ``pencils``: one per usable core,
    as many as the sectors' estimated LU factors fit into ``memory_gb``
    (:func:`copdea_fem.fe.eigen.factor_memory_estimate`).  Every back-end releases the GIL
    in its factorisations and solves (NGSolve's UMFPACK and PARDISO, and SciPy's
    SuperLU 5), so the threads share the cores."""
    from copdea_fem.fe.eigen import factor_memory_estimate
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    largest = max((factor_memory_estimate(pencil) for pencil in pencils), default=0.0)
    fitting = int(memory_gb * 1e9 // largest) if largest > 0 else len(pencils)
    return max(1, min(len(pencils), cores or 1, fitting))


def sampled_shapes(state, modes) -> np.ndarray:
    """(normal, radial, hoop) displacement of each mode on the normalised polar grid.

    :class:`copdea_fem.fe.modes.ModeSampler` samples at r = r_i + (r_o - r_i)(k + 1/2)/n_r:
    the same normalised radius for every geometry, so shapes of different meshes
    (an inner-radius sweep) compare point by point.  Area weights r dr dtheta are
    folded in as sqrt(r / r_o) (dr and dtheta are equal at all samples of one point).
    """
    from copdea_fem.fe.modes import ModeSampler
    sampler = ModeSampler(state)
    weights = np.sqrt(sampler.radii / state.outer_radius)[None, :, None]
    rows = [(sampler.components(mode.vector, mode.sector) * weights).ravel() for mode in modes]
    return np.array(rows) if rows else np.zeros((0, 3 * sampler.shape[0] * sampler.shape[1]))


class QuadrantEngine:
    """The 3-D engine: whole-plane dry modes, quadrant sectors for coupled modes."""

    name = "3d"

    def mesh_key(self, study, with_air: bool):
        """What the 3-D mesh depends on: its geometry spec (with or without air)."""
        return GeometrySpec.from_study(study, with_air=with_air).key(), \
            study.mesh.curve_order

    def space_key(self, study, with_air: bool) -> str:
        """The FE space of the modes' vectors: its mesh's geometry key, order and curving."""
        spec = GeometrySpec.from_study(study, with_air=with_air)
        return f"fe:{spec.key()}:order{study.mesh.order}:curve{study.mesh.curve_order}"

    def prepare_mesh(self, study, with_air=None, cache_dir=None):
        """The (cached) 3-D mesh; ``cache_dir=None``:
        :func:`copdea_fem.fe.quadrant.geometry.mesh_cache_dir`."""
        return study_mesh(study, with_air=with_air, cache_dir=cache_dir)

    def estimate_size(self, study):
        """(elements, unknowns) of the 3-D mesh
        (:func:`copdea_fem.fe.quadrant.geometry.estimate_size`)."""
        mesh = study.mesh
        return estimate_size(GeometrySpec.from_study(study), mesh.order,
                             mesh.pressure_order)

    def forced_problem(self, study):
        """The even-even symmetry sector, forced (:mod:`copdea_fem.fe.quadrant.forced`)."""
        from copdea_fem.fe.quadrant.forced import prepare_quadrant
        return prepare_quadrant(study)

    def driven_sector(self):
        """The even-even sector (:data:`copdea_fem.fe.quadrant.forced.QUADRANT_SECTOR`)."""
        from copdea_fem.fe.quadrant.forced import QUADRANT_SECTOR
        return QUADRANT_SECTOR

    def driven_parts(self, solution, study) -> list[DrivenPart]:
        """The symmetry sectors of a solve (or its whole mesh) with their pencils: the coupled
        operators the solve kept (with air), else the whole plane's dry operators."""
        from copdea_fem.fe.forced.harmonic import DryPencil
        from copdea_fem.fe.linearise import linearised_operators

        bands = band_parts(solution.eigen)
        if solution.coupled is not None:
            pencils = list(solution.coupled.operators)
        else:
            pencils = [DryPencil(linearised_operators(solution.state, study))]
        return [DrivenPart(key, pencil, band, sector=pencil.membrane.sector)
                for (key, band), pencil in zip(bands.items(), pencils)]

    def electrode_forcing(self, state, part: DrivenPart, electrode) -> np.ndarray:
        """The forcing [N/V] of ``electrode`` on the part's membrane unknowns: the sector's
        of the folded weight (:func:`copdea_fem.fe.quadrant.forced.sector_forcing`)."""
        from copdea_fem.fe.quadrant.forced import sector_forcing
        return sector_forcing(state, part.pencil.membrane, electrode)

    def point_sampler(self, state, positions):
        """The fields of ``state`` at points of the prestressed device
        (:class:`copdea_fem.fe.quadrant.points.QuadrantPoints`)."""
        from copdea_fem.fe.quadrant.points import QuadrantPoints
        return QuadrantPoints(state, positions)

    def prestressed_positions(self, state, reference_xy, disc_z: float) -> np.ndarray:
        """Where reference points lie on the prestressed device
        (:meth:`copdea_fem.fe.points.PointSampler.prestressed_positions`)."""
        from copdea_fem.fe.quadrant.points import QuadrantPoints
        return QuadrantPoints.prestressed_positions(state, reference_xy, disc_z)

    def tracking_arrays(self, state, modes, needs_sampling: bool) -> dict:
        """Membrane vectors of the device and M times them (M the pipeline's own,
        :func:`copdea_fem.fe.linearise.membrane_matrices`, cached on the state), and the
        sampled shapes when asked."""
        from copdea_fem.fe.linearise import membrane_matrices
        vectors = np.column_stack([mode.vector for mode in modes]) if modes else \
            np.zeros((state.space.ndof, 0))
        weighted = membrane_matrices(state)[1] @ vectors
        if state.symmetry.quarter:   # device vectors: sectors orthogonal (symmetry doc)
            signatures = np.array([mode.sector.signature() for mode in modes]).reshape(-1, 4)
            vectors = np.vstack([vectors * column for column in signatures.T])
            weighted = np.vstack([weighted * column for column in signatures.T])
        arrays = {"vectors": vectors, "weighted": weighted}
        if needs_sampling:
            arrays["sampled"] = sampled_shapes(state, modes)
        return arrays

    def prestress_solver(self, study, mesh):
        from copdea_fem.fe.prestress import make_solver
        return make_solver(study, mesh)

    def threads(self):
        """NGSolve's TaskManager for the output and force stages."""
        return task_manager()

    def output(self, state, modes=()):
        """The result fields of ``state`` for ParaView and the API
        (:class:`copdea_fem.fe.quadrant.fields.QuadrantOutput`)."""
        from copdea_fem.fe.quadrant.fields import QuadrantOutput
        return QuadrantOutput(state, modes)

    def dry_modes(self, study, mesh, timings=None, solver=None,
                  initial_shifts=None, band: BandSolver | None = None):
        """Prestress and dry modes of the whole plane: (state, modes, eigen result)."""
        timings = timings or Timings()
        band = band or BandSolver.from_study(study)
        with task_manager():
            with timings.stage("prestress"):
                logger.info("prestress (Newton, load steps in z then V_b) ...")
                state = solve_prestress(study, mesh, solver=solver)
            with timings.stage("assembly"):
                operators = linearised_operators(state, study)
            with timings.stage("eigen"), single_threaded_blas():
                logger.info(f"dry modes in [{band.f_min:g}, {band.f_max:g}] Hz "
                            f"({operators.size} unknowns) ...")
                # damping keys: the quadratic/rational step in omega (copdea_fem.fe.eigen.damped)
                result = band.solve(operators.stiffness, operators.mass, band.f_min,
                                    band.f_max, damping=operator_damping(operators, study),
                                    initial_shifts=initial_shifts)
            with timings.stage("classify"):
                modes = classify_modes(operators, result, ModeSampler(state))
        return state, modes, result

    def coupled_modes(self, study, mesh, timings=None, solver=None,
                      initial_shifts=None, band: BandSolver | None = None) -> CoupledSolution:
        """Prestress, dry partners and coupled modes, per symmetry sector on a quadrant
        mesh (:func:`copdea_fem.fe.pipeline.coupled_modes`)."""
        from copdea_fem.fe.coupled import assemble_coupled
        from copdea_fem.fe.eigen import SectorBandResults
        from copdea_fem.fe.linearise import membrane_matrices
        from copdea_fem.fe.modes import coupled_mode_list, match_dry

        timings = timings or Timings()
        band = band or BandSolver.from_study(study)
        initial_shifts = initial_shifts or {}
        with task_manager():
            with timings.stage("prestress"):
                logger.info("prestress (Newton, load steps in z then V_b) ...")
                state = solve_prestress(study, mesh, solver=solver)
            with timings.stage("assembly"):
                matrices = membrane_matrices(state)
                coupled_forms = assemble_coupled(study, mesh, state)
            sectors = []
            with timings.stage("assembly"):
                for sector in state.symmetry.sectors:
                    operators = linearised_operators(state, study, sector, matrices)
                    sectors.append((sector, operators, coupled_forms.restrict(operators)))
                coupled_forms.release()
                return_freed_memory()
        # outside the TaskManager: its workers would compete with the sector threads
        context = carried()

        def solve_sector(sector, operators, coupled):
            """Dry partner band and coupled band of one sector (runs in a worker thread)."""
            where = "" if sector is None else f"{sector.name}: "
            with context(), tagging(where):
                return _solve_sector_band(sector, operators, coupled)

        def _solve_sector_band(sector, operators, coupled):
            say = _say
            say(f"dry modes on the same mesh ({operators.size} unknowns) ...")
            damping = operator_damping(operators, study)    # None: undamped
            dry_result = band.solve(operators.stiffness, operators.mass, band.f_min,
                                    band.dry_partner_top, damping=damping)
            # wet modes lie below their dry partners: the dry count is the first run's k
            expected = coupled_start_modes(dry_result.freq_hz, band.f_min, band.f_max)
            say(f"coupled modes in [{band.f_min:g}, {band.f_max:g}] Hz "
                f"({coupled.stiffness.shape[0]} unknowns) ...")
            key = "all" if sector is None else sector.name
            plan = initial_shifts.get(key) if isinstance(initial_shifts, dict) else initial_shifts
            result = band.solve(coupled.stiffness, coupled.mass, band.f_min, band.f_max,
                                hermitian=False, factorize=coupled.factorize,
                                damping=None if damping is None else damping.embedded(
                                    coupled.membrane_index, coupled.stiffness.shape[0]),
                                max_imag_hz=band.max_imag_hz, initial_shifts=plan,
                                start_modes=expected)
            if study.geometry.enclosure != "none":
                result = without_static_solution(result, band.f_max)
            return key, dry_result, result

        with timings.stage("eigen"), single_threaded_blas():
            # every back-end releases the GIL in its factorisations and solves: sectors run
            # side by side on the cores
            workers = sector_workers([coupled.stiffness for _, _, coupled in sectors],
                                     band.factor_memory_gb)
            with ThreadPoolExecutor(max_workers=workers) as pool:
                solved = list(pool.map(lambda item: solve_sector(*item), sectors))
        modes, pressures, dry, results = [], [], [], {}
        with timings.stage("classify"), task_manager():
            sampler = ModeSampler(state)
            cavity = None
            if study.geometry.enclosure != "none":
                from copdea_fem.fe.quadrant.cavity import QuadrantCavitySampler
                cavity = QuadrantCavitySampler(sectors[0][2].pressure_space,
                                               GeometrySpec.from_study(study))
            for (sector, operators, coupled), (key, dry_result, result) in zip(sectors, solved):
                dry += classify_modes(operators, dry_result, sampler)
                sector_modes, sector_pressures = coupled_mode_list(
                    coupled, result, study.air.min_membrane_energy, sampler)
                if cavity is not None:
                    label_cavity_orders(cavity, sector, coupled, sector_modes, sector_pressures)
                modes += sector_modes
                pressures += sector_pressures
                results[key] = result
            order = sorted(range(len(modes)), key=lambda k: (modes[k].freq_hz, k))
            modes, pressures = [modes[k] for k in order], [pressures[k] for k in order]
            for index, mode in enumerate(modes):
                mode.index = index
            name_coupled_modes(modes, None if cavity is None else dry, matrices[1])
            assign_labels(dry)
            partners = match_dry(modes, dry, matrices[1])
        return CoupledSolution(state, modes, pressures, dry,
                               {k: mode.freq_hz for k, mode in partners.items()},
                               SectorBandResults(results), [coupled for _, _, coupled in sectors])
