"""Universal File Format (UFF/UNV) exports of a scanning vibrometer, read (written by
:func:`copdea_fem.measured.uff_writer.write_scan`).

A PSV-type export holds the scan points (dataset 2411, or the older 15), the units
(164) and one function per point and direction (58, ASCII or binary "58b"): FRFs of
the velocity per volt of drive (function type 4) or velocity spectra (type 12).
:mod:`pyuff` parses the datasets; this module turns them into a :class:`ScanData` in SI
and in the model's frame, and refuses a file it cannot trust with a
:class:`MeasuredDataError` naming the file and the dataset.

Units.  Dataset 164's factors and each dataset 58's unit labels and exponents give the
factor to SI of every function (:mod:`copdea_fem.measured.uff_units`); a label that names
no unit (``NONE``) is said in a warning.  Fortran ``D`` exponents in 58 data lines are
read as ``E``; a value above :data:`LARGEST_VALUE` (how pyuff writes infinity) is refused.

Points and channels.  Every response is put on its point by its measured node, never by
its place in the file: the response node (``rsp_node``), or with one response and several
references (a roving hammer) the reference node, by reciprocity
(:mod:`copdea_fem.measured.references`); a node without coordinates, a point without a
response and two responses of one node and direction are refused.  The direction is the
axis ``rsp_dir`` = +-1, 2, 3 (x, y, z) of the node's displacement coordinate system
(global unless datasets 18/2420 say otherwise: :mod:`copdea_fem.measured.coordinates`,
which also places nodes defined in a local system), or for a 1-D laser the per-point
direction given in measured.yaml.  Channels are ordered by point (in the geometry's
order) and then by direction, whatever the file's order.  A file with a 2411 and a 15
that disagree is read from its 2411, with a warning.
"""

from __future__ import annotations

import contextlib
import io
import logging
import math
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from copdea_fem.inputs import preview
from copdea_fem.measured.coordinates import (
    GLOBAL,
    system_of,
    systems_from_18,
    systems_from_2420,
)
from copdea_fem.measured.errors import MeasuredDataError
from copdea_fem.measured.references import ROVING_REFERENCE, layout
from copdea_fem.measured.scan import ScanData, ScanFrame
from copdea_fem.measured.uff_units import (
    already_divided,
    decode_label,
    exponent_factor,
    parse_unit_label,
    response_of,
)

logger = logging.getLogger(__name__)

#: UFF function types read as scans: 4 = frequency response function, 12 = spectrum.
FUNCTION_TYPES = {4: "frf", 12: "spectrum"}
#: Names of the UFF function types (record 6 of dataset 58), for refusals.
FUNCTION_TYPE_NAMES = {0: "general or unknown", 1: "time response", 2: "auto spectrum",
                       3: "cross spectrum", 4: "frequency response function",
                       5: "transmissibility", 6: "coherence", 7: "auto correlation",
                       8: "cross correlation", 9: "power spectral density",
                       10: "energy spectral density", 11: "probability density function",
                       12: "spectrum", 13: "cumulative frequency distribution",
                       14: "peaks valley", 15: "stress/cycles", 16: "strain/cycles",
                       17: "orbit", 18: "mode indicator function", 19: "force pattern",
                       20: "partial power", 21: "partial coherence", 22: "eigenvalue",
                       23: "eigenvector", 24: "shock response spectrum",
                       25: "finite impulse response filter", 26: "multiple coherence",
                       27: "order function", 28: "phase compensation"}
#: Largest magnitude taken as a measured number: pyuff writes an infinity as the largest
#: double (1.797e308), and anything within a factor 10 of it is an overflow, not data.
LARGEST_VALUE = 1e307


