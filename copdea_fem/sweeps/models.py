"""The models a sweep point runs (dry FE, coupled FE, reduced ring model) and one point's solve."""

from __future__ import annotations

import math
import os
import re
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from copdea_fem.study import Study
from copdea_fem.sweeps.spec import ReuseSettings, SweepPoint

if TYPE_CHECKING:
    from copdea_fem.fe import Engine


@dataclass
class PointResult:
    """What one point produced: a JSON-able record and the arrays for tracking."""

    point_id: str
    status: str                     # "ok" or "failed"
    record: dict
    arrays: dict = field(default_factory=dict)


@dataclass
class ChainState:
    """What a chain keeps between its points (worker-local, never pickled)."""

    context_key: str | None = None
    solver: object = None
    last_point: str | None = None
    last_eigen: object = None       # BandResult of last_point
    last_band: tuple | None = None


_MESHES: dict = {}                  # process-level mesh cache: (geometry key, curve order) -> mesh
_MESH_CACHE_SIZE = 4
_NGSOLVE_LOCK = threading.Lock()    # NGSolve solves in one thread at a time per process


def _mesh_for(study: Study, engine: Engine, with_air: bool, reuse: bool, timings):
    key = engine.mesh_key(study, with_air)
    if reuse and key in _MESHES:
        return _MESHES[key], True
    with timings.stage("mesh"):
        mesh = engine.prepare_mesh(study, with_air=with_air)
    if reuse:
        while len(_MESHES) >= _MESH_CACHE_SIZE:
            _MESHES.pop(next(iter(_MESHES)))
        _MESHES[key] = mesh
    return mesh, False


def shift_plan(result, margin_fraction: float = 0.1, margin_modes: int = 4) -> list:
    """Start shifts for a neighbouring point from a :class:`copdea_fem.fe.eigen.BandResult`.

    Each shift ``sigma`` [rad^2/s^2] of the neighbour asks for the number of
    its band eigenvalues nearest to it, plus ``max(margin_modes,
    margin_fraction * count)``: the count moves by a few between neighbours
    (modes entering/leaving the band), and one extra run to extend a shift
    costs more than a few extra Ritz vectors.
    """
    if hasattr(result, "by_sector"):     # a coupled solve on a quadrant: a plan per sector
        return {name: shift_plan(part, margin_fraction, margin_modes)
                for name, part in result.by_sector.items()}
    shifts = np.asarray(result.shifts, dtype=float)
    if shifts.size == 0:
        return []
    values = np.asarray(result.eigenvalues).real
    nearest = np.argmin(np.abs(values[:, None] - shifts[None, :]), axis=1) if values.size else \
        np.zeros(0, int)
    plan = []
    for j, sigma in enumerate(shifts):
        count = int(np.count_nonzero(nearest == j))
        if count == 0 and j > 0:
            continue
        plan.append((float(sigma), count + max(margin_modes, math.ceil(margin_fraction * count))))
    return plan


class _FEModel:
    """The dry FE model per point (the coupled one derives from it)."""

    name = "dry"
    with_air = False

    def modes(self, study, **reuse):
        """(state, modes, eigen result) of one point: :func:`copdea_fem.fe.dry_modes`."""
        from copdea_fem.fe import dry_modes
        return dry_modes(study, **reuse)

    def check_available(self, sweep) -> None:
        """Refuse a factorisation back-end this machine lacks before any point runs."""
        from copdea_fem.fe import require_backend
        for point in sweep.points:
            require_backend(point.study)

    def solve(self, point: SweepPoint, chain: ChainState, reuse: ReuseSettings,
              needs_sampling: bool) -> PointResult:
        from copdea_fem.progress import Timings
        study, engine = point.study, point.engine     # resolved once for the point
        timings = Timings()
        start = time.perf_counter()
        mesh, mesh_reused = _mesh_for(study, engine, self.with_air, reuse.mesh, timings)
        continued_from = None
        if reuse.prestress and chain.solver is not None and \
                chain.context_key == point.context_key:
            solver, continued_from = chain.solver, chain.last_point
            # from the neighbour's equilibrium one adaptive step per load axis
            # (halved on failure up to prestress.max_cuts times) instead of the path
            solve_study = study.replace({"prestress.z_steps": 1, "prestress.voltage_steps": 1})
        else:
            chain.solver = None
            with timings.stage("solver_setup"):
                solver = engine.prestress_solver(study, mesh)
            solve_study = study
        iterations_before = solver.newton_iterations
        band = (study.eigen.f_min, study.eigen.f_max)
        plan = shift_plan(chain.last_eigen) if reuse.shifts and chain.last_eigen is not None \
            and chain.last_band == band else None
        try:
            state, modes, eigen_result = self.modes(solve_study, mesh=mesh,
                                                    timings=timings, solver=solver,
                                                    initial_shifts=plan, engine=engine)
        except BaseException:
            # the solver may sit at a failed load: the next point starts afresh
            chain.solver = chain.last_eigen = chain.last_point = None
            raise
        modes = [mode for mode in modes if mode.kind != "air"]   # air/PML-only modes
        with timings.stage("tracking_data"):
            arrays = engine.tracking_arrays(state, modes, needs_sampling)
        chain.context_key, chain.solver = point.context_key, solver
        chain.last_point, chain.last_eigen, chain.last_band = point.point_id, eigen_result, band
        seconds = dict(timings.seconds)
        seconds["total"] = time.perf_counter() - start
        record = {
            "modes": [_mode_record(mode) for mode in modes],
            "timings_s": seconds,
            "reuse": {"mesh": mesh_reused, "prestress_from": continued_from,
                      "initial_shifts": plan is not None},
            "prestress": {"newton_iterations": state.newton_iterations - iterations_before,
                          "disc_force_n": state.disc_force, "z_m": state.z,
                          "voltage_v": state.voltage},
            "eigen": {"unknowns": int(eigen_result.unknowns),
                      "factorisations": int(eigen_result.n_factorisations),
                      "shifts_hz": [float(f) for f in eigen_result.shift_freq_hz],
                      "factorisation_s": float(eigen_result.factorisation_seconds),
                      "iteration_s": float(eigen_result.iteration_seconds)},
            "space": point.space_key,
        }
        return PointResult(point.point_id, "ok", record, arrays)


