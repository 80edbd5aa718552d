"""Parameter sweeps (paper Fig. 11): a base study, a grid over study keys, tracked modes.

``copdea-fem sweep SWEEP.yaml [--out DIR]`` runs every grid point with the
dry FE, the reduced (ring) model or the fully-coupled FE (air + PML),
follows every mode from point to point (:mod:`copdea_fem.tracking`) and
writes one long table plus Fig. 11-style plots.

SWEEP.yaml
----------
::

    name: fig11b_g1_z                   # optional (default: file name)
    description: "..."                  # optional
    study: ../g1_z16_v2.yaml            # base study, relative to this file
    set:                                # optional overrides of the base study
      load.voltage: 2 kV
    model: dry                          # dry | reduced | coupled
    axes:                               # one or several study keys; grid = product
      load.z: 0..18 mm, 10 points       # or "0 mm..18 mm, step 2 mm", a list
                                        # [0 mm, 6 mm, 12 mm] or {start, stop, points|step}
    tracking: {mac_min: 0.3, label_weight: 0.25, frequency_weight: 0.5, pair_tolerance: 0.01}
    execution:                          # optional; CLI options override
      executor: local                   # local | pool | dask
      workers: 2                        # pool processes
      scheduler: null                   # dask scheduler address
      chain_length: auto                # points per continuation chain (auto or >= 1)
      reuse: true                       # or false, or {mesh, prestress, shifts}
    output:
      directory: results/sweeps/<name>
      plots: true
      plot_kinds: [out-of-plane, pumping]

Every point's study is validated before anything is solved; errors are
:class:`SweepError` (a ``ValueError``) naming the key, the value and what is
allowed.

Reuse between neighbouring points (``model: dry``)
---------------------------------------------------
The grid is walked in *continuation order*: axes that change the mesh or the
material (anything outside ``load``, ``eigen``, ``disc``, ``spring``,
``reduced``, ``excitation``, ``effects``, ``output``) outermost, then a
serpentine (boustrophedon) over the rest, so consecutive points differ in one
axis by one step.  Consecutive points with the same *context* (mesh +
material + prestress settings) form a chain; inside a chain

* the mesh is built (or read from ``meshes/``) once per geometry and kept in
  memory (``reuse.mesh``);
* one :class:`copdea_fem.prestress.MembraneSolver` continues from the
  neighbour's equilibrium in a single adaptive load step instead of the full
  z-then-V_b path from the flat state (``reuse.prestress``);
* the band eigensolver starts at the neighbour's shifts asking for as many
  modes as the neighbour found around each (``reuse.shifts``,
  ``solve_band(initial_shifts=...)``); the band is still certified, so a poor
  start costs time, never modes.

The factorisation's symbolic analysis is *not* reused: NGSolve's UMFPACK and
PARDISO wrappers and SciPy's SuperLU redo it inside every factorisation and
expose no numeric-only refactorisation.  Measured on the G1 operator (9054
unknowns, NGSolve's timers, one BLAS thread, one factorisation per point):
symbolic ~0.015 s next to ~0.06 s numeric, i.e. ~0.3 % of a ~5 s continued
point, so there is little to buy (the eigen stage's cost is ARPACK's ~190
solves per point).

Execution
---------
``local`` runs the chains one after the other in this process; ``pool`` runs
chains in worker processes (spawned; each writes its points); ``dask`` sends
each point to an existing Dask cluster as a task that depends on its chain
predecessor and prefers the same worker, which keeps the chain's solver in a
worker-local cache (a worker that lacks it -- restarted, or another one --
solves from scratch: slower, same result).  All three gather into the same
table because tracking runs afterwards, on the stored results, along the
continuation path.

On disk (resumable)::

    OUT/points/<id>/result.json    one per point, written atomically
    OUT/points/<id>/vectors.npz    shapes for the MAC (ok points)
    OUT/sweep.csv                  the long table
    OUT/sweep.json                 per-point status, timings, reuse; track labels
    OUT/sweep.png                  frequency vs the swept parameter (Fig. 11 style)
    OUT/sweep.resolved.yaml        the sweep with every point's values, SI

A point whose ``result.json`` says ``ok`` for the same resolved study (hash)
is not recomputed; failed or stale points are.  A failing point is recorded
with its error and does not stop the sweep.
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import hashlib
import itertools
import json
import math
import os
import re
import socket
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import yaml

from .folders import claim, write_manifest
from .inputs import preview, read_yaml
from .study import (SCHEMA, Study, StudyError, _convert, check_air_lift, load_study,
                    package_versions)
from .tracking import ModeSet, TrackingSettings, TrackingInputError, track_modes

MODELS = ("dry", "reduced", "coupled")
EXECUTORS = ("local", "pool", "dask")
TOP_KEYS = ("name", "description", "study", "set", "model", "axes", "tracking", "execution",
            "output")
# Sections whose keys change neither the mesh nor the membrane solver: points that
# differ only there can continue from each other.
LOAD_LIKE_SECTIONS = ("load", "eigen", "disc", "spring", "reduced", "excitation", "effects",
                      "output")
#: What a sweep folder holds (its manifest lists these; each point folder has its own).
SWEEP_FILES = ("sweep.csv", "sweep.csv.tmp", "sweep.json", "sweep.json.tmp",
               "sweep.resolved.yaml", "sweep.png", "points")
DEFAULT_PLOT_KINDS = ("out-of-plane", "pumping")
KINDS = ("out-of-plane", "in-plane", "pumping", "air")


class SweepError(StudyError):
    """A sweep file value is outside what is allowed; the message names key, value, allowed."""


def _fail(key: str, value: Any, allowed: str, why: str = "") -> SweepError:
    why = f" ({why})" if why else ""
    return SweepError(f"{key} = {preview(value)} is not allowed{why}; allowed: {allowed}")


# --------------------------------------------------------------------------- schema


@dataclass(frozen=True)
class Axis:
    """One swept study key.

    Attributes
    ----------
    key : str
        ``section.key`` of the study schema.
    values : tuple
        SI values in sweep order (numbers; text or bool for choice keys).
    unit : str or None
        SI unit of the values (from the schema).
    display_unit : str or None
        Unit the sweep file used (``kV``, ``mm``), for plots.
    """

    key: str
    values: tuple
    unit: str | None
    display_unit: str | None

    @property
    def changes_context(self) -> bool:
        return self.key.split(".", 1)[0] not in LOAD_LIKE_SECTIONS

    def column(self) -> str:
        """CSV column name: key plus its SI unit, e.g. ``load.voltage_v``."""
        if not self.unit:
            return self.key
        return f"{self.key}_{self.unit.lower().replace('/', '_').replace('^', '')}"

    def display(self, value) -> float:
        """An SI value in the display unit."""
        if not isinstance(value, (int, float)) or not self.display_unit or \
                self.display_unit == self.unit:
            return value
        from .study import _units
        return float(_units().Quantity(value, self.unit).to(self.display_unit).magnitude)

    def format(self, value) -> str:
        """A value as text in the display unit: ``2 kV``, ``12 mm``, ``square``."""
        shown = self.display(value)
        if isinstance(shown, bool) or not isinstance(shown, (int, float)):
            return str(shown)
        unit = self.display_unit or self.unit or ""
        return f"{shown:g} {unit}".rstrip()

    def label(self) -> str:
        unit = self.display_unit or self.unit
        return f"{self.key} [{unit}]" if unit else self.key


@dataclass(frozen=True)
class ReuseSettings:
    """Which work neighbouring points share (``execution.reuse``)."""

    mesh: bool = True
    prestress: bool = True
    shifts: bool = True


@dataclass(frozen=True)
class ExecutionSettings:
    executor: str = "local"
    workers: int = 2
    scheduler: str | None = None
    chain_length: int | str = "auto"
    reuse: ReuseSettings = ReuseSettings()


@dataclass(frozen=True)
class SweepPoint:
    """One grid point: its id, grid index, overrides and validated study."""

    point_id: str
    index: tuple
    overrides: dict
    study: Study
    context_key: str
    space_key: str
    study_hash: str


@dataclass
class Sweep:
    """A validated sweep: the base study, the axes, every point, the path and settings."""

    name: str
    description: str
    source: Path | None
    base: Study
    model: str
    axes: list
    points: list            # grid order
    path: list              # continuation order (point ids)
    tracking: TrackingSettings
    execution: ExecutionSettings
    output_directory: str
    plots: bool
    plot_kinds: tuple
    raw: dict = field(default_factory=dict, repr=False)

    def point(self, point_id: str) -> SweepPoint:
        return self._by_id[point_id]

    def __post_init__(self):
        self._by_id = {p.point_id: p for p in self.points}

    def chains(self, chain_length: int | str | None = None, workers: int = 1) -> list[list[str]]:
        """Runs of the path sharing one context, split into chains of ``chain_length``.

        ``"auto"``: a whole run with one worker, else ``ceil(len(run) / workers)``.
        """
        length = self.execution.chain_length if chain_length is None else chain_length
        runs: list[list[str]] = []
        for point_id in self.path:
            key = self.point(point_id).context_key
            if runs and self.point(runs[-1][-1]).context_key == key:
                runs[-1].append(point_id)
            else:
                runs.append([point_id])
        chains = []
        for run in runs:
            size = (len(run) if workers <= 1 else math.ceil(len(run) / workers)) \
                if length == "auto" else int(length)
            chains += [run[i:i + size] for i in range(0, len(run), max(size, 1))]
        return chains

    def resolved(self) -> dict:
        """The sweep as run: axes in SI, the base study resolved, every point's values."""
        return {"name": self.name, "description": self.description, "model": self.model,
                "axes": {a.key: {"unit": a.unit, "values": list(a.values)} for a in self.axes},
                "tracking": dataclasses.asdict(self.tracking),
                "execution": {**dataclasses.asdict(self.execution)},
                "points": {p.point_id: p.overrides for p in self.points},
                "path": list(self.path),
                "base_study": self.base.as_dict(), "provenance": package_versions()}