@dataclass(frozen=True)
class FunctionRecord:
    """One dataset 58 read and converted to SI (:func:`read_functions`).

    Attributes
    ----------
    dataset : int
        1-based position of the dataset in the file (named in errors).
    function_type : int
        UFF function type (1 time, 4 FRF, 9 PSD, 12 spectrum, ...).
    response_node, response_direction, reference_node, reference_direction : int
        Records 6 of the dataset (``rsp_node``, ``rsp_dir``, ``ref_node``, ``ref_dir``).
    abscissa : (F,) float array
        Frequencies [Hz] (time [s] for a time history).
    values : (F,) complex array
        The ordinate (divided by the denominator for an FRF) in SI.
    ordinate_label, denominator_label : str
        The unit labels as written in the file (decoded).
    si_factor : float
        The factor applied to the file's numbers.
    response : str
        displacement, velocity, acceleration or unknown.
    labelled : bool
        Whether the ordinate's label names a unit (else 164 and the exponents gave it).
    """

    dataset: int
    function_type: int
    response_node: int
    response_direction: int
    reference_node: int
    reference_direction: int
    abscissa: np.ndarray
    values: np.ndarray
    ordinate_label: str
    denominator_label: str
    si_factor: float
    response: str
    labelled: bool = True


def _where(path: Path, dataset: str) -> str:
    return f"scan file {str(path)!r} dataset {dataset}"


def _error(path: Path, dataset: str, problem: str, allowed: str) -> MeasuredDataError:
    return MeasuredDataError(f"{_where(path, dataset)}: {problem}; allowed: {allowed}")



#: A dataset 58's delimiter and type line (after a newline; at the file's start, without).
_DATASET_58 = rb" {4}-1[ \t]*\r?\n {4}58b?(?=[ \t\r\n])"


def _raw_58_headers(data: bytes) -> list[list[bytes]]:
    """The 13 header lines of every dataset 58 in the file's bytes, in file order."""
    # the pattern starts with a literal newline so that the search skips ahead by it (a
    # leading "(?:^|\n)" made it try every byte: 0.1 s on a PSV-size binary export)
    starts = [0] if re.match(_DATASET_58, data) else []
    starts += [match.start() + 1 for match in re.finditer(rb"\n" + _DATASET_58, data)]
    return [data[start:start + 13 * 200].splitlines()[:13] for start in starts]


# --- reading --------------------------------------------------------------------------

def _open(path: Path):
    import pyuff

    if not path.is_file():
        raise _error(path, "-", "a folder, not a file" if path.is_dir() else
                     "the file does not exist", "an existing .uff/.unv file")
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            uff = pyuff.UFF(str(path))
            types = [int(t) for t in uff.get_set_types()]
    except Exception as error:  # noqa: BLE001 -- pyuff raises bare Exceptions
        raise _error(path, "-", f"not a readable UFF file ({error})",
                     "a Universal File Format export") from None
    if not types:
        raise _error(path, "-", "no dataset found (no '    -1' delimited block)",
                     "a Universal File Format export")
    return uff, types


def _read_set(uff, index: int, path: Path, kind: int):
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            return uff.read_sets(index)
    except Exception as error:  # noqa: BLE001 -- pyuff raises bare Exceptions
        raise _error(path, f"{kind} #{index + 1}", f"cannot be parsed ({error})",
                     "a well-formed dataset") from None


def read_units(path) -> dict:
    """Dataset 164's factors (``length``, ``force``: ``SI = value / factor``), or SI ones."""
    path = Path(path)
    uff, types = _open(path)
    return _units(uff, types, path)


def _units(uff, types, path) -> dict:
    if 164 not in types:
        return {"length": 1.0, "force": 1.0}
    index = types.index(164)
    record = _read_set(uff, index, path, 164)
    units = {"length": float(record.get("length", 1.0)), "force": float(record.get("force", 1.0))}
    for name, value in units.items():
        if not math.isfinite(value) or value <= 0:
            raise _error(path, f"164 #{index + 1}", f"{name} factor = {value!r}",
                         "a finite factor > 0")
    return units


def read_geometry(path) -> tuple[np.ndarray, np.ndarray]:
    """Node numbers (P,) and coordinates (P, 3) [m, in the file's global axes] of dataset
    2411 (else 15; the first one of the file), lengths converted with dataset 164 and the
    nodes' coordinate systems (datasets 18, 2420) applied."""
    path = Path(path)
    uff, types = _open(path)
    nodes, coordinates, _ = _geometry(uff, types, path, _units(uff, types, path)["length"])
    return nodes, coordinates


