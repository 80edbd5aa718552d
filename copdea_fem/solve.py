"""The pipeline of ``copdea-fem solve``: study -> mesh -> prestress -> modes -> files.

The stages run here for both engines (``mesh.engine``): the 3-D quadrant below and
the axisymmetric engine of :mod:`copdea_fem.axisymmetric` (its own per-order stages);
assembly lives in :mod:`coupled` / :mod:`axisymmetric.operators`, factorisations and
band solves in :mod:`eigen`, classification and dry matching in :mod:`modes`, every
file in :mod:`output`.

Library entry points used by the CLI, the benchmarks and the tests:
:func:`prepare_mesh`, :func:`dry_modes`, :func:`run_solve`, :func:`run_force`.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import output

from .geometry import GeometrySpec, load_mesh
from .linearise import linearised_operators
from .modes import ModeSampler, classify_modes
from .prestress import force_displacement, solve_prestress
from .study import Study, StudyError, check_air_lift, engine_of


@dataclass
class Timings:
    """Wall time per pipeline stage [s]."""

    seconds: dict = field(default_factory=dict)

    @contextlib.contextmanager
    def stage(self, name: str):
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start


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


def _quiet(message: str) -> None:
    pass


def _task_manager():
    import ngsolve as ngs
    return ngs.TaskManager()


def _single_threaded_blas():
    """BLAS on one thread for the eigen stage: SuperLU's triangular solves call BLAS
    on small supernode blocks, where a second thread costs more than it brings
    (coupled sectors of G1, default mesh: 12.0 s on one BLAS thread, 17.7 s on two)."""
    from threadpoolctl import threadpool_limits
    return threadpool_limits(limits=1, user_api="blas")


def _return_freed_memory() -> None:
    """Hand the heap's freed pages back to the system (glibc ``malloc_trim``; a no-op where
    there is none).  Cutting the sector pencils out of the whole-space matrices leaves
    ~175 MB of freed temporaries in the heap on the 0.65 m drum, under the LU factors
    that come next."""
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _workers(pencils: list, memory_gb: float) -> int:
    """Worker threads for independent sector solves of ``pencils``: one per usable core,
    as many as the sectors' estimated LU factors fit into ``memory_gb``
    (:func:`copdea_fem.eigen.factor_memory_estimate`).  Every back-end releases the GIL
    in its factorisations and solves (NGSolve's UMFPACK and PARDISO, and SciPy's
    SuperLU 5), so the threads share the cores."""
    from .eigen import factor_memory_estimate
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    largest = max((factor_memory_estimate(pencil) for pencil in pencils), default=0.0)
    fitting = int(memory_gb * 1e9 // largest) if largest > 0 else len(pencils)
    return max(1, min(len(pencils), cores or 1, fitting))


def require_backend(study: Study) -> None:
    """Reject an ``eigen.backend`` this machine cannot run, before any meshing."""
    from .eigen import available_backends, backend_available
    backend = study["eigen"]["backend"]
    if not backend_available(backend):
        raise StudyError(f"eigen.backend = {backend!r} is not available on this machine "
                         f"(pardiso needs Intel MKL: pip install mkl); allowed here: "
                         f"{', '.join(available_backends())}")


def prepare_mesh(study: Study, with_air: bool | None = None, cache_dir=None, progress=_quiet):
    """The mesh of the study's engine: the meridian (r, z) mesh of the axisymmetric engine
    (it always holds the air; not cached), else the (cached) 3-D mesh; ``cache_dir=None``:
    :func:`geometry.mesh_cache_dir`."""
    if engine_of(study) == "axisymmetric":
        from .axisymmetric.engine import prepare_meridian
        return prepare_meridian(study, progress)
    spec = GeometrySpec.from_study(study, with_air=with_air)
    return load_mesh(spec, study["mesh"]["curve_order"], cache_dir=cache_dir, progress=progress)


def make_prestress_solver(study: Study, mesh, progress=None):
    """The Newton solver of the study's engine on ``mesh`` (:func:`prepare_mesh`)."""
    if engine_of(study) == "axisymmetric":
        from .axisymmetric.prestress import make_axisymmetric_solver
        return make_axisymmetric_solver(study, mesh, progress)
    from .prestress import make_solver
    return make_solver(study, mesh, progress)