def load_sweep(path: str | Path, overrides: dict | None = None) -> Sweep:
    """Read and validate a SWEEP.yaml; ``overrides`` are extra base-study ``--set`` values."""
    path = Path(path)
    raw = read_yaml(path, "sweep file", SweepError)
    return parse_sweep(raw, base_dir=path.parent, name=str(raw.get("name") or path.stem),
                       source=path, overrides=overrides)


def parse_sweep(raw: dict, base_dir: Path | str = ".", name: str = "sweep",
                source: Path | None = None, overrides: dict | None = None) -> Sweep:
    """Validate a raw sweep mapping (see the module docstring) into a :class:`Sweep`."""
    for key in raw:
        if key not in TOP_KEYS:
            raise _fail(key, "...", "keys " + ", ".join(TOP_KEYS), "unknown key")
    model = raw.get("model", "dry")
    if model not in MODELS:
        raise _fail("model", model, "one of " + ", ".join(MODELS))
    base_overrides = _mapping(raw.get("set"), "set")
    axes_raw = _mapping(raw.get("axes"), "axes")
    if not axes_raw:
        raise _fail("axes", raw.get("axes"), "a mapping of one or more study keys to values, "
                    "e.g. {load.voltage: '0..3 kV, 7 points'}")
    for key in axes_raw:
        if key in base_overrides:
            raise _fail(f"set.{key}", base_overrides[key], f"a key that is not swept (it is "
                        f"axes.{key})")
    base = _base_study(raw, Path(base_dir), name, {**base_overrides, **(overrides or {})})
    if model == "dry" and base["air"]["enabled"]:
        raise _fail("air.enabled", True, "false with model: dry (model: coupled couples the air)")
    axes = [_parse_axis(key, value) for key, value in axes_raw.items()]
    tracking = _tracking_settings(_mapping(raw.get("tracking"), "tracking"))
    execution = _execution_settings(_mapping(raw.get("execution"), "execution"))
    output = _mapping(raw.get("output"), "output")
    for key in output:
        if key not in ("directory", "plots", "plot_kinds"):
            raise _fail(f"output.{key}", output[key], "keys output.directory, output.plots, "
                        "output.plot_kinds", "unknown key")
    plots = output.get("plots", True)
    if not isinstance(plots, bool):
        raise _fail("output.plots", plots, "true or false")
    plot_kinds = output.get("plot_kinds", list(DEFAULT_PLOT_KINDS))
    if not isinstance(plot_kinds, list) or not plot_kinds or any(k not in KINDS
                                                                 for k in plot_kinds):
        raise _fail("output.plot_kinds", plot_kinds, "a non-empty list of " + ", ".join(KINDS))
    directory = output.get("directory", f"results/sweeps/{name}")
    if not isinstance(directory, str) or not directory.strip():
        raise _fail("output.directory", directory, "a path")
    points = _expand_grid(base, axes, model)
    path = _continuation_path(points, axes)
    return Sweep(name=name, description=str(raw.get("description", "")), source=source,
                 base=base, model=model, axes=axes, points=points, path=path, tracking=tracking,
                 execution=execution, output_directory=directory, plots=plots,
                 plot_kinds=tuple(plot_kinds), raw=copy.deepcopy(raw))