class _CoupledModel(_FEModel):
    """The fully-coupled membrane-air FE step (``copdea_fem.fe.pipeline.coupled_modes``).

    Every point gets ``air.enabled: true`` and the mesh with air.  The modes'
    ``vector`` (membrane-space coefficients) is tracked like the dry ones;
    air/PML-only modes (kind ``air``) are left out of the sweep.  Reuse as for
    the dry model: the mesh, the prestress continuation and the neighbour's
    coupled shifts.
    """

    name = "coupled"
    with_air = True

    def modes(self, study, **reuse):
        """(state, modes, eigen result) of one point:
        :func:`copdea_fem.fe.coupled_modes`."""
        from copdea_fem.fe import coupled_modes
        solution = coupled_modes(study, **reuse)
        return solution.state, solution.modes, solution.eigen


class _ReducedModel:
    """The ring model (Sect. 3.2): dry modes of eq. (15) at each point, no state to reuse."""

    name = "reduced"

    def check_available(self, sweep) -> None:
        pass                       # pure NumPy/SciPy: nothing optional to check

    def solve(self, point: SweepPoint, chain: ChainState, reuse: ReuseSettings,
              needs_sampling: bool) -> PointResult:
        from copdea_fem.reduced.model import operating_point, ring_model_of
        study = point.study
        start = time.perf_counter()
        ring_model = ring_model_of(study)
        linearisation, basis, _ = operating_point(ring_model, study.load.z,
                                                  study.load.voltage,
                                                  study.effects.maxwell_scale)
        band = study.eigen
        modes = [mode for mode in basis.modes
                 if band.f_min <= mode.frequency_hz <= band.f_max]
        vectors = np.column_stack([mode.shape for mode in modes]) if modes else \
            np.zeros((linearisation.mass_matrix.shape[0], 0))
        record = {
            "modes": [{"label": mode.label, "m": 0, "n": _reduced_order(mode.label),
                       "kind": mode.kind, "freq_hz": float(mode.frequency_hz),
                       "freq_im_hz": 0.0} for mode in modes],
            "timings_s": {"total": time.perf_counter() - start},
            "reuse": {"mesh": False, "prestress_from": None, "initial_shifts": False},
            "space": point.space_key,
        }
        arrays = {"vectors": vectors, "weighted": linearisation.mass_matrix @ vectors}
        return PointResult(point.point_id, "ok", record, arrays)


def _reduced_order(label: str) -> int:
    digits = re.findall(r"\d+", label)
    return int(digits[-1]) if digits else 0


MODEL_CLASSES = {"dry": _FEModel, "reduced": _ReducedModel, "coupled": _CoupledModel}


def _mode_record(mode) -> dict:
    return {"label": mode.label, "m": int(mode.m), "n": int(mode.n), "kind": mode.kind,
            "freq_hz": float(mode.freq_hz), "freq_im_hz": float(getattr(mode, "freq_im_hz", 0.0)),
            "residual": float(getattr(mode, "residual", 0.0)),
            "modal_mass": float(getattr(mode, "modal_mass", math.nan))}


def solve_point(model_name: str, point: SweepPoint, chain: ChainState, reuse: ReuseSettings,
                needs_sampling: bool) -> PointResult:
    """Solve one point, never raising for a failed solve: the error goes in the record.

    Its steps are not reported (:func:`copdea_fem.progress.quiet_progress`): the sweep
    reports one line per point."""
    from copdea_fem.progress import quiet_progress
    model = MODEL_CLASSES[model_name]()
    base = {"point": point.point_id, "index": list(point.index),
            "parameters": point.overrides, "study_hash": point.study_hash, "model": model_name,
            "worker": f"{socket.gethostname()}:{os.getpid()}"}
    start = time.perf_counter()
    try:
        with _NGSOLVE_LOCK, quiet_progress():
            result = model.solve(point, chain, reuse, needs_sampling)
    except Exception as error:   # a failed point is recorded, the sweep goes on
        record = {**base, "status": "failed", "error": f"{type(error).__name__}: {error}",
                  "error_kind": getattr(error, "kind", type(error).__name__),
                  "timings_s": {"total": time.perf_counter() - start}}
        return PointResult(point.point_id, "failed", record)
    result.record = {**base, "status": "ok", **result.record}
    return result