def _node_record(uff, types, path, kind: int):
    index = types.index(kind)
    record = _read_set(uff, index, path, kind)
    where = f"{kind} #{index + 1}"
    try:
        nodes = np.asarray(record["node_nums"], float)
        coordinates = np.column_stack([np.asarray(record[a], float) for a in "xyz"])
        systems = [np.asarray(record.get(key, np.zeros(nodes.size)), float).reshape(-1)
                   for key in ("def_cs", "disp_cs")]
    except (KeyError, ValueError) as error:
        raise _error(path, where, f"incomplete node records ({error})",
                     "node number, coordinate systems and x, y, z per node") from None
    if nodes.size == 0:
        raise _error(path, where, "no node", "at least one scan point")
    if not np.all(np.isfinite(coordinates)) or not np.all(np.isfinite(nodes)):
        bad = int(nodes[np.flatnonzero(~np.all(np.isfinite(coordinates), axis=1))[0]]) \
            if np.all(np.isfinite(nodes)) else "?"
        raise _error(path, where, f"node {bad} has a coordinate that is not a number",
                     "finite coordinates")
    unique, counts = np.unique(nodes, return_counts=True)
    if np.any(counts > 1):
        raise _error(path, where, f"node {int(unique[counts > 1][0])} defined twice",
                     "each node once")
    if any(s.size != nodes.size for s in systems):
        systems = [np.zeros(nodes.size), np.zeros(nodes.size)]
    return where, nodes.astype(int), coordinates, systems[0].astype(int), \
        systems[1].astype(int)


def _systems(uff, types, path, scale: float) -> dict:
    """The file's coordinate systems (datasets 18 and 2420) by label."""
    systems = {}
    for kind, reader in ((18, systems_from_18), (2420, systems_from_2420)):
        indices = [i for i, t in enumerate(types) if t == kind]
        if indices:
            records = [_read_set(uff, i, path, kind) for i in indices]
            systems.update(reader(records, _where(path, f"{kind} #{indices[0] + 1}"), scale))
    return systems


def _geometry(uff, types, path, length_factor: float, length_unit: float | None = None):
    """(nodes (P,), coordinates (P, 3) [m, global], displacement systems (P,) of
    :class:`CoordinateSystem`): dataset 2411, else 15; both present and not the same nodes
    at the same places: 2411 used, with a warning naming both."""
    kind = 2411 if 2411 in types else 15 if 15 in types else None
    if kind is None:
        raise _error(path, "2411/15", "no geometry (no dataset 2411 or 15 with the scan "
                     "points)", "an export with the scan points' coordinates")
    scale = length_unit if length_unit is not None else 1.0 / length_factor
    where, nodes, coordinates, defined_in, displaced_in = _node_record(uff, types, path, kind)
    systems = _systems(uff, types, path, scale)
    coordinates = coordinates * scale
    raw = coordinates.copy()
    for k in np.flatnonzero(defined_in):
        system = system_of(systems, int(defined_in[k]), int(nodes[k]), _where(path, where))
        coordinates[k] = system.point(coordinates[k][None])[0]
    displacement = [system_of(systems, int(label), int(node), _where(path, where))
                    for label, node in zip(displaced_in, nodes)]
    if kind == 2411 and 15 in types:
        other, old_nodes, old_coordinates, *_ = _node_record(uff, types, path, 15)
        same = np.array_equal(np.sort(old_nodes), np.sort(nodes))
        if same:
            order = np.argsort(old_nodes)[np.argsort(np.argsort(nodes))]
            # dataset 15 writes coordinates with 6 significant digits (E13.5)
            same = np.allclose(old_coordinates[order] * scale, raw, rtol=0,
                               atol=1e-5 * max(float(np.abs(raw).max()), 1e-300))
        if not same:
            logger.warning("%s: dataset %s (%d nodes) and dataset %s (%d nodes) give "
                           "different nodes or coordinates: %s used, %s ignored",
                           f"scan file {str(path)!r}", where, nodes.size, other,
                           old_nodes.size, where, other)
    return nodes, coordinates, displacement


def read_functions(path, *, units: dict | None = None) -> tuple[FunctionRecord, ...]:
    """Every dataset 58 of a file in SI (see the module notes on units).

    A binary 58b that :mod:`pyuff` cannot parse is read again after pyuff's own fix for
    commercial exports (:func:`pyuff.datasets.dataset_58.fix_58b`, on a temporary copy).
    """
    path = Path(path)
    uff, types = _open(path)
    units = units or _units(uff, types, path)
    return _functions(uff, types, path, units)