def dry_modes(study: Study, mesh=None, progress=_quiet, timings: Timings | None = None,
              cache_dir=None, solver=None, initial_shifts=None):
    """Prestress and dry (in-vacuo) modes in the study's band: (state, modes, eigen result).

    Sweeps pass ``solver`` (a :class:`copdea_fem.prestress.MembraneSolver` on
    ``mesh``: the prestress continues from its current equilibrium) and
    ``initial_shifts`` (``[(sigma [rad^2/s^2], k), ...]``, see
    :func:`copdea_fem.eigen.solve_band`); the defaults solve from scratch.
    """
    timings = timings or Timings()
    require_backend(study)
    if engine_of(study) == "axisymmetric":
        from .axisymmetric.engine import axisymmetric_dry_modes
        with _single_threaded_blas():     # 2-D problems: NGSolve's TaskManager only costs here
            return axisymmetric_dry_modes(study, mesh, progress, timings, solver, initial_shifts)
    with _task_manager():
        if mesh is None:
            with timings.stage("mesh"):
                mesh = prepare_mesh(study, with_air=study["air"]["enabled"],
                                    cache_dir=cache_dir, progress=progress)
        with timings.stage("prestress"):
            progress("prestress (Newton, load steps in z then V_b) ...")
            state = solve_prestress(study, mesh, progress=progress, solver=solver)
        with timings.stage("assembly"):
            operators = linearised_operators(state, study)
        eigen = study["eigen"]
        with timings.stage("eigen"), _single_threaded_blas():
            from .eigen.damped import solve_structural_band
            from .linearise import operator_damping
            progress(f"dry modes in [{eigen['f_min']:g}, {eigen['f_max']:g}] Hz "
                     f"({operators.size} unknowns) ...")
            # damping keys: the quadratic/rational step in omega (eigen.damped), else linear
            result = solve_structural_band(
                operators.stiffness, operators.mass, eigen["f_min"], eigen["f_max"],
                operator_damping(operators, study),
                damped_imag_hz=eigen["max_damping_ratio"] * eigen["f_max"],
                backend=eigen["backend"], max_modes=eigen["max_modes"], hermitian=True,
                residual_tol=eigen["residual_tol"], progress=progress,
                initial_shifts=initial_shifts)
        with timings.stage("classify"):
            modes = classify_modes(operators, result, ModeSampler(state))
    return state, modes, result


@dataclass
class CoupledSolution:
    """What :func:`coupled_modes` returns: coupled and dry modes on one mesh."""

    state: object
    modes: list              # coupled modes (structural and air), sorted by Re f
    pressures: list          # pressure vector [Pa, free DOFs] of each coupled mode
    dry_modes: list
    dry_partner_hz: dict     # index in modes -> dry partner frequency [Hz]
    eigen: object            # eigen.SectorBandResults: the band result of each sector
    operators: list          # coupled.CoupledOperators of each sector, in solve order


