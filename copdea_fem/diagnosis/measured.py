"""Measured data in: the ``measured.yaml`` manifest, resonance and spectrum CSVs.

Everything is read and checked before any model runs; a problem raises
:class:`MeasuredDataError` (a :class:`copdea_fem.study.StudyError`, hence a
``ValueError``) naming the file or key, the value and what is allowed.

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
                                     #   resonances: see copdea_fem.vibrometer.uff)
        scan_frame:                  # optional: where the model's frame lies in the file's
          origin: [0, 0, -16]        #   coordinates (default: they are the model's)
          x_axis: [1, 0, 0]
          z_axis: [0, 0, 1]
          length_unit: mm            #   default: the file's dataset 164
        scan_directions: [0, 0, 1]   # optional: a 1-D laser's direction (file axes), one
                                     #   for all points or {node: [x, y, z]} per point
        scan_tolerance: 3.55 mm      # optional: how far a point may lie off the device
                                     #   (default a tenth of the outer radius)

Resonance CSV: ``freq_hz`` [Hz] and optionally ``label`` (``P1``, ``(0,1)``,
``(1,1)a``, empty = unknown; quoted or not), ``quality_factor`` [-] and ``kind``
(``pumping``: the disc moves, ``axisymmetric``, ``non-axisymmetric``; empty =
unknown; a label implies its kind).  Spectrum CSV: ``freq_hz`` [Hz] with
either ``v_axial, v_radial`` or the vibrometer's ``v_x, v_y, v_z`` [m/s,
|FFT|/N magnitudes].  Cartesian spectra are turned into the axisymmetric
model's components: axial = v_z; radial = sqrt(v_x^2 + v_y^2) at a point
(v_x = v_r cos(theta), v_y = v_r sin(theta) in phase); for the average over
a full ring of points, the mean of |v_r cos(theta)| is 2/pi |v_r|, so
radial = pi/4 (v_x + v_y).  Lines starting with ``#`` are comments.
"""

from __future__ import annotations

import csv
import logging
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from copdea_fem.diagnosis.effects import DEFAULT_CANDIDATES, parse_effect_list
from copdea_fem.inputs import preview, read_text, read_yaml
from copdea_fem.study import Study, StudyError, load_study
from copdea_fem.vibrometer.scan import MeasuredDataError, ScanData, ScanFrame

KINDS = ("pumping", "axisymmetric", "non-axisymmetric")
POINTS = ("average", "Q1", "Q2", "Q3")
MANIFEST_KEYS = ("name", "description", "base_study", "noise", "candidates", "conditions",
                 "model", "observed", "pairing")
MODELS = ("fe", "reduced")     # the model of record (key ``model``, default fe)
CONDITION_KEYS = ("name", "set", "resonances", "spectrum", "spectrum_point", "band",
                  "modes_json", "scan", "scan_frame", "scan_directions", "scan_tolerance")
SCAN_FRAME_KEYS = ("origin", "x_axis", "z_axis", "length_unit")
RESONANCE_COLUMNS = ("freq_hz", "label", "quality_factor", "kind")

# Keys a condition may not set: the effects switch them (see effects.CATALOGUE).
EFFECT_KEYS = {"effects.": "the effects", "disc.motion": "disc_pumping",
               "spring.mass": "spring_mass", "reduced.damping_": "modal_damping",
               "reduced.modes_json": "air_loading", "reduced.coupled_freq_0": "air_loading",
               "air.enabled": "air_loading", "geometry.frame": "frame_reflection",
               "reduced.pumping_added_mass": "spring_mass",
               "membrane.prony": "viscoelastic_membrane"}


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
class Resonance:
    """One identified resonance: frequency [Hz], label, kind, quality factor [-] (nan: none)."""

    frequency_hz: float
    label: str = ""
    kind: str = ""
    quality_factor: float = math.nan


@dataclass(frozen=True)
class Spectrum:
    """Measured velocity spectrum, |FFT|/N [m/s] of the axial and radial components.

    ``point`` is ``"average"`` (mean magnitude over the scan grid) or Q1-Q3.
    """

    frequency_hz: np.ndarray
    axial: np.ndarray
    radial: np.ndarray
    point: str = "average"


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
        Largest distance [m] of a scan point from the prestressed device (nan: no scan).
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