def _functions(uff, types, path, units) -> tuple[FunctionRecord, ...]:
    indices = [i for i, t in enumerate(types) if t == 58]
    data = path.read_bytes()
    try:
        records = [_read_58(uff, i) for i in indices]
    except _Unparsed as failed:
        if b"58b" in data:
            records, data = _read_fixed(path, types, failed)
        else:
            records, data = _read_with_e_exponents(path, data, failed)
    headers = _raw_58_headers(data)
    if len(headers) != len(records):
        headers = [None] * len(records)
    out = []
    for index, record, header in zip(indices, records, headers):
        out.append(_function(path, index, record, header, units))
    unlabelled = [record for record in out if not record.labelled]
    if unlabelled:
        first = unlabelled[0]
        logger.warning("scan file %r: %d of %d datasets 58 have an ordinate unit label that "
                       "names no unit (%r in 58 #%d): their unit taken as dataset 164's "
                       "units to the exponents of records 8-11 (SI, m N s, without a 164; "
                       "factor to SI %g)", str(path), len(unlabelled), len(out),
                       first.ordinate_label, first.dataset, first.si_factor)
    return tuple(out)


#: A Fortran double's exponent letter (``1.5D+02``, legal in UFF data lines).
_FORTRAN_EXPONENT = re.compile(rb"(?<=[0-9.])[Dd](?=[+-]?[0-9])")
#: An ASCII dataset 58 block: the delimiter, "58", header records 1-6, record 7 (numbers),
#: records 8-11, the data lines.
_ASCII_58 = re.compile(rb"((?:^|\n) {4}-1[ \t]*\r?\n {4}58[ \t]*\r?\n(?:[^\n]*\n){6})"
                       rb"([^\n]*\n)((?:[^\n]*\n){4})"
                       rb"(.*?)(?=\n {4}-1[ \t]*\r?(?:\n|$))", re.DOTALL)


def _read_with_e_exponents(path: Path, data: bytes, failed):
    """The datasets 58 of an ASCII file read again with the Fortran ``D`` exponents of
    their data lines written as ``E`` (on a temporary copy); refused when there are none
    or the copy cannot be read either."""
    import pyuff

    count = 0

    def fixed_block(match):
        nonlocal count
        record_7, found_7 = _FORTRAN_EXPONENT.subn(b"E", match.group(2))
        body, found = _FORTRAN_EXPONENT.subn(b"E", match.group(4))
        count += found + found_7
        return match.group(1) + record_7 + match.group(3) + body

    fixed = _ASCII_58.sub(fixed_block, data)
    if count == 0:
        raise _error(path, f"58 #{failed.index + 1}", f"cannot be parsed ({failed.reason})",
                     "a well-formed dataset 58") from None
    logger.info("scan file %r: %d Fortran D exponents in dataset 58 data lines read as E",
                str(path), count)
    with tempfile.TemporaryDirectory(prefix="copdea-uff-") as folder:
        copy = Path(folder) / path.name
        copy.write_bytes(fixed)
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                uff = pyuff.UFF(str(copy))
                types = [int(t) for t in uff.get_set_types()]
            records = [_read_58(uff, i) for i, t in enumerate(types) if t == 58]
        except _Unparsed as again:
            raise _error(path, f"58 #{again.index + 1}", f"cannot be parsed ({again.reason}, "
                         "also with its D exponents read as E)", "a well-formed dataset 58") \
                from None
        except Exception as error:  # noqa: BLE001 -- pyuff raises bare Exceptions
            raise _error(path, f"58 #{failed.index + 1}", f"cannot be parsed ({error})",
                         "a well-formed dataset 58") from None
    return records, fixed


class _Unparsed(Exception):
    def __init__(self, index, reason):
        super().__init__(reason)
        self.index, self.reason = index, reason


def _read_58(uff, index):
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            return uff.read_sets(index)
    except Exception as error:  # noqa: BLE001 -- pyuff raises bare Exceptions
        raise _Unparsed(index, str(error)) from None