def coupled_modes(study: Study, mesh=None, progress=_quiet, timings: Timings | None = None,
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
    from .coupled import assemble_coupled
    from .eigen import SectorBandResults
    from .eigen.damped import solve_structural_band
    from .linearise import membrane_matrices, operator_damping
    from .modes import assign_labels, coupled_mode_list, match_dry

    timings = timings or Timings()
    require_backend(study)
    check_air_lift(study)
    if engine_of(study) == "axisymmetric":
        from .axisymmetric.engine import axisymmetric_coupled_modes
        with _single_threaded_blas():     # 2-D problems: NGSolve's TaskManager only costs here
            return axisymmetric_coupled_modes(study, mesh, progress, timings, solver,
                                              initial_shifts)
    eigen = study["eigen"]
    band = dict(backend=eigen["backend"], max_modes=eigen["max_modes"],
                residual_tol=eigen["residual_tol"])
    initial_shifts = initial_shifts or {}
    with _task_manager():
        if mesh is None:
            with timings.stage("mesh"):
                mesh = prepare_mesh(study, with_air=True, cache_dir=cache_dir, progress=progress)
        with timings.stage("prestress"):
            progress("prestress (Newton, load steps in z then V_b) ...")
            state = solve_prestress(study, mesh, progress=progress, solver=solver)
        with timings.stage("assembly"):
            matrices = membrane_matrices(state)
            coupled_forms = assemble_coupled(study, mesh, state, progress=progress)
        sectors = []
        with timings.stage("assembly"):
            for sector in state.symmetry.sectors:
                operators = linearised_operators(state, study, sector, matrices)
                sectors.append((sector, operators, coupled_forms.restrict(operators)))
            coupled_forms.release()
            _return_freed_memory()
    # outside the TaskManager: its workers would compete with the sector threads

    def solve_sector(sector, operators, coupled):
        """Dry partner band and coupled band of one sector (runs in a worker thread)."""
        where = "" if sector is None else f"{sector.name}: "

        def say(message):
            progress(where + message)

        say(f"dry modes on the same mesh ({operators.size} unknowns) ...")
        # damping keys: the quadratic/rational step in omega (eigen.damped), else linear
        damping = operator_damping(operators, study)
        dry_result = solve_structural_band(
            operators.stiffness, operators.mass, eigen["f_min"], eigen["f_max"] * 1.5,
            damping, damped_imag_hz=eigen["max_damping_ratio"] * eigen["f_max"] * 1.5,
            hermitian=True, progress=say, **band)
        # wet modes lie below their dry partners: the dry count is the first run's k
        expected = int(np.count_nonzero(dry_result.freq_hz <= 1.1 * eigen["f_max"])) + 2
        say(f"coupled modes in [{eigen['f_min']:g}, {eigen['f_max']:g}] Hz "
            f"({coupled.stiffness.shape[0]} unknowns) ...")
        key = "all" if sector is None else sector.name
        plan = initial_shifts.get(key) if isinstance(initial_shifts, dict) else initial_shifts
        result = solve_structural_band(
                            coupled.stiffness, coupled.mass, eigen["f_min"], eigen["f_max"],
                            None if damping is None else damping.embedded(
                                coupled.membrane_index, coupled.stiffness.shape[0]),
                            hermitian=False, factorize=coupled.factorize,
                            max_imag_hz=eigen["max_damping_ratio"] * eigen["f_max"],
                            initial_shifts=plan, start_modes=expected, progress=say, **band)
        return key, dry_result, result

    with timings.stage("eigen"), _single_threaded_blas():
        # every back-end releases the GIL in its factorisations and solves: sectors run
        # side by side on the cores
        workers = _workers([coupled.stiffness for _, _, coupled in sectors],
                           eigen["factor_memory_gb"])
        with ThreadPoolExecutor(max_workers=workers) as pool:
            solved = list(pool.map(lambda item: solve_sector(*item), sectors))
    modes, pressures, dry, results = [], [], [], {}
    with timings.stage("classify"), _task_manager():
        sampler = ModeSampler(state)
        for (sector, operators, coupled), (key, dry_result, result) in zip(sectors, solved):
            dry += classify_modes(operators, dry_result, sampler)
            sector_modes, sector_pressures = coupled_mode_list(
                coupled, result, study["air"]["min_membrane_energy"], sampler)
            modes += sector_modes
            pressures += sector_pressures
            results[key] = result
        order = sorted(range(len(modes)), key=lambda k: (modes[k].freq_hz, k))
        modes, pressures = [modes[k] for k in order], [pressures[k] for k in order]
        for index, mode in enumerate(modes):
            mode.index = index
        assign_labels([mode for mode in modes if mode.kind != "air"])
        assign_labels(dry)
        partners = match_dry(modes, dry, matrices[1])
    return CoupledSolution(state, modes, pressures, dry,
                           {k: mode.freq_hz for k, mode in partners.items()},
                           SectorBandResults(results), [coupled for _, _, coupled in sectors])


def run_solve(study: Study, out_dir: str | Path | None = None, progress=_quiet,
              cache_dir=None) -> SolveResult:
    """Full ``solve``: prestress, modes (coupled when ``air.enabled``), result files."""
    timings = Timings()
    coupled = None
    if study["air"]["enabled"]:
        coupled = coupled_modes(study, progress=progress, timings=timings, cache_dir=cache_dir)
        state, modes, eigen_result = coupled.state, coupled.modes, coupled.eigen
        rows = output.mode_rows(modes, coupled.dry_partner_hz)
    else:
        state, modes, eigen_result = dry_modes(study, progress=progress, timings=timings,
                                               cache_dir=cache_dir)
        rows = output.mode_rows(modes)
    result = SolveResult(study, state, modes, rows, timings, eigen_result, coupled=coupled)
    if out_dir is not None:
        threads = contextlib.nullcontext() if engine_of(study) == "axisymmetric" else \
            _task_manager()
        with timings.stage("output"), threads:
            progress("writing results ...")
            output.write_results(result, Path(out_dir))
        result.out_dir = Path(out_dir)
    return result


def run_force(study: Study, z_values, voltages, out_dir: str | Path | None = None,
              progress=_quiet, cache_dir=None) -> np.ndarray:
    """Static F(z) [N] at each voltage (Fig. 4b); writes force_displacement.csv/.png."""
    threads = contextlib.nullcontext() if engine_of(study) == "axisymmetric" else _task_manager()
    with threads:
        mesh = prepare_mesh(study, with_air=False, cache_dir=cache_dir, progress=progress)
        forces = force_displacement(study, mesh, z_values, voltages, progress=progress,
                                    new_solver=make_prestress_solver)
    if out_dir is not None:
        output.write_force_results(study, Path(out_dir), z_values, voltages, forces)
    return forces