@dataclass(frozen=True)
class MeasuredSet:
    """A validated ``measured.yaml``: the base study, conditions, noise model, candidates."""

    name: str
    description: str
    path: Path | None
    base_study: Study
    conditions: tuple
    noise: NoiseModel
    candidates: tuple = DEFAULT_CANDIDATES
    model: str = "fe"
    observed: ObservedFamilies | None = None
    pairing: PairingSettings | None = None

    def study_of(self, condition: Condition, extra: dict | None = None) -> Study:
        """The base study with the condition's overrides (and ``extra`` ones) applied."""
        return self.base_study.replace({**condition.overrides, **(extra or {})})


def _fail(key, value, allowed, why="") -> MeasuredDataError:
    why = f" ({why})" if why else ""
    return MeasuredDataError(f"{key} = {preview(value)} is not allowed{why}; allowed: {allowed}")


_LABEL_PUMPING = re.compile(r"^[Pp]\s*([1-9]\d*)$")
_LABEL_MN = re.compile(r"^\(\s*(\d+)\s*,\s*([1-9]\d*)\s*\)\s*([ab]?)$")


def normalise_label(text: str, where: str) -> tuple[str, str]:
    """``" (0, 1) "`` -> ``("(0,1)", "axisymmetric")``; ``""`` -> ``("", "")``.

    Pumping labels ``P1, P2, ...``; ``(m,n)`` with m >= 0, n >= 1, an optional
    ``a``/``b`` for one of a split pair.
    """
    text = (text or "").strip()
    if not text:
        return "", ""
    match = _LABEL_PUMPING.match(text)
    if match:
        return f"P{match.group(1)}", "pumping"
    match = _LABEL_MN.match(text)
    if match:
        m, n, suffix = int(match.group(1)), int(match.group(2)), match.group(3)
        return f"({m},{n}){suffix}", "axisymmetric" if m == 0 else "non-axisymmetric"
    raise _fail(where, text, "empty, P1, P2, ... or (m,n) with m >= 0, n >= 1 and an optional "
                "a/b, e.g. (0,1), (1,1)a")


def _read_rows(path: Path, key: str):
    if not path.exists():
        raise _fail(key, path, "an existing CSV file", "file does not exist")
    text = read_text(path, key, error=MeasuredDataError)
    lines = text.splitlines()
    rows = list(csv.reader(r for r in lines if r.strip() and not r.lstrip().startswith("#")))
    if not rows:
        raise _fail(key, path, "a CSV with a header row", "empty file")
    return [name.strip() for name in rows[0]], rows[1:]


def _number(text, where, positive=True, allow_empty=False):
    text = (text or "").strip()
    if not text:
        if allow_empty:
            return math.nan
        raise _fail(where, text, "a number")
    try:
        value = float(text)
    except ValueError:
        raise _fail(where, text, "a number in SI units") from None
    if not math.isfinite(value) or (positive and value <= 0) or value < 0:
        raise _fail(where, text, "a finite number > 0" if positive else "a finite number >= 0")
    return value


def _rejoin_labels(row, width):
    """An unquoted label ``(0,1)`` splits into ``(0`` and ``1)``: join such cells back."""
    if len(row) <= width:
        return row
    out, i = [], 0
    while i < len(row):
        cell = row[i]
        if cell.strip().startswith("(") and ")" not in cell:
            j = i
            while j + 1 < len(row) and ")" not in row[j]:
                j += 1
            cell = ",".join(row[i:j + 1])
            i = j
        out.append(cell)
        i += 1
    return out


