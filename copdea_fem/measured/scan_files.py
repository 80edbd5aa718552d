"""Scan files by format: :func:`read_scan` picks a file's reader by its suffix.

A reader is ``read(path, *, frame, directions, geometry) -> ScanData``
(:func:`copdea_fem.measured.uff.read_scan` reads Universal File Format exports); a new
format is one module with its reader and one line of :data:`SCAN_READERS`.
"""

from __future__ import annotations

from pathlib import Path

from copdea_fem.measured import uff
from copdea_fem.measured.errors import refusal
from copdea_fem.measured.scan import ScanData, ScanFrame

#: The reader of each scan file suffix (lower case; a file's suffix is matched in any case).
SCAN_READERS = {".uff": uff.read_scan, ".unv": uff.read_scan}


def read_scan(path, *, frame: ScanFrame | None = None, directions=None,
              geometry: bool = True) -> ScanData:
    """A vibrometer's scan file as a :class:`ScanData` (SI, the model's frame), read by the
    reader of its suffix (:data:`SCAN_READERS`).

    Parameters
    ----------
    path : path-like
        The scan file (``.uff``/``.unv``: :func:`copdea_fem.measured.uff.read_scan`).
    frame : ScanFrame, optional
        Where the model's frame lies in the file's coordinates (default: they are the
        model's).
    directions : (3,) sequence or dict, optional
        A 1-D laser's measuring direction in the file's axes, one for every point or
        ``{node: [x, y, z]}`` per point.
    geometry : bool, default True
        Whether the file must give the points' coordinates (False: a file without them
        gives its measured nodes, positions NaN).

    Returns
    -------
    ScanData

    Raises
    ------
    MeasuredDataError
        A suffix no reader takes (naming the file, the suffix and the suffixes allowed), or
        the reader's refusal of the file.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SCAN_READERS:
        raise refusal(f"scan file {str(path)!r} suffix", path.suffix, ", ".join(SCAN_READERS))
    return SCAN_READERS[suffix](path, frame=frame, directions=directions, geometry=geometry)


__all__ = ["SCAN_READERS", "read_scan"]
