"""The resonance and spectrum CSVs of a measured condition (``resonances:``, ``spectrum:``
in ``measured.yaml``: :mod:`copdea_fem.measured.manifest`).

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
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from copdea_fem.inputs import read_text
from copdea_fem.measured.errors import MeasuredDataError, refusal

logger = logging.getLogger(__name__)

#: The kinds of a resonance (``kind`` column; empty: unknown).
KINDS = ("pumping", "axisymmetric", "non-axisymmetric")
#: Where a spectrum was taken (``spectrum_point``): the scan grid's average or one point.
POINTS = ("average", "Q1", "Q2", "Q3")
RESONANCE_COLUMNS = ("freq_hz", "label", "quality_factor", "kind")


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


_LABEL_PUMPING = re.compile(r"^[Pp]\s*([1-9]\d*)$")
MODE_LABEL = re.compile(r"^\(\s*(\d+)\s*,\s*([1-9]\d*)\s*\)\s*([ab]?)$")


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
    match = MODE_LABEL.match(text)
    if match:
        m, n, suffix = int(match.group(1)), int(match.group(2)), match.group(3)
        return f"({m},{n}){suffix}", "axisymmetric" if m == 0 else "non-axisymmetric"
    raise refusal(where, text, "empty, P1, P2, ... or (m,n) with m >= 0, n >= 1 and an optional "
                  "a/b, e.g. (0,1), (1,1)a")


def _read_rows(path: Path, key: str):
    if not path.exists():
        raise refusal(key, path, "an existing CSV file", "file does not exist")
    text = read_text(path, key, error=MeasuredDataError)
    lines = text.splitlines()
    rows = list(csv.reader(r for r in lines if r.strip() and not r.lstrip().startswith("#")))
    if not rows:
        raise refusal(key, path, "a CSV with a header row", "empty file")
    return [name.strip() for name in rows[0]], rows[1:]


def _number(text, where, positive=True, allow_empty=False):
    text = (text or "").strip()
    if not text:
        if allow_empty:
            return math.nan
        raise refusal(where, text, "a number")
    try:
        value = float(text)
    except ValueError:
        raise refusal(where, text, "a number in SI units") from None
    if not math.isfinite(value) or (positive and value <= 0) or value < 0:
        raise refusal(where, text, "a finite number > 0" if positive else "a finite number >= 0")
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
        raise refusal(f"{key} columns", header, "freq_hz and optionally label, quality_factor, "
                      f"kind (file {path})")
    index = {name: header.index(name) for name in header}
    out, seen, lines_of = [], {}, {}
    for line, row in enumerate(rows, start=2):
        row = _rejoin_labels(row, len(header))
        where = f"{path.name} line {line}"
        same = tuple(cell.strip() for cell in row)
        if same in lines_of:        # a peak pasted twice would weigh twice in the fit
            logger.warning(f"{where} repeats line {lines_of[same]} (a duplicated peak): "
                           "counted once")
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
            raise refusal(f"{where} kind", kind, ", ".join(KINDS) + " or empty")
        elif implied and kind != implied:
            raise refusal(f"{where} kind", kind, f"{implied} (the kind of label {label})")
        quality = _number(cell("quality_factor"), f"{where} quality_factor", allow_empty=True)
        if label:
            if label in seen:
                raise refusal(f"{where} label", label, "each label once per condition",
                              f"also on line {seen[label]}")
            seen[label] = line
        out.append(Resonance(frequency, label, kind, quality))
    if not out:
        raise refusal(key, path, "at least one resonance row")
    return tuple(sorted(out, key=lambda r: r.frequency_hz))


def read_spectrum(path, point: str = "average", key: str = "spectrum") -> Spectrum:
    """Spectrum CSV -> :class:`Spectrum` (cartesian components converted, see module notes)."""
    path = Path(path)
    header, rows = _read_rows(path, key)
    if point not in POINTS:
        raise refusal("spectrum_point", point, ", ".join(POINTS))
    if "freq_hz" in header and {"v_axial", "v_radial"} <= set(header):
        names = ("freq_hz", "v_axial", "v_radial")
    elif "freq_hz" in header and {"v_x", "v_y", "v_z"} <= set(header):
        names = ("freq_hz", "v_x", "v_y", "v_z")
    else:
        raise refusal(f"{key} columns", header, "freq_hz, v_axial, v_radial or freq_hz, v_x, v_y, "
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
        raise refusal(f"{key} freq_hz", f"{frequency.size} rows", "at least 8 rows with strictly "
                      f"increasing frequencies (file {path})")
    if "v_axial" in data:
        axial, radial = data["v_axial"], data["v_radial"]
    else:
        axial = data["v_z"]
        radial = (math.pi / 4 * (data["v_x"] + data["v_y"]) if point == "average"
                  else np.hypot(data["v_x"], data["v_y"]))
    return Spectrum(frequency, axial, radial, point)


__all__ = ["KINDS", "MODE_LABEL", "POINTS", "RESONANCE_COLUMNS", "Resonance", "Spectrum",
           "normalise_label", "read_resonances", "read_spectrum"]