def read_resonances(path, key: str = "resonances") -> tuple:
    """Resonance CSV -> tuple of :class:`Resonance`, sorted by frequency."""
    path = Path(path)
    header, rows = _read_rows(path, key)
    unknown = [name for name in header if name not in RESONANCE_COLUMNS]
    if "freq_hz" not in header or unknown:
        raise _fail(f"{key} columns", header, "freq_hz and optionally label, quality_factor, "
                    f"kind (file {path})")
    index = {name: header.index(name) for name in header}
    out, seen, lines_of = [], {}, {}
    for line, row in enumerate(rows, start=2):
        row = _rejoin_labels(row, len(header))
        where = f"{path.name} line {line}"
        same = tuple(cell.strip() for cell in row)
        if same in lines_of:        # a peak pasted twice would weigh twice in the fit
            logging.getLogger(__name__).warning(
                f"{where} repeats line {lines_of[same]} (a duplicated peak): counted once")
            continue
        lines_of[same] = line
        cell = lambda name: row[index[name]] if name in index and index[name] < len(row) \
            else ""
        frequency = _number(cell("freq_hz"), f"{where} freq_hz")
        label, implied = normalise_label(cell("label"), f"{where} label")
        kind = cell("kind").strip().lower()
        if kind in ("", "unknown"):
            kind = implied
        elif kind not in KINDS:
            raise _fail(f"{where} kind", kind, ", ".join(KINDS) + " or empty")
        elif implied and kind != implied:
            raise _fail(f"{where} kind", kind, f"{implied} (the kind of label {label})")
        quality = _number(cell("quality_factor"), f"{where} quality_factor", allow_empty=True)
        if label:
            if label in seen:
                raise _fail(f"{where} label", label, "each label once per condition",
                            f"also on line {seen[label]}")
            seen[label] = line
        out.append(Resonance(frequency, label, kind, quality))
    if not out:
        raise _fail(key, path, "at least one resonance row")
    return tuple(sorted(out, key=lambda r: r.frequency_hz))


def read_spectrum(path, point: str = "average", key: str = "spectrum") -> Spectrum:
    """Spectrum CSV -> :class:`Spectrum` (cartesian components converted, see module notes)."""
    path = Path(path)
    header, rows = _read_rows(path, key)
    if point not in POINTS:
        raise _fail("spectrum_point", point, ", ".join(POINTS))
    if "freq_hz" in header and {"v_axial", "v_radial"} <= set(header):
        names = ("freq_hz", "v_axial", "v_radial")
    elif "freq_hz" in header and {"v_x", "v_y", "v_z"} <= set(header):
        names = ("freq_hz", "v_x", "v_y", "v_z")
    else:
        raise _fail(f"{key} columns", header, "freq_hz, v_axial, v_radial or freq_hz, v_x, v_y, "
                    f"v_z (m/s) (file {path})")
    data = {}
    for name in names:
        column = header.index(name)
        data[name] = np.array([_number(row[column] if column < len(row) else "",
                                       f"{path.name} line {line} {name}",
                                       positive=name == "freq_hz")
                               for line, row in enumerate(rows, start=2)])
    frequency = data["freq_hz"]
    if frequency.size < 8 or np.any(np.diff(frequency) <= 0):
        raise _fail(f"{key} freq_hz", f"{frequency.size} rows", "at least 8 rows with strictly "
                    f"increasing frequencies (file {path})")
    if "v_axial" in data:
        axial, radial = data["v_axial"], data["v_radial"]
    else:
        axial = data["v_z"]
        radial = (math.pi / 4 * (data["v_x"] + data["v_y"]) if point == "average"
                  else np.hypot(data["v_x"], data["v_y"]))
    return Spectrum(frequency, axial, radial, point)


def _quantity(value, unit, where):
    from copdea_fem.study import Key, convert_value
    return convert_value(where, Key(unit, 0.0, where, minimum=0), value)


def load_measured(path) -> MeasuredSet:
    """Read and check ``measured.yaml`` and every file it names (no model runs)."""
    path = Path(path)
    if not path.exists():
        raise _fail("measured file", path, "an existing measured.yaml", "does not exist")
    raw = read_yaml(path, "measured file", MeasuredDataError)
    return parse_measured(raw, path.parent, name=str(raw.get("name") or path.stem), path=path)


