"""The ``measured.yaml`` manifest: the base study, the conditions and the files they name.

Everything is read and checked before any model runs (the resonance and spectrum CSVs:
:mod:`copdea_fem.measured.csv_files`; the scans: :func:`copdea_fem.measured.read_scan`);
a problem raises :class:`MeasuredDataError` (a :class:`copdea_fem.study.StudyError`, hence
a ``ValueError``) naming the file or key, the value and what is allowed.  What the
manifest says of the diagnosis's effects (``candidates:``, the keys a condition may not
set) is checked with the rules the diagnosis gives (:class:`EffectRules`).

Manifest (paths relative to the manifest's folder)::

    name: g1_example                 # optional, default: the file name
    description: ...                 # optional
    base_study: base_study.yaml      # the model to diagnose (a study file)
    noise:                           # optional, the measurement's error model
      frequency_relative: 0.015      #   1-sigma relative scatter of peak frequencies
      quality_relative: 0.25         #   1-sigma relative scatter of quality factors
      missing_probability: 0.1       #   chance that a mode in the band is not identified
      spurious_per_condition: 0.2    #   expected peaks per condition no axisymmetric model has
    candidates: [air_loading, ...]   # optional: effects the diagnosis may add (default: all
                                     #   but enclosure, which is opt-in)
    observed: ["(m,1)", "(0,n)"]     # optional: the mode families the measurement can see
                                     #   (default: all); model modes outside them cost
                                     #   nothing when no peak explains them
    pairing: {window: 50 %, mac_min: 0.5}   # optional: pairing of scanned shapes with the
                                     #   model's (copdea_fem.vibrometer.pairing)
    identification: {resolve_pairs: true}  # optional: split close pairs in the scans'
                                     #   identification (default false)
    model: fe                        # optional: the model of record, fe (default: the FE as
                                     #   the base study is written, the ring model its
                                     #   anchored surrogate) or reduced (the ring model alone)
    conditions:
      - name: z16_v2                 # unique; letters, digits, _ . -
        set: {load.z: 16 mm, load.voltage: 2 kV}   # overrides of the base study
        resonances: z16_v2_resonances.csv          # and/or
        spectrum: z16_v2_spectrum.csv
        spectrum_point: average      # average (default), Q1, Q2 or Q3 (Sect. 5.3, Fig. 14)
        band: [5 Hz, 1000 Hz]        # optional; default: the spectrum's, else the chirp's
        modes_json: fe/modes.json    # optional: coupled FE frequencies (effect air_loading)
      - name: z16_v2_scan
        set: {load.z: 16 mm, load.voltage: 2 kV}
        scan: z16_v2.uff             # a vibrometer's UFF export (instead of or beside the
                                     #   resonances: see copdea_fem.measured.scan_files)
        scan_frame:                  # optional: where the model's frame lies in the file's
          origin: [0, 0, -16]        #   coordinates (default: they are the model's)
          x_axis: [1, 0, 0]
          z_axis: [0, 0, 1]
          length_unit: mm            #   default: the file's dataset 164
        scan_directions: [0, 0, 1]   # optional: a 1-D laser's direction (file axes), one
                                     #   for all points or {node: [x, y, z]} per point
        scan_tolerance: 3.55 mm      # optional: how far a point may lie off the device
                                     #   (default a tenth of the outer radius)
      - name: z16_v2_modes
        set: {load.z: 16 mm, load.voltage: 2 kV}
        modes: z16_v2_modes.unv      # mode shapes another program identified (dataset 55
                                     #   with the geometry: copdea_fem.measured.mode_sets),
                                     #   paired by shape as a scan's; not beside scan:
                                     #   (which shapes to pair would be ambiguous).
                                     #   scan_frame and scan_tolerance apply; band default:
                                     #   the lowest to the highest mode
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from copdea_fem.inputs import as_path, read_yaml
from copdea_fem.measured.csv_files import POINTS, Spectrum, read_resonances, read_spectrum
from copdea_fem.measured.errors import MeasuredDataError, refusal
from copdea_fem.measured.geometry import check_on_device
from copdea_fem.measured.mode_sets import MODE_SET_SUFFIXES, MeasuredModes, read_mode_set
from copdea_fem.measured.observation import (
    ObservedFamilies,
    PairingSettings,
    parse_identification,
    parse_observed,
    parse_pairing,
)
from copdea_fem.measured.scan import ScanData, ScanFrame
from copdea_fem.measured.scan_files import SCAN_READERS, read_scan
from copdea_fem.study import Study, StudyError, load_study

MANIFEST_KEYS = ("name", "description", "base_study", "noise", "candidates", "conditions",
                 "model", "observed", "pairing", "identification")
MODELS = ("fe", "reduced")     # the model of record (key ``model``, default fe)
CONDITION_KEYS = ("name", "set", "resonances", "spectrum", "spectrum_point", "band",
                  "modes_json", "scan", "scan_frame", "scan_directions", "scan_tolerance",
                  "modes")
SCAN_FRAME_KEYS = ("origin", "x_axis", "z_axis", "length_unit")


@dataclass(frozen=True)
class EffectRules:
    """What a manifest may say about the diagnosis's effects: given by the diagnosis, which
    sits above this package (:data:`copdea_fem.diagnosis.effects.MANIFEST_RULES`).

    Attributes
    ----------
    parse_candidates : callable
        ``parse_candidates(value, key) -> tuple of str``: ``candidates:`` as the effect ids
        it names, in order; a :class:`~copdea_fem.study.StudyError` naming ``key`` for an
        unknown effect.
    default_candidates : tuple of str
        The effects the diagnosis may add when ``candidates:`` is absent.
    switched_keys : dict
        ``{prefix: effect}``: a condition's ``set:`` may not name a study key that starts
        with ``prefix``, which that effect switches.
    """

    parse_candidates: Callable[[Any, str], tuple]
    default_candidates: tuple
    switched_keys: dict


@dataclass(frozen=True)
class NoiseModel:
    """Error model of the measurement (the likelihood of :mod:`copdea_fem.diagnosis.compare`).

    Attributes
    ----------
    frequency_relative : float
        sigma_f: 1-sigma scatter of ln(f) of an identified peak [-] (1-2 %).
    quality_relative : float
        sigma_Q: 1-sigma scatter of ln(Q) [-].
    missing_probability : float
        p_miss: chance that a mode in the band is not identified [-].
    spurious_per_condition : float
        lambda_s: expected number of peaks per condition that no axisymmetric
        model has (electrical pick-up, set-up resonances, unlabelled
        non-axisymmetric modes) [-].
    """

    frequency_relative: float = 0.015
    quality_relative: float = 0.25
    missing_probability: float = 0.1
    spurious_per_condition: float = 0.2


NOISE_BOUNDS = {"frequency_relative": (1e-4, 0.5), "quality_relative": (1e-3, 5.0),
                "missing_probability": (1e-3, 0.9), "spurious_per_condition": (1e-3, 20.0)}


@dataclass(frozen=True)
class Condition:
    """One measured condition: base study + overrides, and its data.

    Attributes
    ----------
    name : str
    overrides : dict
        ``{"section.key": value}`` on top of the base study.
    resonances : tuple of Resonance or None
    spectrum : Spectrum or None
    band : tuple of float
        (f_low, f_high) [Hz] in which peaks were looked for.
    fe_frequencies : dict or None
        Coupled FE frequencies {label: Hz} from ``modes_json``.
    files : dict
        The files read, for the report.
    scan : ScanData or None
        The vibrometer scan (``scan:``), in SI and in the model's frame.
    scan_distance : float
        Largest distance [m] of a scan point (or a mode set's node) from the prestressed
        device (nan: neither).
    mode_set : MeasuredModes or None
        Mode shapes another program identified (``modes:``), in the model's frame.
    """

    name: str
    overrides: dict
    resonances: tuple | None
    spectrum: Spectrum | None
    band: tuple
    fe_frequencies: dict | None = None
    files: dict = field(default_factory=dict)
    scan: ScanData | None = None
    scan_distance: float = math.nan
    mode_set: MeasuredModes | None = None

    @property
    def shapes_measured(self) -> bool:
        """Whether the condition has measured shapes to pair with the model's (a scan or a
        mode set)."""
        return self.scan is not None or self.mode_set is not None


@dataclass(frozen=True)
class MeasuredSet:
    """A validated ``measured.yaml``: the base study, conditions, noise model, candidates
    (the effects the diagnosis may add: the manifest's, else the diagnosis's default list;
    none on a set made by hand without them)."""

    name: str
    description: str
    path: Path | None
    base_study: Study
    conditions: tuple
    noise: NoiseModel
    candidates: tuple = ()
    model: str = "fe"
    observed: ObservedFamilies | None = None
    pairing: PairingSettings | None = None
    identification: dict = field(default_factory=dict)

    def study_of(self, condition: Condition, extra: dict | None = None) -> Study:
        """The base study with the condition's overrides (and ``extra`` ones) applied."""
        return self.base_study.replace({**condition.overrides, **(extra or {})})