def _read_fixed(path: Path, types, failed: _Unparsed):
    import pyuff
    from pyuff.datasets.dataset_58 import fix_58b

    logger.info("%s: dataset 58 #%d unreadable, reading pyuff's fixed copy", path.name,
                failed.index + 1)
    with tempfile.TemporaryDirectory(prefix="copdea-uff-") as folder:
        fixed = Path(folder) / path.name
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                fix_58b(str(path), str(fixed))
                uff = pyuff.UFF(str(fixed))
                fixed_types = [int(t) for t in uff.get_set_types()]
        except Exception as error:  # noqa: BLE001 -- pyuff raises bare Exceptions
            raise _error(path, f"58 #{failed.index + 1}", f"cannot be parsed ({failed.reason}; "
                         f"pyuff's 58b fix failed too: {error})", "a well-formed dataset 58") \
                from None
        indices = [i for i, t in enumerate(fixed_types) if t == 58]
        try:
            records = [_read_58(uff, i) for i in indices]
        except _Unparsed as again:
            raise _error(path, f"58 #{again.index + 1}", f"cannot be parsed ({again.reason}, "
                         "also after pyuff's 58b fix)", "a well-formed dataset 58") from None
        return records, fixed.read_bytes()


def _label(record: dict, header, line: int, key: str) -> str:
    """A unit label from the raw header bytes (columns 47-67 of records 8-11), else pyuff's."""
    if header is not None and len(header) > line:
        return decode_label(header[line][46:67])
    return str(record.get(key, "")).strip()


def _function(path, index, record, header, units) -> FunctionRecord:
    where = f"58 #{index + 1}"
    try:
        abscissa = np.asarray(record["x"], float)
        values = np.asarray(record["data"])
        node = int(record["rsp_node"])
    except (KeyError, TypeError, ValueError) as error:
        raise _error(path, where, f"incomplete record ({error})", "a dataset 58 with data") \
            from None
    where = f"58 #{index + 1} (response node {node})"
    if values.size == 0 or abscissa.size != values.size:
        raise _error(path, where, f"{values.size} values on {abscissa.size} abscissae",
                     "one value per abscissa, at least one")
    bad = ~np.isfinite(values) | ~np.isfinite(abscissa)
    if np.any(bad):
        raise _error(path, where, f"{int(bad.sum())} values are NaN or infinite (first at "
                     f"abscissa {abscissa[np.argmax(bad)]:g})", "finite numbers")
    parts = np.column_stack([np.real(values).ravel(), np.imag(values).ravel()])
    huge = np.abs(parts).max(axis=1) > LARGEST_VALUE
    if np.any(huge):
        first = int(np.argmax(huge))
        raise _error(path, where, f"{int(huge.sum())} values of magnitude above "
                     f"{LARGEST_VALUE:g} (first {np.abs(parts[first]).max():.4g} at abscissa "
                     f"{abscissa[first]:g}: how pyuff writes infinity, or an overflow)",
                     f"finite measured numbers (below {LARGEST_VALUE:g})")
    function_type = int(record.get("func_type", 0))
    ordinate_text = _label(record, header, 10, "ordinate_axis_units_lab")
    denominator_text = _label(record, header, 11, "orddenom_axis_units_lab")
    abscissa_text = _label(record, header, 9, "abscissa_axis_units_lab")
    ordinate = parse_unit_label(ordinate_text)
    denominator = parse_unit_label(denominator_text) if function_type == 4 else None
    factor = ordinate.factor if ordinate else exponent_factor(units, record, "ordinate")
    dimensions = ordinate.dimensions if ordinate else None
    if function_type == 4:
        if denominator is not None:
            if dimensions is not None and already_divided(dimensions, denominator.dimensions):
                dimensions = {k: dimensions.get(k, 0) + denominator.dimensions.get(k, 0)
                              for k in set(dimensions) | set(denominator.dimensions)}
                dimensions = {k: v for k, v in dimensions.items() if v}
            else:
                factor /= denominator.factor
        else:
            factor /= exponent_factor(units, record, "orddenom")
    abscissa_unit = parse_unit_label(abscissa_text)
    if abscissa_unit is not None and abscissa_unit.dimensions == {"[time]": -1}:
        abscissa = abscissa * abscissa_unit.factor
    response = response_of(dimensions, int(record.get("ordinate_spec_data_type", 0)))
    return FunctionRecord(
        dataset=index + 1, function_type=function_type, response_node=node,
        response_direction=int(record.get("rsp_dir", 0)),
        reference_node=int(record.get("ref_node", 0)),
        reference_direction=int(record.get("ref_dir", 0)), abscissa=abscissa,
        values=values.astype(complex) * factor, ordinate_label=ordinate_text,
        denominator_label=denominator_text, si_factor=factor, response=response,
        labelled=ordinate is not None)