def _mapping(value, key: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise _fail(key, value, "a mapping")
    return dict(value)


def _base_study(raw: dict, base_dir: Path, name: str, overrides: dict) -> Study:
    study_path = raw.get("study")
    if not isinstance(study_path, str) or not study_path.strip():
        raise _fail("study", study_path, "the path of a base study file, relative to the sweep "
                    "file (e.g. ../g1_z16_v2.yaml)")
    full = Path(study_path) if Path(study_path).is_absolute() else base_dir / study_path
    if not full.exists():
        raise _fail("study", study_path, "an existing study file", f"{full} does not exist")
    try:
        study = load_study(full, overrides=overrides)
    except SweepError:
        raise
    except StudyError as error:
        raise SweepError(f"base study {study_path} with set: {error}") from None
    study.name = name
    return study


_RANGE = re.compile(r"^\s*(?P<start>[^,]+?)\s*\.\.\s*(?P<stop>[^,]+?)\s*,\s*"
                    r"(?:(?P<points>\d+)\s*points?|step\s+(?P<step>.+?))\s*$")
_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")
_MAX_POINTS = 10_000


def _unit_of(text) -> str | None:
    if not isinstance(text, str):
        return None
    match = _NUMBER_UNIT.match(text)
    return match.group(2) or None if match else None


def _parse_axis(key: str, value) -> Axis:
    """Axis values in SI from a range text, a list or a {start, stop, points|step} mapping."""
    section, _, name = key.partition(".")
    if section not in SCHEMA or name not in SCHEMA[section]:
        known = SCHEMA.get(section)
        allowed = ("keys " + ", ".join(f"{section}.{k}" for k in known)) if known else \
            "study keys SECTION.KEY of sections " + ", ".join(SCHEMA)
        raise _fail(f"axes.{key}", value, allowed, "unknown study key")
    spec = SCHEMA[section][name]
    where = f"axes.{key}"
    allowed_forms = ("'START..STOP UNIT, N points', 'START..STOP UNIT, step STEP UNIT', a list "
                     "of values, or {start, stop, points} / {start, stop, step}")
    numeric = spec.kind in (int, float) and not spec.choices
    display_unit = None
    if isinstance(value, str) and numeric:
        match = _RANGE.match(value)
        if not match:
            raise _fail(where, value, allowed_forms)
        start, stop = match.group("start"), match.group("stop")
        start_unit = _unit_of(start)
        display_unit = _unit_of(stop) or start_unit
        if start_unit is None and display_unit and _NUMBER_UNIT.match(start):
            start = f"{start} {display_unit}"
        step = match.group("step")
        if step is not None and _unit_of(step) is None and display_unit and \
                _NUMBER_UNIT.match(step):
            step = f"{step} {display_unit}"
        values = _range_values(where, spec, start, stop, match.group("points"), step)
    elif isinstance(value, dict) and numeric:
        unknown = set(value) - {"start", "stop", "points", "step"}
        if unknown or "start" not in value or "stop" not in value or \
                ("points" in value) == ("step" in value):
            raise _fail(where, value, allowed_forms)
        display_unit = _unit_of(value["stop"]) or _unit_of(value["start"])
        values = _range_values(where, spec, value["start"], value["stop"], value.get("points"),
                               value.get("step"))
    elif isinstance(value, list) and value:
        display_unit = next((u for u in map(_unit_of, value) if u), None)
        values = [_convert_value(where, spec, item) for item in value]
    else:
        raise _fail(where, value, allowed_forms if numeric else
                    f"a non-empty list of values ({spec.allowed()})")
    if len(set(map(repr, values))) != len(values):
        raise _fail(where, value, "distinct values", "a value is repeated")
    if spec.kind is int:
        values = [int(round(v)) for v in values]
    return Axis(key=key, values=tuple(values), unit=spec.unit, display_unit=display_unit)


def _convert_value(where: str, spec, value):
    try:
        return _convert(where, spec, value)
    except StudyError as error:
        raise SweepError(str(error)) from None


def _range_values(where, spec, start, stop, points, step) -> list:
    relaxed = dataclasses.replace(spec, minimum=None, maximum=None, kind=float)
    first = _convert_value(where + " start", relaxed, start)
    last = _convert_value(where + " stop", relaxed, stop)
    if points is not None:
        count = points if isinstance(points, int) and not isinstance(points, bool) else \
            int(points) if isinstance(points, str) and points.isdigit() else None
        if count is None or not 1 <= count <= _MAX_POINTS or (count == 1 and first != last):
            raise _fail(where, points, f"an integer number of points in [2, {_MAX_POINTS}] "
                        "(1 only when start = stop)")
        values = list(np.linspace(first, last, count))
    else:
        increment = _convert_value(where + " step", relaxed, step)
        if not increment > 0:
            raise _fail(where, step, "a step > 0")
        count = round(abs(last - first) / increment) + 1
        # a whole number of steps to ~1e-9 (round-off of unit conversion)
        if abs((count - 1) * increment - abs(last - first)) > 1e-9 * max(abs(last - first),
                                                                      increment):
            raise _fail(where, step, f"a step that divides STOP - START = {last - first:g} "
                        f"{spec.unit or ''} into whole steps")
        if count > _MAX_POINTS:
            raise _fail(where, step, f"at most {_MAX_POINTS} points")
        values = list(np.linspace(first, last, count))
    # 12 significant digits: linspace's round-off (0.018000000000000002) out of the table
    values = [float(f"{v:.12g}") for v in values]
    for value in values:   # bounds of the key, on every value
        _convert_value(where, spec, value if spec.kind is not int else round(value))
    return values


def _tracking_settings(raw: dict) -> TrackingSettings:
    names = {f.name for f in dataclasses.fields(TrackingSettings)}
    for key in raw:
        if key not in names:
            raise _fail(f"tracking.{key}", raw[key], "keys " + ", ".join(
                f"tracking.{n}" for n in sorted(names)), "unknown key")
    try:
        return TrackingSettings(**raw)
    except TrackingInputError as error:
        raise SweepError(str(error)) from None


def _execution_settings(raw: dict) -> ExecutionSettings:
    allowed = ("executor", "workers", "scheduler", "chain_length", "reuse")
    for key in raw:
        if key not in allowed:
            raise _fail(f"execution.{key}", raw[key], "keys " + ", ".join(
                f"execution.{k}" for k in allowed), "unknown key")
    executor = raw.get("executor", "local")
    if executor not in EXECUTORS:
        raise _fail("execution.executor", executor, "one of " + ", ".join(EXECUTORS))
    workers = raw.get("workers", 2)
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 1024:
        raise _fail("execution.workers", workers, "an integer in [1, 1024]")
    scheduler = raw.get("scheduler")
    if scheduler is not None and not isinstance(scheduler, str):
        raise _fail("execution.scheduler", scheduler, "a Dask scheduler address such as "
                    "tcp://10.0.0.5:8786")
    chain_length = check_chain_length(raw.get("chain_length", "auto"), "execution.chain_length")
    return ExecutionSettings(executor=executor, workers=workers, scheduler=scheduler,
                             chain_length=chain_length, reuse=parse_reuse(raw.get("reuse", True)))


def check_chain_length(value, key: str = "--chain-length"):
    if value == "auto":
        return value
    if isinstance(value, str) and value.isdigit():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise _fail(key, value, "auto or an integer >= 1")
    return value


def parse_reuse(value) -> ReuseSettings:
    """``true``/``false`` or a mapping ``{mesh, prestress, shifts}`` of booleans."""
    if isinstance(value, bool):
        return ReuseSettings(value, value, value)
    if isinstance(value, dict):
        names = {f.name for f in dataclasses.fields(ReuseSettings)}
        for key, flag in value.items():
            if key not in names or not isinstance(flag, bool):
                raise _fail(f"execution.reuse.{key}", flag, "keys mesh, prestress, shifts with "
                            "true or false")
        return ReuseSettings(**value)
    raise _fail("execution.reuse", value, "true, false or {mesh, prestress, shifts: true/false}")


# --------------------------------------------------------------------------- grid


def _hash(data) -> str:
    text = json.dumps(data, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def _context_key(study: Study, model: str) -> str:
    """Points with equal keys can share a mesh and continue one membrane solver."""
    values = {section: keys for section, keys in study.values.items()
              if section not in LOAD_LIKE_SECTIONS}
    return _hash({"model": model, **values})


def _space_key(study: Study, model: str) -> str:
    """Points with equal keys have shape vectors in the same basis (MAC by mass matrix)."""
    if model == "reduced":
        return f"rings:{study['reduced']['rings']}:{study['disc']['motion']}"
    from .geometry import GeometrySpec
    spec = GeometrySpec.from_study(study, with_air=model == "coupled")
    return f"fe:{spec.key()}:order{study['mesh']['order']}:curve{study['mesh']['curve_order']}"


def _expand_grid(base: Study, axes: list[Axis], model: str) -> list[SweepPoint]:
    """Every grid point (row-major over the axes as given), validated before any solve."""
    shape = [len(axis.values) for axis in axes]
    total = int(np.prod(shape))
    if total > _MAX_POINTS:
        raise _fail("axes", f"{total} points", f"at most {_MAX_POINTS} grid points")
    width = max(3, len(str(total - 1)))
    points = []
    for number, index in enumerate(itertools.product(*(range(n) for n in shape))):
        overrides = {axis.key: axis.values[i] for axis, i in zip(axes, index)}
        if model == "coupled":
            overrides.setdefault("air.enabled", True)
        try:
            study = base.replace(overrides)
            if model == "coupled":
                check_air_lift(study)
        except StudyError as error:
            where = ", ".join(f"{a.key} = {a.values[i]!r}" for a, i in zip(axes, index))
            raise SweepError(f"grid point p{number:0{width}d} ({where}): {error}") from None
        if model == "dry" and study["air"]["enabled"]:
            raise _fail("air.enabled", True, "false with model: dry (model: coupled couples "
                        "the air)", f"grid point p{number:0{width}d}")
        study.name = f"{base.name}/p{number:0{width}d}"
        hashed = {s: v for s, v in study.values.items() if s != "output"}
        points.append(SweepPoint(point_id=f"p{number:0{width}d}", index=tuple(index),
                                 overrides=overrides, study=study,
                                 context_key=_context_key(study, model),
                                 space_key=_space_key(study, model),
                                 study_hash=_hash({"model": model, **hashed})))
    return points


def _continuation_path(points: list[SweepPoint], axes: list[Axis]) -> list[str]:
    """Context-changing axes outermost, then a serpentine: neighbours differ by one step."""
    order = [i for i, a in enumerate(axes) if a.changes_context] + \
        [i for i, a in enumerate(axes) if not a.changes_context]

    def serpentine(point: SweepPoint):
        key, flips = [], 0
        for i in order:
            position = point.index[i]
            count = len(axes[i].values)
            key.append(count - 1 - position if flips % 2 else position)
            flips += key[-1]
        return tuple(key)

    return [p.point_id for p in sorted(points, key=serpentine)]


# --------------------------------------------------------------------------- models


@dataclass
class PointResult:
    """What one point produced: a JSON-able record and the arrays for tracking."""

    point_id: str
    status: str                     # "ok" or "failed"
    record: dict
    arrays: dict = field(default_factory=dict)


@dataclass
class _ChainState:
    """What a chain keeps between its points (worker-local, never pickled)."""

    context_key: str | None = None
    solver: object = None
    mass: object = None             # full-space mass matrix (SciPy) of the context [kg]
    last_point: str | None = None
    last_eigen: object = None       # BandResult of last_point
    last_band: tuple | None = None


_MESHES: dict = {}                  # process-level mesh cache: (geometry key, curve order) -> mesh
_MESH_CACHE_SIZE = 4
_NGSOLVE_LOCK = threading.Lock()    # NGSolve solves in one thread at a time per process


def _mesh_for(study: Study, with_air: bool, reuse: bool, timings):
    from .geometry import GeometrySpec
    from .solve import prepare_mesh
    from .study import engine_of
    if engine_of(study) == "axisymmetric":
        from .axisymmetric.meridian import MeridianSpec
        key = (MeridianSpec.from_study(study), study["mesh"]["curve_order"])
    else:
        key = (GeometrySpec.from_study(study, with_air=with_air).key(),
               study["mesh"]["curve_order"])
    if reuse and key in _MESHES:
        return _MESHES[key], True
    with timings.stage("mesh"):
        mesh = prepare_mesh(study, with_air=with_air)
    if reuse:
        while len(_MESHES) >= _MESH_CACHE_SIZE:
            _MESHES.pop(next(iter(_MESHES)))
        _MESHES[key] = mesh
    return mesh, False


def shift_plan(result, margin_fraction: float = 0.1, margin_modes: int = 4) -> list:
    """Start shifts for a neighbouring point from a :class:`copdea_fem.eigen.BandResult`.

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

    def modes_function(self):
        from .solve import dry_modes
        return dry_modes

    def check_available(self, sweep) -> None:
        """Refuse a factorisation back-end this machine lacks before any point runs."""
        from .solve import require_backend
        for point in sweep.points:
            require_backend(point.study)

    def solve(self, point: SweepPoint, chain: _ChainState, reuse: ReuseSettings, progress,
              needs_sampling: bool) -> PointResult:
        from .solve import Timings, make_prestress_solver
        study = point.study
        timings = Timings()
        start = time.perf_counter()
        mesh, mesh_reused = _mesh_for(study, self.with_air, reuse.mesh, timings)
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
                solver = make_prestress_solver(study, mesh)
            solve_study = study
        iterations_before = solver.newton_iterations
        band = (study["eigen"]["f_min"], study["eigen"]["f_max"])
        plan = shift_plan(chain.last_eigen) if reuse.shifts and chain.last_eigen is not None \
            and chain.last_band == band else None
        try:
            state, modes, eigen_result, accepted = call_modes_function(
                self.modes_function(), solve_study, mesh=mesh, progress=progress,
                timings=timings, solver=solver, initial_shifts=plan)
        except BaseException:
            # the solver may sit at a failed load: the next point starts afresh
            chain.solver = chain.last_eigen = chain.last_point = None
            raise
        if "solver" not in accepted:   # this model cannot continue: the solver is unused
            continued_from, solver = None, None
        if "initial_shifts" not in accepted:
            plan = None
        modes = [mode for mode in modes if mode.kind != "air"]   # air/PML-only modes
        with timings.stage("tracking_data"):
            if getattr(state, "engine", "3d") == "axisymmetric":
                # orders have spaces of their own: shapes are compared on the polar grid
                from .axisymmetric.modes import sampled_shapes
                arrays = {"sampled": sampled_shapes(state, modes)}
            else:
                arrays = _device_vectors_of(state, modes, chain, point, needs_sampling)
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


def _device_vectors_of(state, modes, chain, point, needs_sampling) -> dict:
    """Tracking arrays of a 3-D result: membrane vectors of the device and M times them."""
    if chain.mass is None or chain.context_key != point.context_key:
        chain.mass = _full_mass_matrix(state)
    vectors = np.column_stack([mode.vector for mode in modes]) if modes else \
        np.zeros((state.space.ndof, 0))
    weighted = chain.mass @ vectors
    if state.symmetry.quarter:   # device vectors: sectors orthogonal (symmetry doc)
        signatures = np.array([mode.sector.signature() for mode in modes]).reshape(-1, 4)
        vectors = np.vstack([vectors * column for column in signatures.T])
        weighted = np.vstack([weighted * column for column in signatures.T])
    arrays = {"vectors": vectors, "weighted": weighted}
    if needs_sampling:
        arrays["sampled"] = _sampled_shapes(state, modes)
    return arrays


def call_modes_function(function, study, mesh, progress, timings, solver=None,
                        initial_shifts=None):
    """Call a ``dry_modes``-like function with the reuse keywords it accepts.

    Returns
    -------
    state, modes, eigen_result, accepted
        ``accepted``: the names among ``solver``, ``initial_shifts`` that were
        passed.  The function may return ``(state, modes, eigen_result)`` or an
        object with ``state``, ``modes``, ``eigen`` (``CoupledSolution``).
    """
    import inspect
    parameters = inspect.signature(function).parameters
    keywords = {"mesh": mesh, "progress": progress, "timings": timings}
    accepted = set()
    for name, value in (("solver", solver), ("initial_shifts", initial_shifts)):
        if name in parameters:
            keywords[name] = value
            accepted.add(name)
    result = function(study, **keywords)
    if isinstance(result, tuple):
        state, modes, eigen_result = result
    else:
        state, modes, eigen_result = result.state, result.modes, result.eigen
    return state, list(modes), eigen_result, accepted


class _CoupledModel(_FEModel):
    """The fully-coupled membrane-air FE step (``copdea_fem.solve.coupled_modes``).

    Every point gets ``air.enabled: true`` and the mesh with air.  The modes'
    ``vector`` (membrane-space coefficients) is tracked like the dry ones;
    air/PML-only modes (kind ``air``) are left out of the sweep.  Reuse as for
    the dry model: the mesh, the prestress continuation and the neighbour's
    coupled shifts.
    """

    name = "coupled"
    with_air = True

    def modes_function(self):
        from .solve import coupled_modes
        return coupled_modes


class _ReducedModel:
    """The ring model (Sect. 3.2): dry modes of eq. (15) at each point, no state to reuse."""

    name = "reduced"

    def check_available(self, sweep) -> None:
        pass                       # pure NumPy/SciPy: nothing optional to check

    def solve(self, point: SweepPoint, chain: _ChainState, reuse: ReuseSettings, progress,
              needs_sampling: bool) -> PointResult:
        from .reduced.model import operating_point, ring_model_of
        study = point.study
        start = time.perf_counter()
        ring_model = ring_model_of(study)
        linearisation, basis, _ = operating_point(ring_model, study["load"]["z"],
                                                  study["load"]["voltage"],
                                                  study["effects"]["maxwell_scale"])
        band = study["eigen"]
        modes = [mode for mode in basis.modes
                 if band["f_min"] <= mode.frequency_hz <= band["f_max"]]
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


def _full_mass_matrix(state):
    """Consistent membrane mass on the full space, rho0 h0 / lambda_p^2 int u.v dS [kg]."""
    import ngsolve as ngs
    from .linearise import to_scipy
    u, v = state.space.TnT()
    form = ngs.BilinearForm(state.material.areal_density * u * v * state.measure,
                            symmetric=False).Assemble()
    return to_scipy(form.mat)


def _sampled_shapes(state, modes) -> np.ndarray:
    """(normal, radial, hoop) displacement of each mode on the normalised polar grid.

    :class:`copdea_fem.modes.ModeSampler` samples at r = r_i + (r_o - r_i)(k + 1/2)/n_r:
    the same normalised radius for every geometry, so shapes of different meshes
    (an inner-radius sweep) compare point by point.  Area weights r dr dtheta are
    folded in as sqrt(r / r_o) (dr and dtheta are equal at all samples of one point).
    """
    from .modes import ModeSampler
    sampler = ModeSampler(state)
    weights = np.sqrt(sampler.radii / state.outer_radius)[None, :, None]
    rows = [(sampler.components(mode.vector, mode.sector) * weights).ravel() for mode in modes]
    return np.array(rows) if rows else np.zeros((0, 3 * sampler.shape[0] * sampler.shape[1]))


# --------------------------------------------------------------------------- one point


def solve_point(model_name: str, point: SweepPoint, chain: _ChainState, reuse: ReuseSettings,
                needs_sampling: bool, progress=None) -> PointResult:
    """Solve one point, never raising for a failed solve: the error goes in the record."""
    model = MODEL_CLASSES[model_name]()
    progress = progress or (lambda message: None)
    base = {"point": point.point_id, "index": list(point.index),
            "parameters": point.overrides, "study_hash": point.study_hash, "model": model_name,
            "worker": f"{socket.gethostname()}:{os.getpid()}"}
    start = time.perf_counter()
    try:
        with _NGSOLVE_LOCK:
            result = model.solve(point, chain, reuse, progress, needs_sampling)
    except Exception as error:   # a failed point is recorded, the sweep goes on
        record = {**base, "status": "failed", "error": f"{type(error).__name__}: {error}",
                  "error_kind": getattr(error, "kind", type(error).__name__),
                  "timings_s": {"total": time.perf_counter() - start}}
        return PointResult(point.point_id, "failed", record)
    result.record = {**base, "status": "ok", **result.record}
    return result


# --------------------------------------------------------------------------- storage


class PointStore:
    """``OUT/points/<id>/result.json`` (+ ``vectors.npz``), each point written atomically."""

    def __init__(self, directory: str | Path):
        self.root = Path(directory) / "points"

    def record(self, point_id: str) -> dict | None:
        path = self.root / point_id / "result.json"
        if not path.is_file():
            return None
        try:
            return json.loads(path.read_text())
        except (OSError, json.JSONDecodeError):
            return None

    def finished(self, point: SweepPoint) -> bool:
        record = self.record(point.point_id)
        return bool(record) and record.get("status") == "ok" and \
            record.get("study_hash") == point.study_hash and \
            (self.root / point.point_id / "vectors.npz").is_file()

    def write(self, result: PointResult) -> None:
        from .folders import result_directory
        self.root.mkdir(parents=True, exist_ok=True)
        with result_directory(self.root / result.point_id, "sweep point") as staging:
            if result.arrays:
                # float32 halves the files; the MAC needs ~1e-6, float32 gives ~1e-7
                np.savez(staging / "vectors.npz",
                         **{k: _compact(v) for k, v in result.arrays.items()})
            (staging / "result.json").write_text(json.dumps(result.record, indent=1,
                                                            default=_json_default))

    def arrays(self, point_id: str) -> dict:
        with np.load(self.root / point_id / "vectors.npz") as data:
            return {key: data[key] for key in data.files}


def _compact(array: np.ndarray) -> np.ndarray:
    array = np.asarray(array)
    return array.astype(np.complex64 if np.iscomplexobj(array) else np.float32)


def _json_default(value):
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


# --------------------------------------------------------------------------- executors


def _needs_sampling(sweep: Sweep) -> bool:
    return len({p.space_key for p in sweep.points}) > 1


def _describe(sweep: Sweep, point: SweepPoint) -> str:
    return ", ".join(f"{axis.key} = {axis.format(point.overrides[axis.key])}"
                     for axis in sweep.axes)


def _summary_line(sweep: Sweep, record: dict) -> str:
    point = sweep.point(record["point"])
    head = f"{record['point']} ({_describe(sweep, point)})"
    if record["status"] != "ok":
        return f"{head}: FAILED -- {record['error']}"
    seconds = record.get("timings_s", {})
    reuse = record.get("reuse", {})
    parts = [f"{len(record['modes'])} modes in {seconds.get('total', 0):.2f} s"]
    if "prestress" in seconds:
        source = f" from {reuse['prestress_from']}" if reuse.get("prestress_from") else ""
        parts.append(f"prestress {seconds['prestress']:.2f} s{source}")
    if "eigen" in seconds:
        parts.append(f"eigen {seconds['eigen']:.2f} s"
                     + (" (neighbour's shifts)" if reuse.get("initial_shifts") else ""))
    return f"{head}: " + ", ".join(parts)


def _run_chain(sweep: Sweep, chain_ids: list[str], reuse: ReuseSettings, sink: Callable,
               chain: _ChainState | None = None) -> None:
    """Solve the points of one chain in order, continuing from each to the next."""
    chain = chain or _ChainState()
    needs_sampling = _needs_sampling(sweep)
    for point_id in chain_ids:
        result = solve_point(sweep.model, sweep.point(point_id), chain, reuse, needs_sampling,
                             progress=None)
        sink(result)


def _pool_chain_task(sweep: Sweep, chain_ids: list[str], reuse: ReuseSettings,
                     directory: str, threads: int) -> list[str]:
    """Worker process: run one chain, writing each point to the store as it finishes."""
    try:
        import ngsolve
        ngsolve.SetNumThreads(max(1, threads))
    except Exception:   # noqa: BLE001 -- the thread count is a hint only
        pass
    store = PointStore(directory)
    _run_chain(sweep, chain_ids, reuse, store.write)
    return chain_ids


_WORKER_CHAINS: dict = {}          # dask worker-local chain states, by chain key
_WORKER_CHAINS_LOCK = threading.Lock()


def _dask_point_task(sweep: Sweep, point_id: str, chain_key: str, previous_id: str | None,
                     last_in_chain: bool, reuse: ReuseSettings, needs_sampling: bool,
                     _after=None) -> PointResult:
    """Dask task: one point, continuing the chain's solver if this worker holds it.

    ``_after`` is the predecessor's future (ordering only).
    """
    with _WORKER_CHAINS_LOCK:
        chain = _WORKER_CHAINS.get(chain_key)
        if chain is None or chain.last_point != previous_id:
            chain = _ChainState()      # no (or a stale) predecessor here: start afresh
        _WORKER_CHAINS[chain_key] = chain
    try:
        return solve_point(sweep.model, sweep.point(point_id), chain, reuse, needs_sampling)
    finally:
        if last_in_chain:
            with _WORKER_CHAINS_LOCK:
                _WORKER_CHAINS.pop(chain_key, None)


@dataclass
class SweepOutcome:
    """What :func:`run_sweep` did."""

    directory: Path
    table: list
    computed: list
    resumed: list
    failed: dict
    wall_seconds: float
    tracks: dict


def run_sweep(sweep: Sweep, out_dir: str | Path | None = None, executor: str | None = None,
              workers: int | None = None, scheduler=None, chain_length=None,
              reuse: ReuseSettings | None = None, progress: Callable | None = None,
              on_point_done: Callable | None = None) -> SweepOutcome:
    """Run (or resume) a sweep and write its table, plots and summary.

    Parameters
    ----------
    sweep : Sweep
    out_dir : path, optional
        Result directory (default ``output.directory`` of the sweep file).
    executor : {"local", "pool", "dask"}, optional
        Default ``execution.executor``.
    workers : int, optional
        Processes of the ``pool`` executor (default ``execution.workers``).
    scheduler : str or distributed.Client, optional
        Dask scheduler address (or a connected client) for ``executor="dask"``.
    chain_length : "auto" or int, optional
        Points per continuation chain (default ``execution.chain_length``).
    reuse : ReuseSettings, optional
        Default ``execution.reuse``.
    progress : callable(str), optional
        One line per point (and a few more).
    on_point_done : callable(PointResult), optional
        Called in this process after each computed point is stored.

    Returns
    -------
    SweepOutcome
    """
    start = time.perf_counter()
    progress = progress or (lambda message: None)
    executor = executor or sweep.execution.executor
    if executor not in EXECUTORS:
        raise _fail("--executor", executor, "one of " + ", ".join(EXECUTORS))
    workers = sweep.execution.workers if workers is None else workers
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise _fail("--workers", workers, "an integer >= 1")
    chain_length = check_chain_length(sweep.execution.chain_length if chain_length is None
                                      else chain_length)
    scheduler = scheduler if scheduler is not None else sweep.execution.scheduler
    if executor == "dask" and scheduler is None:
        raise _fail("--scheduler", None, "a Dask scheduler address (tcp://HOST:PORT) with "
                    "--executor dask")
    reuse = reuse or sweep.execution.reuse
    MODEL_CLASSES[sweep.model]().check_available(sweep)
    directory = Path(out_dir or sweep.output_directory)
    with claim(directory, "sweep", progress=progress):
        directory.mkdir(parents=True, exist_ok=True)
        write_manifest(directory, "sweep", SWEEP_FILES)
        store = PointStore(directory)
        resumed = [pid for pid in sweep.path if store.finished(sweep.point(pid))]
        todo = [pid for pid in sweep.path if pid not in set(resumed)]
        progress(f"sweep {sweep.name}: {len(sweep.points)} points, model {sweep.model}, "
                 f"{len(resumed)} already done, {len(todo)} to compute ({executor})")
        computed: list[str] = []
        counter = itertools.count(len(resumed) + 1)

        def sink(result: PointResult, write: bool = True):
            if write:
                store.write(result)
            computed.append(result.point_id)
            progress(f"[{next(counter)}/{len(sweep.points)}] "
                     + _summary_line(sweep, result.record))
            if on_point_done is not None:
                on_point_done(result)

        todo_set = set(todo)

        def chains_for(parallel: int) -> list[list[str]]:
            chains = [[pid for pid in chain if pid in todo_set]
                      for chain in sweep.chains(chain_length, parallel)]
            return [chain for chain in chains if chain]

        if executor == "local":
            for chain in chains_for(1):
                _run_chain(sweep, chain, reuse, sink)
        elif executor == "pool":
            _run_pool(sweep, chains_for(workers), reuse, directory, workers, store, sink)
        elif todo:
            _run_dask(sweep, chains_for, reuse, scheduler, sink, progress)
        outcome = finish_sweep(sweep, directory, progress=progress)
        outcome.computed, outcome.resumed = computed, resumed
        outcome.wall_seconds = time.perf_counter() - start
        _write_summary(sweep, directory, outcome)
        return outcome


def _run_pool(sweep, chains, reuse, directory, workers, store, sink) -> None:
    """Chains in spawned worker processes; points are reported as they land in the store."""
    import concurrent.futures
    import multiprocessing
    # one BLAS thread per process and a share of the cores for NGSolve: no oversubscription
    saved = {name: os.environ.get(name) for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                      "MKL_NUM_THREADS")}
    for name in saved:
        os.environ.setdefault(name, "1")
    threads = max(1, (os.cpu_count() or 1) // workers)
    context = multiprocessing.get_context("spawn")   # NGSolve's threads do not survive fork
    reported: set[str] = set()

    def report_new(chain_ids):
        for point_id in chain_ids:
            record = None if point_id in reported else store.record(point_id)
            if record:
                if record.get("study_hash") == sweep.point(point_id).study_hash:
                    reported.add(point_id)
                    sink(PointResult(point_id, record["status"], record), write=False)

    try:
        with concurrent.futures.ProcessPoolExecutor(max_workers=min(workers, len(chains) or 1),
                                                    mp_context=context) as pool:
            futures = {pool.submit(_pool_chain_task, sweep, chain, reuse, str(directory),
                                   threads): chain for chain in chains}
            pending = set(futures)
            try:
                while pending:
                    done, pending = concurrent.futures.wait(
                        pending, timeout=1.0, return_when=concurrent.futures.FIRST_COMPLETED)
                    for future in pending:
                        report_new(futures[future])
                    for future in done:
                        report_new(futures[future])
                        error = future.exception()
                        for point_id in futures[future]:
                            if error is not None and point_id not in reported:
                                # a crashed worker process: its unfinished points fail
                                record = {"point": point_id, "status": "failed",
                                          "study_hash": sweep.point(point_id).study_hash,
                                          "error": f"worker process failed: {error!r}",
                                          "parameters": sweep.point(point_id).overrides}
                                reported.add(point_id)
                                sink(PointResult(point_id, "failed", record))
            except BaseException:
                for future in futures:
                    future.cancel()
                raise
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _run_dask(sweep, chains_for, reuse, scheduler, sink, progress) -> None:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise _fail("--executor", "dask", "local or pool, or install Dask: pip install "
                    "'copdea-fem[dask]'", "dask.distributed is not installed") from None
    own_client = isinstance(scheduler, str)
    client = Client(scheduler) if own_client else scheduler
    try:
        addresses = sorted(client.scheduler_info()["workers"])
        chains = chains_for(max(1, len(addresses)))
        progress(f"dask: {len(chains)} chains on {len(addresses)} workers at "
                 f"{client.scheduler.address}")
        needs_sampling = _needs_sampling(sweep)
        token = _hash([sweep.name, sweep.path, time.time_ns()])
        shared_sweep = client.scatter(sweep, broadcast=True)   # shipped once, not per task
        futures = {}
        for number, chain in enumerate(chains):
            worker = [addresses[number % len(addresses)]] if addresses else None
            previous_future, previous_id = None, None
            for position, point_id in enumerate(chain):
                future = client.submit(
                    _dask_point_task, shared_sweep, point_id, f"{token}:{number}", previous_id,
                    position == len(chain) - 1, reuse, needs_sampling, previous_future,
                    key=f"copdea-sweep-{token}-{point_id}", workers=worker,
                    allow_other_workers=True, pure=False)
                futures[future] = point_id
                previous_future, previous_id = future, point_id
        for future in as_completed(list(futures)):
            point_id = futures[future]
            try:
                result = future.result()
            except Exception as error:   # a lost worker: report the point, go on
                record = {"point": point_id, "status": "failed",
                          "study_hash": sweep.point(point_id).study_hash,
                          "error": f"dask task failed: {error!r}",
                          "parameters": sweep.point(point_id).overrides}
                result = PointResult(point_id, "failed", record)
            sink(result)
            future.release()
    finally:
        if own_client:
            client.close()


# --------------------------------------------------------------------------- gather


TABLE_COLUMNS = ("point", "status", "track", "track_label", "member", "pair", "label", "m", "n",
                 "kind", "freq_hz", "freq_im_hz", "mac_previous", "error")


def finish_sweep(sweep: Sweep, directory: str | Path, progress=None) -> SweepOutcome:
    """Track the stored results along the path; write sweep.csv, sweep.png, resolved YAML."""
    directory = Path(directory)
    store = PointStore(directory)
    records = {pid: store.record(pid) for pid in sweep.path}
    sets = []
    for pid in sweep.path:
        record = records[pid]
        if store.finished(sweep.point(pid)):
            arrays = store.arrays(pid)
            modes = record["modes"]
            sets.append(ModeSet(
                freq_hz=[m["freq_hz"] for m in modes], labels=[m["label"] for m in modes],
                kinds=[m["kind"] for m in modes], m=[m["m"] for m in modes],
                vectors=arrays.get("vectors"), weighted=arrays.get("weighted"),
                space=record.get("space"), sampled=arrays.get("sampled")))
        else:
            sets.append(ModeSet(np.zeros(0), [], [], np.zeros(0, int)))
    tracking = track_modes(sets, sweep.tracking)
    path_position = {pid: i for i, pid in enumerate(sweep.path)}
    rows, failed = [], {}
    for point in sweep.points:
        record = records[point.point_id]
        parameters = {axis.column(): point.overrides[axis.key] for axis in sweep.axes}
        base_row = {"point": point.point_id, **parameters}
        if not record or record.get("study_hash") != point.study_hash or \
                (record["status"] == "ok" and not store.finished(point)):
            rows.append({**base_row, "status": "missing"})
            failed[point.point_id] = "not computed"
            continue
        if record["status"] != "ok":
            rows.append({**base_row, "status": "failed", "error": record.get("error", "")})
            failed[point.point_id] = record.get("error", "")
            continue
        p = path_position[point.point_id]
        order = np.argsort([m["freq_hz"] for m in record["modes"]], kind="stable")
        for k in order:
            mode = record["modes"][k]
            track = int(tracking.track[p][k])
            mac = tracking.mac_previous[p][k]
            rows.append({**base_row, "status": "ok", "track": track,
                         "track_label": tracking.labels[track],
                         "member": int(tracking.member[p][k]),
                         "pair": bool(tracking.unit_size[p][k] == 2), "label": mode["label"],
                         "m": mode["m"], "n": mode["n"], "kind": mode["kind"],
                         "freq_hz": mode["freq_hz"], "freq_im_hz": mode.get("freq_im_hz", 0.0),
                         "mac_previous": "" if math.isnan(mac) else round(float(mac), 6),
                         "error": ""})
    columns = ["point"] + [axis.column() for axis in sweep.axes] + list(TABLE_COLUMNS[1:])
    directory.mkdir(parents=True, exist_ok=True)
    _write_csv(directory / "sweep.csv", rows, columns)
    (directory / "sweep.resolved.yaml").write_text(yaml.safe_dump(
        json.loads(json.dumps(sweep.resolved(), default=_json_default)), sort_keys=False))
    if sweep.plots:
        plot_sweep(directory / "sweep.png", sweep, rows)
    if failed and progress:
        for point_id, error in failed.items():
            progress(f"point {point_id} has no result: {error}")
    return SweepOutcome(directory=directory, table=rows, computed=[], resumed=[], failed=failed,
                        wall_seconds=0.0, tracks=dict(tracking.labels))


def _write_csv(path: Path, rows: list[dict], columns: list[str]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({c: _csv_value(row.get(c, "")) for c in columns})
    tmp.replace(path)


def _csv_value(value):
    if isinstance(value, float):
        return repr(value)
    return value


def read_table(path: str | Path) -> list[dict]:
    """The rows of a ``sweep.csv`` as dicts of strings."""
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _write_summary(sweep: Sweep, directory: Path, outcome: SweepOutcome) -> None:
    store = PointStore(directory)
    points = []
    for point_id in sweep.path:
        record = store.record(point_id) or {}
        points.append({"point": point_id, "parameters": sweep.point(point_id).overrides,
                       "status": record.get("status", "missing"),
                       "error": record.get("error"), "timings_s": record.get("timings_s"),
                       "reuse": record.get("reuse"), "eigen": record.get("eigen"),
                       "prestress": record.get("prestress"), "worker": record.get("worker"),
                       "computed_now": point_id in outcome.computed})
    document = {"name": sweep.name, "model": sweep.model, "path": sweep.path,
                "wall_s": outcome.wall_seconds, "computed": outcome.computed,
                "resumed": outcome.resumed, "failed": outcome.failed,
                "tracks": {str(k): v for k, v in outcome.tracks.items()}, "points": points}
    tmp = directory / "sweep.json.tmp"
    tmp.write_text(json.dumps(document, indent=1, default=_json_default))
    tmp.replace(directory / "sweep.json")


def format_summary(sweep: Sweep, outcome: SweepOutcome, max_columns: int = 12) -> str:
    """Tracked modes of the plotted kinds as text: one row per track, one column per point.

    Single-axis sweeps with at most ``max_columns`` points get the frequency at every
    point [Hz]; otherwise each track's range.
    """
    rows = [row for row in outcome.table if row.get("status") == "ok"]
    shown = sorted({row["track"] for row in rows if row["kind"] in sweep.plot_kinds})
    axis = sweep.axes[0]
    lines = []
    if len(sweep.axes) == 1 and len(axis.values) <= max_columns:
        column = axis.column()
        header = "".join(f"{axis.format(v).split()[0]:>9}" for v in axis.values)
        lines.append(f"{'track':>5}  {'label':<14}{header}   <- {axis.label()}")
        for track in shown:
            by_value: dict = {}
            for row in rows:
                if row["track"] == track:
                    by_value.setdefault(row[column], []).append(row["freq_hz"])
            cells = "".join(f"{np.mean(by_value[v]):9.2f}" if v in by_value else f"{'-':>9}"
                            for v in axis.values)
            lines.append(f"{track:>5}  {outcome.tracks[track]:<14}{cells}")
        lines.append(f"{'':>5}  {'':<14}{'[Hz]':>9}")
    else:
        for track in shown:
            freqs = [row["freq_hz"] for row in rows if row["track"] == track]
            lines.append(f"{track:>5}  {outcome.tracks[track]:<14}{min(freqs):9.2f} .."
                         f"{max(freqs):9.2f} Hz at {len(freqs)} rows")
    for point_id, error in outcome.failed.items():
        lines.append(f"point {point_id} failed: {error}")
    lines.append(f"{len(sweep.points)} points ({len(outcome.computed)} computed, "
                 f"{len(outcome.resumed)} resumed, {len(outcome.failed)} without result) in "
                 f"{outcome.wall_seconds:.1f} s; results in {outcome.directory}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- plots


def plot_sweep(path: Path, sweep: Sweep, rows: list[dict], max_panels: int = 12) -> None:
    """Fig. 11 style: frequency vs the first axis, one labelled line per tracked mode.

    Tracks that have one of ``output.plot_kinds`` at some point are drawn.

    Other axes give one panel per combination of their values (at most
    ``max_panels``).  Pairs are drawn as one line at the mean of their members.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x_axis = sweep.axes[0]
    others = sweep.axes[1:]
    combos = list(itertools.product(*(range(len(a.values)) for a in others)))[:max_panels]
    columns = min(3, len(combos))
    figure_rows = math.ceil(len(combos) / columns)
    figure, panels = plt.subplots(figure_rows, columns, figsize=(5.2 * columns,
                                                                  4.2 * figure_rows),
                                  squeeze=False)
    # a track is drawn whole if it has the plotted kind at one point at least (through a
    # veering its kind may change, e.g. (0,3) -> in-plane)
    shown_tracks = {row["track"] for row in rows
                    if row.get("status") == "ok" and row["kind"] in sweep.plot_kinds}
    ok = [row for row in rows if row.get("status") == "ok" and row["track"] in shown_tracks]
    colours = plt.get_cmap("tab20")
    for number, combo in enumerate(combos):
        axes = panels[number // columns][number % columns]
        wanted = {a.column(): a.values[i] for a, i in zip(others, combo)}
        tracks: dict[int, list] = {}
        for row in ok:
            if all(row[c] == v for c, v in wanted.items()):
                tracks.setdefault(row["track"], []).append(row)
        ends = []   # (x, y, label, colour) of each line's right end
        for track, members in sorted(tracks.items()):
            by_x: dict = {}
            for row in members:
                by_x.setdefault(row[x_axis.column()], []).append(row["freq_hz"])
            xs = sorted(by_x)
            ys = [float(np.mean(by_x[x])) for x in xs]
            shown = [x_axis.display(x) for x in xs]
            colour = colours(track % 20)
            axes.plot(shown, ys, "o-", color=colour, markersize=3.5, linewidth=1.2)
            ends.append((shown[-1], ys[-1], members[0]["track_label"], colour))
        _label_line_ends(axes, ends)
        axes.set_xlabel(x_axis.label())
        axes.set_ylabel("natural frequency [Hz]")
        title = ", ".join(f"{a.key} = {a.format(a.values[i])}"
                          for a, i in zip(others, combo)) or sweep.name
        axes.set_title(f"{title} ({sweep.model})", fontsize=9)
        axes.grid(alpha=0.3)
        axes.margins(x=0.12)
    for number in range(len(combos), figure_rows * columns):
        panels[number // columns][number % columns].axis("off")
    figure.tight_layout()
    figure.savefig(path, dpi=130)
    plt.close(figure)


def _label_line_ends(axes, ends, min_gap_fraction: float = 0.028) -> None:
    """Write each line's label at its right end, nudged apart where ends crowd.

    Labels ending at the same x are spread upwards to at least
    ``min_gap_fraction`` of the frequency range (about one 7-pt text line on
    the default figure).
    """
    if not ends:
        return
    low, high = axes.get_ylim()
    gap = min_gap_fraction * (high - low)
    by_x: dict = {}
    for x, y, label, colour in ends:
        by_x.setdefault(x, []).append((y, label, colour))
    for x, group in by_x.items():
        placed = -math.inf
        for y, label, colour in sorted(group, key=lambda item: item[0]):
            text_y = max(y, placed + gap)
            placed = text_y
            axes.annotate(label, (x, text_y), xytext=(4, 0), textcoords="offset points",
                          fontsize=7, color=colour, va="center")


# --------------------------------------------------------------------------- benchmark


def _benchmark(argv: list[str]) -> int:
    """``python -m copdea_fem.sweep benchmark SWEEP.yaml [--repeat N] [--set K=V]``.

    Runs the sweep in fresh processes with every reuse switched off, then on
    one by one (mesh; + prestress continuation; + eigen start shifts),
    interleaved (one run of each variant per repetition, so a change of the
    machine's load hits all variants alike), and reports per variant the
    median wall time, the median CPU time of the process (user + system, all
    threads: less sensitive to other jobs on a shared machine) and the
    per-point stage medians, as JSON on stdout.
    """
    import argparse
    import resource
    import statistics
    import subprocess
    import tempfile

    parser = argparse.ArgumentParser(prog="python -m copdea_fem.sweep benchmark")
    parser.add_argument("sweep")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--variants", default="independent,mesh,prestress,all")
    args = parser.parse_args(argv)
    variants = {"independent": {"mesh": False, "prestress": False, "shifts": False},
                "mesh": {"mesh": True, "prestress": False, "shifts": False},
                "prestress": {"mesh": True, "prestress": True, "shifts": False},
                "all": {"mesh": True, "prestress": True, "shifts": True}}
    names = args.variants.split(",")
    for name in names:
        if name not in variants:
            raise _fail("--variants", name, "a comma-separated list of " + ", ".join(variants))
    runs: dict[str, list] = {name: [] for name in names}
    for repetition in range(args.repeat):
        for name in names:
            with tempfile.TemporaryDirectory() as tmp:
                command = [sys.executable, "-m", "copdea_fem.sweep", "_once", args.sweep,
                           tmp, json.dumps(variants[name])] + args.set
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                subprocess.run(command, check=True)
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                run = json.loads((Path(tmp) / "sweep.json").read_text())
                run["cpu_s"] = (after.ru_utime - before.ru_utime) + \
                    (after.ru_stime - before.ru_stime)
                timers = Path(tmp) / "factorisation_timers.json"
                run["factorisation_timers"] = json.loads(timers.read_text()) \
                    if timers.is_file() else {}
                runs[name].append(run)
            print(f"{name} {repetition + 1}/{args.repeat}: wall {run['wall_s']:.1f} s, "
                  f"process CPU {run['cpu_s']:.1f} s", file=sys.stderr)
    report = {}
    for name in names:
        variant_runs = runs[name]
        stages = sorted({s for run in variant_runs for p in run["points"]
                         for s in (p["timings_s"] or {})})
        per_point = {}
        for position, point in enumerate(variant_runs[0]["points"]):
            per_point[point["point"]] = {
                stage: statistics.median((run["points"][position]["timings_s"] or {}).get(
                    stage, 0.0) for run in variant_runs) for stage in stages}
        report[name] = {
            "wall_s_median": statistics.median(run["wall_s"] for run in variant_runs),
            "wall_s_all": [run["wall_s"] for run in variant_runs],
            "cpu_s_median": statistics.median(run["cpu_s"] for run in variant_runs),
            "cpu_s_all": [run["cpu_s"] for run in variant_runs],
            "stage_sum_s": {stage: statistics.median(
                sum((p["timings_s"] or {}).get(stage, 0.0) for p in run["points"])
                for run in variant_runs) for stage in stages},
            "per_point_s": per_point,
            "newton_iterations": [(p["prestress"] or {}).get("newton_iterations")
                                  for p in variant_runs[0]["points"]],
            "eigen_factorisations": [(p["eigen"] or {}).get("factorisations")
                                     for p in variant_runs[0]["points"]],
            "failed": variant_runs[0]["failed"],
            "factorisation_timers_s": variant_runs[-1].get("factorisation_timers", {})}
    print(json.dumps(report, indent=1))
    return 0


def _once(argv: list[str]) -> int:
    sweep_path, directory, reuse_text, *sets = argv
    from .study import parse_overrides
    sweep = load_sweep(sweep_path, overrides=parse_overrides(sets))
    run_sweep(sweep, out_dir=directory, executor="local",
              reuse=parse_reuse(json.loads(reuse_text)),
              progress=lambda message: print(message, file=sys.stderr, flush=True))
    # what symbolic-analysis reuse could buy: NGSolve's own UMFPACK timers [s]
    import ngsolve
    timers = {t["name"]: {"seconds": t["time"], "counts": t["counts"]} for t in ngsolve.Timers()
              if "Umfpack Inverse" in t["name"] or "SparseCholesky" in t["name"]}
    (Path(directory) / "factorisation_timers.json").write_text(json.dumps(timers, indent=1))
    return 0


if __name__ == "__main__":
    command, *rest = sys.argv[1:] or ["help"]
    if command == "benchmark":
        sys.exit(_benchmark(rest))
    if command == "_once":
        sys.exit(_once(rest))
    print(_benchmark.__doc__)
    sys.exit(2)