def parse_measured(raw: dict, folder, name: str = "measured", path=None) -> MeasuredSet:
    """Validate a manifest mapping; relative paths are taken from ``folder``."""
    folder = Path(folder)
    for key in raw:
        if key not in MANIFEST_KEYS:
            raise _fail(key, "...", "keys " + ", ".join(MANIFEST_KEYS), "unknown key")
    if "base_study" not in raw or not isinstance(raw["base_study"], str):
        raise _fail("base_study", raw.get("base_study"), "the path of a study YAML file, "
                    "relative to the measured.yaml")
    base = load_study(folder / raw["base_study"])
    noise_raw = raw.get("noise") or {}
    if not isinstance(noise_raw, dict):
        raise _fail("noise", noise_raw, "a mapping of " + ", ".join(NOISE_BOUNDS))
    noise_values = {}
    for key, value in noise_raw.items():
        if key not in NOISE_BOUNDS:
            raise _fail(f"noise.{key}", value, "keys " + ", ".join(NOISE_BOUNDS), "unknown key")
        lo, hi = NOISE_BOUNDS[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo <= value <= hi:
            raise _fail(f"noise.{key}", value, f"a number in [{lo:g}, {hi:g}]")
        noise_values[key] = float(value)
    noise = NoiseModel(**noise_values)
    candidates = (parse_effect_list(raw["candidates"], "candidates")
                  if raw.get("candidates") is not None else DEFAULT_CANDIDATES)
    model = raw.get("model", "fe")
    if model not in MODELS:
        raise _fail("model", model, ", ".join(MODELS) + " (fe: the FE as the base study is "
                    "written, the ring model its anchored surrogate; reduced: the ring model "
                    "alone)")
    conditions_raw = raw.get("conditions")
    if not isinstance(conditions_raw, list) or not conditions_raw:
        raise _fail("conditions", conditions_raw, "a non-empty list of conditions")
    conditions, names = [], set()
    for index, item in enumerate(conditions_raw):
        condition = _parse_condition(item, index, base, folder)
        if condition.name in names:
            raise _fail(f"conditions[{index}].name", condition.name, "a name used once")
        names.add(condition.name)
        conditions.append(condition)
    return MeasuredSet(name=name, description=str(raw.get("description", "")),
                       path=Path(path) if path else None, base_study=base,
                       conditions=tuple(conditions), noise=noise, candidates=candidates,
                       model=model, observed=parse_observed(raw.get("observed")),
                       pairing=parse_pairing(raw.get("pairing")))


def _parse_condition(item, index, base: Study, folder: Path) -> Condition:
    where = f"conditions[{index}]"
    if not isinstance(item, dict):
        raise _fail(where, item, "a mapping with keys " + ", ".join(CONDITION_KEYS))
    for key in item:
        if key not in CONDITION_KEYS:
            raise _fail(f"{where}.{key}", "...", "keys " + ", ".join(CONDITION_KEYS),
                        "unknown key")
    name = str(item.get("name", f"condition_{index + 1}"))
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
        raise _fail(f"{where}.name", name, "letters, digits, _ . - (it names output files)")
    overrides = item.get("set") or {}
    if not isinstance(overrides, dict):
        raise _fail(f"{where}.set", overrides, "a mapping of SECTION.KEY: value")
    for key in overrides:
        owner = next((o for prefix, o in EFFECT_KEYS.items() if str(key).startswith(prefix)),
                     None)
        if owner:
            raise _fail(f"{where}.set.{key}", overrides[key], "operating-point, geometry and "
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
        raise _fail(f"{where}.spectrum_point", point, ", ".join(POINTS))
    if item.get("spectrum") is not None:
        files["spectrum"] = folder / str(item["spectrum"])
        spectrum = read_spectrum(files["spectrum"], point, f"{where}.spectrum")
    scan, scan_distance = None, math.nan
    if item.get("scan") is not None:
        if not isinstance(item["scan"], str) or not item["scan"].strip():
            raise _fail(f"{where}.scan", item["scan"], "the name of a .uff/.unv file, relative "
                        "to the measured.yaml")
        files["scan"] = folder / item["scan"]
        scan, scan_distance = _read_scan(item, where, files["scan"], study)
    else:
        for key in ("scan_frame", "scan_directions", "scan_tolerance"):
            if item.get(key) is not None:
                raise _fail(f"{where}.{key}", item[key], "only beside scan: FILE")
    if resonances is None and spectrum is None and scan is None:
        raise _fail(f"{where} ({name})", "no data", "resonances and/or spectrum, and/or scan")
    if item.get("band") is not None:
        band_raw = item["band"]
        if not isinstance(band_raw, (list, tuple)) or len(band_raw) != 2:
            raise _fail(f"{where}.band", band_raw, "[f_low, f_high], e.g. [5 Hz, 1000 Hz]")
        band = tuple(_quantity(v, "Hz", f"{where}.band") for v in band_raw)
    elif spectrum is not None:
        band = (float(spectrum.frequency_hz[0]), float(spectrum.frequency_hz[-1]))
    elif scan is not None:
        positive = scan.frequencies[scan.frequencies > 0]
        band = (float(positive[0]), float(positive[-1]))
    else:
        x = study.excitation
        band = (max(x.f_start, 1.0 / x.duration), x.f_end)
    if not 0 < band[0] < band[1]:
        raise _fail(f"{where}.band", list(band), "0 < f_low < f_high (Hz)")
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
                     scan_distance=scan_distance)


def _vector(value, where: str, nonzero: bool) -> np.ndarray:
    allowed = "[x, y, z]: three finite numbers" + (", not all zero" if nonzero else "")
    if not isinstance(value, (list, tuple)) or len(value) != 3 or any(
            isinstance(v, bool) or not isinstance(v, (int, float)) for v in value):
        raise _fail(where, value, allowed)
    vector = np.array(value, float)
    if not np.all(np.isfinite(vector)) or (nonzero and not np.any(vector)):
        raise _fail(where, value, allowed)
    return vector


def parse_scan_frame(raw, where: str = "scan_frame") -> ScanFrame:
    """``scan_frame:`` -> :class:`ScanFrame` (origin in the file's length unit, the model's
    x and z axes in the file's axes, perpendicular; ``length_unit``: ``mm``, ``m``, ...)."""
    if not isinstance(raw, dict):
        raise _fail(where, raw, "a mapping of " + ", ".join(SCAN_FRAME_KEYS))
    for key in raw:
        if key not in SCAN_FRAME_KEYS:
            raise _fail(f"{where}.{key}", raw[key], "keys " + ", ".join(SCAN_FRAME_KEYS),
                        "unknown key")
    origin = _vector(raw.get("origin", [0, 0, 0]), f"{where}.origin", nonzero=False)
    x_axis = _vector(raw.get("x_axis", [1, 0, 0]), f"{where}.x_axis", nonzero=True)
    z_axis = _vector(raw.get("z_axis", [0, 0, 1]), f"{where}.z_axis", nonzero=True)
    cosine = abs(x_axis @ z_axis) / (np.linalg.norm(x_axis) * np.linalg.norm(z_axis))
    if cosine > 1e-3:
        raise _fail(f"{where}.x_axis", raw.get("x_axis", [1, 0, 0]), "an axis perpendicular "
                    "to z_axis (|cos| <= 1e-3)", f"|cos| = {cosine:.3g}")
    unit = raw.get("length_unit")
    length_unit = None
    if unit is not None:
        text = f"1 {unit}" if isinstance(unit, str) and not unit.strip()[:1].isdigit() \
            else unit
        length_unit = _quantity(text, "m", f"{where}.length_unit")
        if not length_unit > 0:
            raise _fail(f"{where}.length_unit", unit, "a length unit such as mm or m")
    return ScanFrame(origin=origin, x_axis=x_axis, z_axis=z_axis, length_unit=length_unit)


def _scan_directions(raw, where: str):
    if raw is None:
        return None
    if isinstance(raw, dict):
        out = {}
        for node, value in raw.items():
            if isinstance(node, bool) or not isinstance(node, int):
                raise _fail(f"{where} node", node, "the file's node numbers (integers)")
            out[node] = _vector(value, f"{where}[{node}]", nonzero=True)
        return out
    return _vector(raw, where, nonzero=True)


def _read_scan(item: dict, where: str, path: Path, study: Study):
    """The condition's scan, read and checked on the device; (ScanData, largest distance)."""
    from copdea_fem.vibrometer.geometry import check_on_device
    from copdea_fem.vibrometer.uff import read_scan

    frame = (parse_scan_frame(item["scan_frame"], f"{where}.scan_frame")
             if item.get("scan_frame") is not None else None)
    directions = _scan_directions(item.get("scan_directions"), f"{where}.scan_directions")
    tolerance = None
    if item.get("scan_tolerance") is not None:
        tolerance = _quantity(item["scan_tolerance"], "m", f"{where}.scan_tolerance")
        if not tolerance > 0:
            raise _fail(f"{where}.scan_tolerance", item["scan_tolerance"], "a length > 0")
    try:
        scan = read_scan(path, frame=frame, directions=directions)
    except MeasuredDataError as error:
        raise MeasuredDataError(f"{where}.scan: {error}") from None
    distance = check_on_device(scan, study, tolerance, f"{where}.scan")
    return scan, distance


# -- observed families and the pairing of scanned shapes ---------------------------------------

_FAMILY = re.compile(r"^\(\s*(m|\d+)\s*,\s*(n|[1-9]\d*)\s*\)$")
#: Kind words of ``observed``, and the model kinds each covers.  The diagnosis's model modes
#: are pumping, axisymmetric or non-axisymmetric (out-of-plane all three; its FE drops the
#: in-plane family, which an out-of-plane vibrometer hardly sees).
FAMILY_KINDS = {"out-of-plane": ("pumping", "axisymmetric", "non-axisymmetric"),
                "in-plane": ("in-plane",), "pumping": ("pumping",),
                "axisymmetric": ("axisymmetric",), "non-axisymmetric": ("non-axisymmetric",)}


@dataclass(frozen=True)
class ObservedFamilies:
    """The mode families a measurement can see (``observed:``).

    ``"(m,1)"``: every mode with one nodal circle (m any); ``"(0,n)"``: the axisymmetric
    membrane modes; ``"(2,1)"``: that mode (both members of its pair); a kind word
    (``out-of-plane``, ``in-plane``, ``pumping``, ``axisymmetric``, ``non-axisymmetric``):
    every mode of that kind.  A pumping mode ``P1, P2, ...`` is covered by ``pumping`` and
    ``out-of-plane`` only.
    """

    families: tuple

    def covers(self, label: str, kind: str) -> bool:
        """Whether a model mode (label, kind) belongs to an observed family."""
        match = _LABEL_MN.match(label or "")
        for family in self.families:
            if family in FAMILY_KINDS:
                if kind in FAMILY_KINDS[family]:
                    return True
                continue
            m_text, n_text = _FAMILY.match(family).groups()
            if match and m_text in ("m", match.group(1)) and n_text in ("n", match.group(2)):
                return True
        return False


def parse_observed(value) -> ObservedFamilies | None:
    """``observed:`` -> :class:`ObservedFamilies` (None: every mode can be seen)."""
    if value is None:
        return None
    allowed = ("a non-empty list of families: (m,n) patterns such as \"(m,1)\", \"(0,n)\", "
               "\"(2,1)\", or " + ", ".join(FAMILY_KINDS))
    if isinstance(value, str) or not isinstance(value, list) or not value:
        raise _fail("observed", value, allowed)
    families = []
    for index, item in enumerate(value):
        text = re.sub(r"\s+", "", item) if isinstance(item, str) else item
        if not isinstance(text, str) or not (text in FAMILY_KINDS or _FAMILY.match(text)):
            raise _fail(f"observed[{index}]", item, allowed)
        families.append(text)
    return ObservedFamilies(tuple(dict.fromkeys(families)))


@dataclass(frozen=True)
class PairingSettings:
    """How scanned shapes pair with the model's (:func:`copdea_fem.vibrometer.pairing.
    correlate_shapes`): relative frequency ``window`` and smallest ``mac_min`` of a pair."""

    window: float = 0.5
    mac_min: float = 0.5


PAIRING_BOUNDS = {"window": (0.01, 2.0), "mac_min": (0.05, 1.0)}


def parse_pairing(value) -> PairingSettings:
    """``pairing:`` -> :class:`PairingSettings` (defaults when absent); ``window`` takes a
    fraction (0.5) or a percentage (``50 %``)."""
    if value is None:
        return PairingSettings()
    if not isinstance(value, dict):
        raise _fail("pairing", value, "a mapping of " + ", ".join(PAIRING_BOUNDS))
    settings = {}
    for key, raw in value.items():
        if key not in PAIRING_BOUNDS:
            raise _fail(f"pairing.{key}", raw, "keys " + ", ".join(PAIRING_BOUNDS),
                        "unknown key")
        number = raw
        if isinstance(raw, str) and raw.strip().endswith("%"):
            try:
                number = float(raw.strip()[:-1]) / 100
            except ValueError:
                number = raw
        lo, hi = PAIRING_BOUNDS[key]
        if (isinstance(number, bool) or not isinstance(number, (int, float))
                or not math.isfinite(number) or not lo <= number <= hi):
            raise _fail(f"pairing.{key}", raw, f"a number in [{lo:g}, {hi:g}]"
                        + (" (or a percentage)" if key == "window" else ""))
        settings[key] = float(number)
    return PairingSettings(**settings)


__all__ = [
    "Condition",
    "MeasuredDataError",
    "MeasuredSet",
    "NoiseModel",
    "ObservedFamilies",
    "PairingSettings",
    "Resonance",
    "Spectrum",
    "load_measured",
    "normalise_label",
    "parse_measured",
    "parse_observed",
    "parse_pairing",
    "read_resonances",
    "read_spectrum",
]