def _direction_vector(value, where: str) -> np.ndarray:
    try:
        vector = np.asarray(value, float).reshape(3)
    except (TypeError, ValueError):
        raise MeasuredDataError(f"{where} = {preview(value)} is not allowed; allowed: a "
                                "direction [x, y, z] (three numbers, not all zero)") from None
    norm = float(np.linalg.norm(vector))
    if not math.isfinite(norm) or norm == 0:
        raise MeasuredDataError(f"{where} = {preview(value)} is not allowed; allowed: a "
                                "direction [x, y, z] (three finite numbers, not all zero)")
    return vector / norm


def read_scan(path, *, frame: ScanFrame | None = None, directions=None,
              geometry: bool = True) -> ScanData:
    """A vibrometer's UFF export as a :class:`ScanData` (SI, the model's frame).

    Parameters
    ----------
    path : path-like
        The ``.uff``/``.unv`` file.
    frame : ScanFrame, optional
        Where the model's frame lies in the file's coordinates; default: the file's
        coordinates are the model's (lengths converted with dataset 164).
    directions : (3,) sequence or dict, optional
        A 1-D laser's measuring direction in the file's axes: one for every point, or
        ``{node: [x, y, z]}`` per point.  It replaces ``rsp_dir`` for those points;
        without it ``rsp_dir`` must be +-1, 2 or 3.
    geometry : bool, default True
        Whether the file must hold the points' coordinates (dataset 2411/15); without
        one (``geometry=False`` only) the points are the measured nodes, their positions
        NaN.

    Returns
    -------
    ScanData

    Raises
    ------
    MeasuredDataError
        No geometry, a node without data or data without a node, two responses of one
        node and direction, mixed frequency axes or function types, a function type
        other than FRF or spectrum, several references with several responses, NaN, a
        direction that is not given: the message names the file and the dataset.

    Notes
    -----
    The measured node of an FRF is its response node, or with one response and several
    references (a roving hammer) its reference node, by reciprocity
    (:mod:`copdea_fem.measured.references`).  A node's direction code refers to its
    displacement coordinate system (datasets 18, 2420; :mod:`copdea_fem.measured.coordinates`).
    """
    path = Path(path)
    uff, types = _open(path)
    units = _units(uff, types, path)
    frame = frame or ScanFrame()
    has_geometry = 2411 in types or 15 in types
    if geometry or has_geometry:
        nodes, coordinates, systems = _geometry(uff, types, path, units["length"],
                                                frame.length_unit)
    if 58 not in types:
        raise _error(path, "58", "no response function (no dataset 58)",
                     "one dataset 58 per scan point and direction")
    records = _functions(uff, types, path, units)
    _check_function_types(path, records)
    first = records[0]
    for record in records:
        where = f"58 #{record.dataset} (response node {record.response_node})"
        if record.abscissa.shape != first.abscissa.shape or not np.allclose(
                record.abscissa, first.abscissa, rtol=1e-9, atol=0.0):
            raise _error(path, where, f"a frequency axis of {record.abscissa.size} lines "
                         f"{record.abscissa[0]:g}..{record.abscissa[-1]:g} Hz unlike dataset "
                         f"58 #{first.dataset}'s {first.abscissa.size} lines "
                         f"{first.abscissa[0]:g}..{first.abscissa[-1]:g} Hz (mixed "
                         "frequency axes)", "one frequency axis for every response")
        if record.response != first.response:
            raise _error(path, where, f"a {record.response} response beside a "
                         f"{first.response} one in dataset 58 #{first.dataset}",
                         "one response quantity in a scan")
    frequencies = first.abscissa
    if frequencies.size < 2 or np.any(np.diff(frequencies) <= 0) or frequencies[0] < 0:
        raise _error(path, f"58 #{first.dataset}", "frequencies not strictly increasing "
                     "from >= 0", "a frequency axis of at least two increasing lines")
    swapped = layout(records, f"scan file {str(path)!r}") == ROVING_REFERENCE
    measured_at = [(r.reference_node, r.reference_direction) if swapped
                   else (r.response_node, r.response_direction) for r in records]
    if not (geometry or has_geometry):
        nodes = np.array(sorted({node for node, _ in measured_at}), int)
        coordinates = np.full((nodes.size, 3), np.nan)
        systems = [GLOBAL] * nodes.size
        logger.info("scan file %r: no geometry (dataset 2411/15): %d nodes without "
                    "coordinates", str(path), nodes.size)
    point_of = {int(node): i for i, node in enumerate(nodes)}
    per_point = _point_directions(directions, point_of, path)
    role = "reference" if swapped else "response"
    channels, seen = [], {}
    for record, (node, code) in zip(records, measured_at):
        where = f"58 #{record.dataset} ({role} node {node})"
        if node not in point_of:
            raise _error(path, where, f"node {node} has no coordinates in "
                         "the geometry (dataset 2411/15)", "responses of scan points only")
        point = point_of[node]
        if point in per_point:
            direction = per_point[point]
        elif abs(code) in (1, 2, 3):
            direction = np.zeros(3)
            direction[abs(code) - 1] = np.sign(code)
            direction = systems[point].direction(direction[None])[0]
        else:
            raise _error(path, where, f"{role} direction {code} and no "
                         "direction given for the point", "rsp_dir +-1, +-2, +-3 (global x, "
                         "y, z) or a 1-D laser's direction in measured.yaml (scan_directions)")
        key = (point, tuple(np.round(direction, 9)))
        if key in seen:
            raise _error(path, where, f"a second {role} of node {node} "
                         f"along {direction.tolist()} (also dataset 58 #{seen[key]})",
                         f"one {role} per node and direction")
        seen[key] = record.dataset
        order = abs(code) if point not in per_point else 0
        channels.append((point, order, record.dataset, direction, record.values))
    measured = {point for point, *_ in channels}
    missing = [int(nodes[i]) for i in range(len(nodes)) if i not in measured]
    if missing and geometry:
        raise _error(path, "2411/15", f"{len(missing)} node(s) without data (first: node "
                     f"{missing[0]})", "a response (dataset 58) for every scan point")
    if missing:
        logger.info("scan file %r: %d geometry nodes without data (first: node %d) left out",
                    str(path), len(missing), missing[0])
        keep = np.array(sorted(measured), int)
        renumber = {int(old): new for new, old in enumerate(keep)}
        channels = [(renumber[c[0]], *c[1:]) for c in channels]
        nodes, coordinates = nodes[keep], coordinates[keep]
    channels.sort(key=lambda c: (c[0], c[1], c[2]))
    rotation = frame.rotation()
    origin = np.asarray(frame.origin, float) * (frame.length_unit if frame.length_unit
                                                is not None else 1.0 / units["length"])
    positions = (coordinates - origin) @ rotation.T
    directions_model = np.array([c[3] for c in channels]) @ rotation.T
    return ScanData(path=path, nodes=nodes, positions=positions,
                    channel_point=np.array([c[0] for c in channels], int),
                    channel_direction=directions_model, frequencies=frequencies,
                    values=np.array([c[4] for c in channels]),
                    quantity=FUNCTION_TYPES[first.function_type], response=first.response)