def _quantity(value, unit, where, positive=False):
    from copdea_fem.study import Key, convert_value
    return convert_value(where, Key(unit, 0.0, where, minimum=0, open_min=positive), value)


def load_measured(path, *, effects: EffectRules) -> MeasuredSet:
    """Read and check ``measured.yaml`` and every file it names (no model runs).

    Parameters
    ----------
    path : path-like
        The manifest; the files it names are taken relative to its folder.
    effects : EffectRules
        The diagnosis's effects (:data:`copdea_fem.diagnosis.effects.MANIFEST_RULES`; the
        diagnosis's and the API's ``load_measured`` pass them).

    Returns
    -------
    MeasuredSet

    Raises
    ------
    MeasuredDataError
        A file or key that is missing or not allowed, naming it, its value and what is
        allowed (a bad base study: its :class:`~copdea_fem.study.StudyError`).
    """
    path = as_path(path, "measured file", MeasuredDataError)
    if not path.exists():
        raise refusal("measured file", path, "an existing measured.yaml", "does not exist")
    raw = read_yaml(path, "measured file", MeasuredDataError)
    return parse_measured(raw, path.parent, name=str(raw.get("name") or path.stem), path=path,
                          effects=effects)


def parse_measured(raw: dict, folder, name: str = "measured", path=None, *,
                   effects: EffectRules) -> MeasuredSet:
    """Validate a manifest mapping; relative paths are taken from ``folder`` (the rest as
    :func:`load_measured`)."""
    folder = Path(folder)
    for key in raw:
        if key not in MANIFEST_KEYS:
            raise refusal(key, "...", "keys " + ", ".join(MANIFEST_KEYS), "unknown key")
    if "base_study" not in raw or not isinstance(raw["base_study"], str):
        raise refusal("base_study", raw.get("base_study"), "the path of a study YAML file, "
                      "relative to the measured.yaml")
    base = load_study(folder / raw["base_study"])
    noise_raw = raw.get("noise") or {}
    if not isinstance(noise_raw, dict):
        raise refusal("noise", noise_raw, "a mapping of " + ", ".join(NOISE_BOUNDS))
    noise_values = {}
    for key, value in noise_raw.items():
        if key not in NOISE_BOUNDS:
            raise refusal(f"noise.{key}", value, "keys " + ", ".join(NOISE_BOUNDS), "unknown key")
        lo, hi = NOISE_BOUNDS[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
            raise refusal(f"noise.{key}", value, f"a number in [{lo:g}, {hi:g}]")
        noise_values[key] = float(value)
    noise = NoiseModel(**noise_values)
    candidates = (effects.parse_candidates(raw["candidates"], "candidates")
                  if raw.get("candidates") is not None else effects.default_candidates)
    model = raw.get("model", "fe")
    if model not in MODELS:
        raise refusal("model", model, ", ".join(MODELS) + " (fe: the FE as the base study is "
                      "written, the ring model its anchored surrogate; reduced: the ring model "
                      "alone)")
    conditions_raw = raw.get("conditions")
    if not isinstance(conditions_raw, list) or not conditions_raw:
        raise refusal("conditions", conditions_raw, "a non-empty list of conditions")
    conditions, names = [], set()
    for index, item in enumerate(conditions_raw):
        condition = _parse_condition(item, index, base, folder, effects.switched_keys)
        if condition.name in names:
            raise refusal(f"conditions[{index}].name", condition.name, "a name used once")
        names.add(condition.name)
        conditions.append(condition)
    return MeasuredSet(name=name, description=str(raw.get("description", "")),
                       path=Path(path) if path else None, base_study=base,
                       conditions=tuple(conditions), noise=noise, candidates=candidates,
                       model=model, observed=parse_observed(raw.get("observed")),
                       pairing=parse_pairing(raw.get("pairing")),
                       identification=parse_identification(raw.get("identification")))


def _parse_condition(item, index, base: Study, folder: Path, switched_keys: dict) -> Condition:
    where = f"conditions[{index}]"
    if not isinstance(item, dict):
        raise refusal(where, item, "a mapping with keys " + ", ".join(CONDITION_KEYS))
    for key in item:
        if key not in CONDITION_KEYS:
            raise refusal(f"{where}.{key}", "...", "keys " + ", ".join(CONDITION_KEYS),
                          "unknown key")
    name = str(item.get("name", f"condition_{index + 1}"))
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
        raise refusal(f"{where}.name", name, "letters, digits, _ . - (it names output files)")
    overrides = item.get("set") or {}
    if not isinstance(overrides, dict):
        raise refusal(f"{where}.set", overrides, "a mapping of SECTION.KEY: value")
    for key in overrides:
        owner = next((o for prefix, o in switched_keys.items() if str(key).startswith(prefix)),
                     None)
        if owner:
            raise refusal(f"{where}.set.{key}", overrides[key], "operating-point, geometry and "
                          "material keys", f"switched by effect {owner}, not by a condition")
    try:
        study = base.replace(overrides)
    except StudyError as error:
        raise MeasuredDataError(f"{where} ({name}).set: {error}") from None
    files = {}
    resonances = spectrum = None
    if item.get("resonances") is not None:
        files["resonances"] = folder / str(item["resonances"])
        resonances = read_resonances(files["resonances"], f"{where}.resonances")
    point = str(item.get("spectrum_point", "average"))
    if point not in POINTS:
        raise refusal(f"{where}.spectrum_point", point, ", ".join(POINTS))
    if item.get("spectrum") is not None:
        files["spectrum"] = folder / str(item["spectrum"])
        spectrum = read_spectrum(files["spectrum"], point, f"{where}.spectrum")
    scan, scan_distance = None, math.nan
    if item.get("scan") is not None:
        if not isinstance(item["scan"], str) or not item["scan"].strip():
            raise refusal(f"{where}.scan", item["scan"], "the name of a " + "/".join(SCAN_READERS)
                          + " file, relative to the measured.yaml")
        files["scan"] = folder / item["scan"]
        scan, scan_distance = _read_scan(item, where, files["scan"], study)
    mode_set = None
    if item.get("modes") is not None:
        if scan is not None:
            raise refusal(f"{where}.modes", item["modes"], "scan: or modes:, not both (which "
                          "shapes to pair would be ambiguous: the scan's identified modes or "
                          "the file's; give each its own condition)")
        if not isinstance(item["modes"], str) or not item["modes"].strip():
            raise refusal(f"{where}.modes", item["modes"], "the name of a "
                          + "/".join(MODE_SET_SUFFIXES) + " file with dataset 55 mode shapes, "
                          "relative to the measured.yaml")
        if item.get("scan_directions") is not None:
            raise refusal(f"{where}.scan_directions", item["scan_directions"], "only beside "
                          "scan: FILE (a mode set's shapes lie along the file's axes)")
        files["modes"] = folder / item["modes"]
        mode_set, scan_distance = _read_mode_set(item, where, files["modes"], study)
    if scan is None and mode_set is None:
        for key in ("scan_frame", "scan_directions", "scan_tolerance"):
            if item.get(key) is not None:
                raise refusal(f"{where}.{key}", item[key], "only beside scan: FILE or "
                              "modes: FILE")
    if resonances is None and spectrum is None and scan is None and mode_set is None:
        raise refusal(f"{where} ({name})", "no data", "resonances and/or spectrum, and/or scan "
                      "or modes")
    if item.get("band") is not None:
        band_raw = item["band"]
        if not isinstance(band_raw, (list, tuple)) or len(band_raw) != 2:
            raise refusal(f"{where}.band", band_raw, "[f_low, f_high], e.g. [5 Hz, 1000 Hz]")
        band = tuple(_quantity(v, "Hz", f"{where}.band") for v in band_raw)
    elif spectrum is not None:
        band = (float(spectrum.frequency_hz[0]), float(spectrum.frequency_hz[-1]))
    elif scan is not None:
        positive = scan.frequencies[scan.frequencies > 0]
        band = (float(positive[0]), float(positive[-1]))
    elif mode_set is not None:
        band = (float(mode_set.freq_hz[0]), float(mode_set.freq_hz[-1]))
    else:
        x = study.excitation
        band = (max(x.f_start, 1.0 / x.duration), x.f_end)
    if not (0 < band[0] < band[1] or (item.get("band") is None and 0 < band[0] == band[1])):
        raise refusal(f"{where}.band", list(band), "0 < f_low < f_high (Hz)")
    fe = None
    if item.get("modes_json") is not None:
        from copdea_fem.reduced.io import read_modes_json
        files["modes_json"] = folder / str(item["modes_json"])
        try:
            fe = read_modes_json(files["modes_json"], study)
        except StudyError as error:
            raise MeasuredDataError(f"{where}.modes_json: {error}") from None
    return Condition(name=name, overrides=dict(overrides), resonances=resonances,
                     spectrum=spectrum, band=band, fe_frequencies=fe, files=files, scan=scan,
                     scan_distance=scan_distance, mode_set=mode_set)


def _vector(value, where: str, nonzero: bool) -> np.ndarray:
    allowed = "[x, y, z]: three finite numbers" + (", not all zero" if nonzero else "")
    if not isinstance(value, (list, tuple)) or len(value) != 3 or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise refusal(where, value, allowed)
    vector = np.array(value, float)
    if not np.all(np.isfinite(vector)) or (nonzero and not np.any(vector)):
        raise refusal(where, value, allowed)
    return vector


def parse_scan_frame(raw, where: str = "scan_frame") -> ScanFrame:
    """``scan_frame:`` -> :class:`ScanFrame` (origin in the file's length unit, the model's
    x and z axes in the file's axes, perpendicular; ``length_unit``: ``mm``, ``m``, ...)."""
    if not isinstance(raw, dict):
        raise refusal(where, raw, "a mapping of " + ", ".join(SCAN_FRAME_KEYS))
    for key in raw:
        if key not in SCAN_FRAME_KEYS:
            raise refusal(f"{where}.{key}", raw[key], "keys " + ", ".join(SCAN_FRAME_KEYS),
                          "unknown key")
    origin = _vector(raw.get("origin", [0, 0, 0]), f"{where}.origin", nonzero=False)
    x_axis = _vector(raw.get("x_axis", [1, 0, 0]), f"{where}.x_axis", nonzero=True)
    z_axis = _vector(raw.get("z_axis", [0, 0, 1]), f"{where}.z_axis", nonzero=True)
    cosine = abs(x_axis @ z_axis) / (np.linalg.norm(x_axis) * np.linalg.norm(z_axis))
    if cosine > 1e-3:
        raise refusal(f"{where}.x_axis", raw.get("x_axis", [1, 0, 0]), "an axis perpendicular "
                      "to z_axis (|cos| <= 1e-3)", f"|cos| = {cosine:.3g}")
    unit = raw.get("length_unit")
    length_unit = None
    if unit is not None:
        text = f"1 {unit}" if isinstance(unit, str) and not unit.strip()[:1].isdigit() \
            else unit
        length_unit = _quantity(text, "m", f"{where}.length_unit")
        if not length_unit > 0:
            raise refusal(f"{where}.length_unit", unit, "a length unit such as mm or m")
    return ScanFrame(origin=origin, x_axis=x_axis, z_axis=z_axis, length_unit=length_unit)


def _scan_directions(raw, where: str):
    if raw is None:
        return None
    if isinstance(raw, dict):
        out = {}
        for node, value in raw.items():
            if isinstance(node, bool) or not isinstance(node, int):
                raise refusal(f"{where} node", node, "the file's node numbers (integers)")
            out[node] = _vector(value, f"{where}[{node}]", nonzero=True)
        return out
    return _vector(raw, where, nonzero=True)


def _frame_and_tolerance(item: dict, where: str):
    """The condition's ``scan_frame`` (None: the file's frame) and ``scan_tolerance`` [m]
    (None: the default)."""
    frame = (parse_scan_frame(item["scan_frame"], f"{where}.scan_frame")
             if item.get("scan_frame") is not None else None)
    tolerance = None
    if item.get("scan_tolerance") is not None:
        # one rule for 0 and a negative length alike: > 0 m
        tolerance = _quantity(item["scan_tolerance"], "m", f"{where}.scan_tolerance",
                              positive=True)
    return frame, tolerance


def _read_mode_set(item: dict, where: str, path: Path, study: Study):
    """The condition's mode set, read and checked on the device; (MeasuredModes, largest
    distance of a node from the device [m])."""
    frame, tolerance = _frame_and_tolerance(item, where)
    try:
        mode_set = read_mode_set(path, frame=frame)
    except MeasuredDataError as error:
        raise MeasuredDataError(f"{where}.modes: {error}") from None
    distance = check_on_device(mode_set.channels, study, tolerance, f"{where}.modes")
    return mode_set, distance


def _read_scan(item: dict, where: str, path: Path, study: Study):
    """The condition's scan, read and checked on the device; (ScanData, largest distance)."""
    frame, tolerance = _frame_and_tolerance(item, where)
    directions = _scan_directions(item.get("scan_directions"), f"{where}.scan_directions")
    try:
        scan = read_scan(path, frame=frame, directions=directions)
    except MeasuredDataError as error:
        raise MeasuredDataError(f"{where}.scan: {error}") from None
    distance = check_on_device(scan, study, tolerance, f"{where}.scan")
    return scan, distance


__all__ = ["CONDITION_KEYS", "MANIFEST_KEYS", "MODELS", "NOISE_BOUNDS", "SCAN_FRAME_KEYS",
           "Condition", "EffectRules", "MeasuredSet", "NoiseModel", "load_measured",
           "parse_measured", "parse_scan_frame"]
