"""Sweep files: the schema of a sweep (axes, tracking, execution, output), parsed and validated."""

from __future__ import annotations

import copy
import dataclasses
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from copdea_fem.folders import package_versions
from copdea_fem.inputs import read_yaml
from copdea_fem.parallel import SWEEP_SPELLINGS, executor_name
from copdea_fem.study import SCHEMA, Study, StudyError, convert_value, load_study
from copdea_fem.sweeps.axes import (
    MAX_POINTS,
    Axis,
    SweepError,
    SweepPoint,
    sweep_error,
)
from copdea_fem.sweeps.grid import continuation_path, expand_grid
from copdea_fem.sweeps.tracking import TrackingInputError, TrackingSettings

MODELS = ("dry", "reduced", "coupled")
TOP_KEYS = ("name", "description", "study", "set", "model", "axes", "tracking", "execution",
            "output")
#: What a sweep folder holds (its manifest lists these; each point folder has its own).
SWEEP_FILES = ("sweep.csv", "sweep.csv.tmp", "sweep.json", "sweep.json.tmp",
               "sweep.resolved.yaml", "sweep.png", "points")
DEFAULT_PLOT_KINDS = ("out-of-plane", "pumping")
KINDS = ("out-of-plane", "in-plane", "pumping", "air")


@dataclass(frozen=True)
class ReuseSettings:
    """Which work neighbouring points share (``execution.reuse``)."""

    mesh: bool = True
    prestress: bool = True
    shifts: bool = True


@dataclass(frozen=True)
class ExecutionSettings:
    executor: str | None = None       # None: inline (copdea_fem.parallel.EXECUTORS)
    workers: int = 2
    scheduler: str | None = None
    chain_length: int | str = "auto"
    reuse: ReuseSettings = ReuseSettings()


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
                "execution": {**dataclasses.asdict(self.execution),
                              "executor": self.execution.executor or "inline"},
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
            raise sweep_error(key, "...", "keys " + ", ".join(TOP_KEYS), "unknown key")
    model = raw.get("model", "dry")
    if model not in MODELS:
        raise sweep_error("model", model, "one of " + ", ".join(MODELS))
    base_overrides = _mapping(raw.get("set"), "set")
    axes_raw = _mapping(raw.get("axes"), "axes")
    if not axes_raw:
        raise sweep_error("axes", raw.get("axes"), "a mapping of one or more study keys to values, "
                          "e.g. {load.voltage: '0..3 kV, 7 points'}")
    for key in axes_raw:
        if key in base_overrides:
            raise sweep_error(f"set.{key}", base_overrides[key], f"a key that is not swept (it is "
                              f"axes.{key})")
    base = _base_study(raw, Path(base_dir), name, {**base_overrides, **(overrides or {})})
    if model == "dry" and base.air.enabled:
        raise sweep_error("air.enabled", True, "false with model: dry (model: coupled couples the air)")
    axes = [_parse_axis(key, value) for key, value in axes_raw.items()]
    tracking = _tracking_settings(_mapping(raw.get("tracking"), "tracking"))
    execution = _execution_settings(_mapping(raw.get("execution"), "execution"))
    output = _mapping(raw.get("output"), "output")
    for key in output:
        if key not in ("directory", "plots", "plot_kinds"):
            raise sweep_error(f"output.{key}", output[key], "keys output.directory, output.plots, "
                              "output.plot_kinds", "unknown key")
    plots = output.get("plots", True)
    if not isinstance(plots, bool):
        raise sweep_error("output.plots", plots, "true or false")
    plot_kinds = output.get("plot_kinds", list(DEFAULT_PLOT_KINDS))
    if not isinstance(plot_kinds, list) or not plot_kinds or any(k not in KINDS
                                                                 for k in plot_kinds):
        raise sweep_error("output.plot_kinds", plot_kinds, "a non-empty list of " + ", ".join(KINDS))
    directory = output.get("directory", f"results/sweeps/{name}")
    if not isinstance(directory, str) or not directory.strip():
        raise sweep_error("output.directory", directory, "a path")
    points = expand_grid(base, axes, model)
    path = continuation_path(points, axes)
    return Sweep(name=name, description=str(raw.get("description", "")), source=source,
                 base=base, model=model, axes=axes, points=points, path=path, tracking=tracking,
                 execution=execution, output_directory=directory, plots=plots,
                 plot_kinds=tuple(plot_kinds), raw=copy.deepcopy(raw))