def _check_function_types(path: Path, records) -> None:
    """Refuse a file with a function type other than FRF or spectrum, or with both,
    listing what the file holds and what is accepted."""
    held: dict[int, list[int]] = {}
    for record in records:
        held.setdefault(record.function_type, []).append(record.dataset)

    def named(kind):
        datasets = held[kind]
        where = ", ".join(f"#{d}" for d in datasets[:3]) + (" ..." if len(datasets) > 3 else "")
        return (f"function type {kind} ({FUNCTION_TYPE_NAMES.get(kind, 'unknown')}) in "
                f"{len(datasets)} dataset(s) 58 {where}")

    unread = [record for record in records if record.function_type not in FUNCTION_TYPES]
    if unread:
        raise _error(path, f"58 #{unread[0].dataset} (response node "
                     f"{unread[0].response_node})",
                     f"the file holds {'; '.join(named(k) for k in sorted(held))}",
                     "function type 4 (frequency response function) or 12 (spectrum) in "
                     "every dataset 58")
    if len(held) > 1:
        raise _error(path, "58", f"the file holds {'; '.join(named(k) for k in sorted(held))}",
                     "one function type in a scan")


def _point_directions(directions, point_of: dict, path: Path) -> dict:
    if directions is None:
        return {}
    if isinstance(directions, dict):
        out = {}
        for node, value in directions.items():
            try:
                point = point_of[int(node)]
            except (KeyError, TypeError, ValueError):
                raise MeasuredDataError(f"scan_directions node {preview(node)} is not allowed "
                                        f"(not a scan point of {preview(path)}); allowed: the "
                                        "file's node numbers") from None
            out[point] = _direction_vector(value, f"scan_directions[{node}]")
        return out
    vector = _direction_vector(directions, "scan_directions")
    return {point: vector for point in point_of.values()}