def _mapping(value, key: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise sweep_error(key, value, "a mapping")
    return dict(value)


def _base_study(raw: dict, base_dir: Path, name: str, overrides: dict) -> Study:
    study_path = raw.get("study")
    if not isinstance(study_path, str) or not study_path.strip():
        raise sweep_error("study", study_path, "the path of a base study file, relative to the sweep "
                          "file (e.g. ../g1_z16_v2.yaml)")
    full = Path(study_path) if Path(study_path).is_absolute() else base_dir / study_path
    if not full.exists():
        raise sweep_error("study", Path(study_path), "an existing study file",
                          f"{full} does not exist")
    try:
        study = load_study(full, overrides=overrides)
    except SweepError:
        raise
    except StudyError as error:
        raise SweepError(f"base study {study_path} with set: {error}") from None
    return dataclasses.replace(study, name=name)


_RANGE = re.compile(r"^\s*(?P<start>[^,]+?)\s*\.\.\s*(?P<stop>[^,]+?)\s*,\s*"
                    r"(?:(?P<points>\d+)\s*points?|step\s+(?P<step>.+?))\s*$")
_NUMBER_UNIT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


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
        raise sweep_error(f"axes.{key}", value, allowed, "unknown study key")
    spec = SCHEMA[section][name]
    where = f"axes.{key}"
    allowed_forms = ("'START..STOP UNIT, N points', 'START..STOP UNIT, step STEP UNIT', a list "
                     "of values, or {start, stop, points} / {start, stop, step}")
    numeric = spec.kind in (int, float) and not spec.choices
    display_unit = None
    if isinstance(value, str) and numeric:
        match = _RANGE.match(value)
        if not match:
            raise sweep_error(where, value, allowed_forms)
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
            raise sweep_error(where, value, allowed_forms)
        display_unit = _unit_of(value["stop"]) or _unit_of(value["start"])
        values = _range_values(where, spec, value["start"], value["stop"], value.get("points"),
                               value.get("step"))
    elif isinstance(value, list) and value:
        display_unit = next((u for u in map(_unit_of, value) if u), None)
        values = [_convert_value(where, spec, item) for item in value]
    else:
        raise sweep_error(where, value, allowed_forms if numeric else
                          f"a non-empty list of values ({spec.allowed()})")
    if len(set(map(repr, values))) != len(values):
        raise sweep_error(where, value, "distinct values", "a value is repeated")
    if spec.kind is int:
        values = [int(round(v)) for v in values]
    return Axis(key=key, values=tuple(values), unit=spec.unit, display_unit=display_unit)


def _convert_value(where: str, spec, value):
    try:
        return convert_value(where, spec, value)
    except StudyError as error:
        raise SweepError(str(error)) from None


def _range_values(where, spec, start, stop, points, step) -> list:
    relaxed = dataclasses.replace(spec, minimum=None, maximum=None, kind=float)
    first = _convert_value(where + " start", relaxed, start)
    last = _convert_value(where + " stop", relaxed, stop)
    if points is not None:
        count = points if isinstance(points, int) and not isinstance(points, bool) else \
            int(points) if isinstance(points, str) and points.isdigit() else None
        if count is None or not 1 <= count <= MAX_POINTS or (count == 1 and first != last):
            raise sweep_error(where, points, f"an integer number of points in [2, {MAX_POINTS}] "
                              "(1 only when start = stop)")
        values = list(np.linspace(first, last, count))
    else:
        increment = _convert_value(where + " step", relaxed, step)
        if not increment > 0:
            raise sweep_error(where, step, "a step > 0")
        count = round(abs(last - first) / increment) + 1
        # a whole number of steps to ~1e-9 (round-off of unit conversion)
        if abs((count - 1) * increment - abs(last - first)) > 1e-9 * max(abs(last - first),
                                                                      increment):
            raise sweep_error(where, step, f"a step that divides STOP - START = {last - first:g} "
                              f"{spec.unit or ''} into whole steps")
        if count > MAX_POINTS:
            raise sweep_error(where, step, f"at most {MAX_POINTS} points")
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
            raise sweep_error(f"tracking.{key}", raw[key], "keys " + ", ".join(
                f"tracking.{n}" for n in sorted(names)), "unknown key")
    try:
        return TrackingSettings(**raw)
    except TrackingInputError as error:
        raise SweepError(str(error)) from None


def _execution_settings(raw: dict) -> ExecutionSettings:
    allowed = ("executor", "workers", "scheduler", "chain_length", "reuse")
    for key in raw:
        if key not in allowed:
            raise sweep_error(f"execution.{key}", raw[key], "keys " + ", ".join(
                f"execution.{k}" for k in allowed), "unknown key")
    executor = executor_name(raw.get("executor"), SWEEP_SPELLINGS, "execution.executor",
                             SweepError)
    workers = raw.get("workers", 2)
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 1024:
        raise sweep_error("execution.workers", workers, "an integer in [1, 1024]")
    scheduler = raw.get("scheduler")
    if scheduler is not None and not isinstance(scheduler, str):
        raise sweep_error("execution.scheduler", scheduler, "a Dask scheduler address such as "
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
        raise sweep_error(key, value, "auto or an integer >= 1")
    return value


def parse_reuse(value) -> ReuseSettings:
    """``true``/``false`` or a mapping ``{mesh, prestress, shifts}`` of booleans."""
    if isinstance(value, bool):
        return ReuseSettings(value, value, value)
    if isinstance(value, dict):
        names = {f.name for f in dataclasses.fields(ReuseSettings)}
        for key, flag in value.items():
            if key not in names or not isinstance(flag, bool):
                raise sweep_error(f"execution.reuse.{key}", flag, "keys mesh, prestress, shifts with "
                                  "true or false")
        return ReuseSettings(**value)
    raise sweep_error("execution.reuse", value, "true, false or {mesh, prestress, shifts: true/false}")