def read_trace_lines(path) -> tuple[tuple[str, tuple[np.ndarray, ...]], ...]:
    """Every dataset 82 (trace lines) of a file: ``(name, polylines)``, each polyline the
    (n,) node numbers drawn one after another (a node 0 lifts the pen: a new polyline)."""
    path = Path(path)
    uff, types = _open(path)
    out = []
    for index, kind in enumerate(types):
        if kind != 82:
            continue
        record = _read_set(uff, index, path, 82)
        try:
            count = int(record.get("n_nodes", 0))
            nodes = np.asarray(record["nodes"], float)[:count].astype(int)
        except (KeyError, TypeError, ValueError) as error:
            raise _error(path, f"82 #{index + 1}", f"incomplete record ({error})",
                         "a dataset 82 of trace lines") from None
        parts = [part[part != 0] for part in np.split(nodes, np.flatnonzero(nodes == 0))]
        polylines = tuple(part for part in parts if part.size >= 2)
        out.append((str(record.get("id", "")).strip() or f"trace {index + 1}", polylines))
    return tuple(out)


# --- dataset 55: identified mode shapes ------------------------------------------------

@dataclass(frozen=True)
class ModeSet:
    """One dataset 55 (a mode shape an identification program exported).

    ``frequency_hz`` and ``damping_ratio`` from the complex eigenvalue (record 8:
    ``s = -zeta w + i w sqrt(1 - zeta^2)``, damped frequency ``|Im s| / 2 pi``) when there is
    one, else from the text header; ``shape`` (P, 3) complex per node of ``nodes``.
    """

    dataset: int
    mode: int
    frequency_hz: float
    damping_ratio: float
    nodes: np.ndarray
    shape: np.ndarray
    header: str


def read_mode_sets(path) -> tuple[ModeSet, ...]:
    """Every dataset 55 of a file (LMS Test.Lab, ARTeMIS mode-shape exports), in file order."""
    path = Path(path)
    uff, types = _open(path)
    out = []
    for index, kind in enumerate(types):
        if kind != 55:
            continue
        record = _read_set(uff, index, path, 55)
        where = f"55 #{index + 1}"
        try:
            nodes = np.asarray(record["node_nums"], int)
            shape = np.column_stack([np.asarray(record.get(f"r{k}", np.zeros(nodes.size)))
                                     for k in (1, 2, 3)])
        except (KeyError, ValueError) as error:
            raise _error(path, where, f"incomplete record ({error})", "a dataset 55") \
                from None
        eigenvalue = record.get("eig")
        header = str(record.get("id4", ""))
        if eigenvalue is not None and complex(eigenvalue) != 0:
            s = complex(eigenvalue)
            frequency, damping = abs(s.imag) / (2 * math.pi), -s.real / abs(s)
        elif record.get("freq") is not None:
            frequency, damping = float(record["freq"]), float(record.get("modal_damp_vis", 0))
        else:
            raise _error(path, where, "no eigenvalue or frequency", "a dataset 55 of modes")
        out.append(ModeSet(index + 1, int(record.get("mode_n", len(out) + 1)), frequency,
                           damping, nodes, shape, header))
    return tuple(out)


__all__ = [
    "FUNCTION_TYPES",
    "FUNCTION_TYPE_NAMES",
    "LARGEST_VALUE",
    "FunctionRecord",
    "ModeSet",
    "read_functions",
    "read_geometry",
    "read_mode_sets",
    "read_scan",
    "read_trace_lines",
    "read_units",
]
