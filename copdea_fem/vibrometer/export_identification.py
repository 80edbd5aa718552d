"""The modes of any structure's UFF export, without a study (``copdea-fem identify FILE``).

The file is read as a scan (:func:`copdea_fem.measured.read_scan` with ``geometry=False``:
a file without dataset 2411/15 gives its nodes without coordinates; one reference or one
response by reciprocity, :mod:`copdea_fem.measured.references`) and identified as a
study's scan is (:func:`copdea_fem.vibrometer.identification.identify_scan`: LSCF poles,
LSFD residues).  What is written:

``modes.csv``           one row per mode: test_mode, freq_hz [Hz], damping_ratio [-], mpc [-]
``shapes.csv``          the complex shape per node and direction (the residue of each
                        channel [the FRF's unit times rad/s]), the node's coordinates [m]
                        and the channel's unit direction in the file's global axes
``stabilisation.png``   the stabilisation diagram
``shapes/``             one VTU per mode on the file's points and ``shapes.pvd`` (only with
                        a geometry): the trace lines (dataset 82) as lines where the file
                        has them, else the points as vertices
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from copdea_fem.measured import ScanData
from copdea_fem.vibrometer.identification import Identification

logger = logging.getLogger(__name__)

#: Columns of modes.csv.
MODES_COLUMNS = ("test_mode", "freq_hz", "damping_ratio", "mpc")
#: Columns of shapes.csv (coordinates [m]; direction: unit vector; shape: the residue).
SHAPE_COLUMNS = ("test_mode", "freq_hz", "node", "x_m", "y_m", "z_m", "direction_x",
                 "direction_y", "direction_z", "shape_real", "shape_imag", "shape_abs",
                 "shape_phase_deg")


@dataclass(frozen=True)
class ExportIdentification:
    """The modes of one export: the scan read, the identification (modes and diagram),
    the trace lines (``(name, polylines of node numbers)``, dataset 82) and whether the
    file gave coordinates."""

    scan: ScanData
    identification: Identification
    trace_lines: tuple = ()

    @property
    def has_geometry(self) -> bool:
        return bool(np.all(np.isfinite(self.scan.positions)))

    @property
    def modes(self) -> tuple:
        return self.identification.modes


def trace_segments(scan: ScanData, trace_lines) -> np.ndarray:
    """(S, 2) point indices of the trace lines' segments whose both ends are scan points
    (a segment to a node without data is left out)."""
    point_of = {int(node): i for i, node in enumerate(scan.nodes)}
    segments = []
    for _, polylines in trace_lines:
        for polyline in polylines:
            for a, b in itertools.pairwise(polyline):
                if int(a) in point_of and int(b) in point_of and a != b:
                    segments.append((point_of[int(a)], point_of[int(b)]))
    return np.array(segments, int).reshape(-1, 2)


def export_meshes(result: ExportIdentification):
    """``(name, VtuMesh)`` per mode on the file's points: point data ``shape_real``,
    ``shape_imag`` (P, 3) and ``shape_abs`` (P,) [residue units]; cells the trace lines
    (VTK lines), else one vertex per point."""
    from copdea_fem.vibrometer.identified import point_vectors
    from copdea_fem.vtu import VtuMesh

    scan = result.scan
    segments = trace_segments(scan, result.trace_lines)
    cells = [("line", segments)] if segments.size else \
        [("vertex", np.arange(scan.n_points).reshape(-1, 1))]
    out = []
    for mode in result.modes:
        vectors = point_vectors(scan, mode.shape)
        data = {"shape_real": vectors.real, "shape_imag": vectors.imag,
                "shape_abs": np.linalg.norm(np.abs(vectors), axis=1)}
        out.append((f"mode_{mode.test_mode:02d}_{mode.freq_hz:.1f}Hz".replace(".", "p"),
                    VtuMesh(scan.positions, cells, point_data=data)))
    return out


def shape_rows(result: ExportIdentification) -> list[dict]:
    """shapes.csv's rows: one per mode and channel (module notes)."""
    scan = result.scan
    rows = []
    for mode in result.modes:
        for channel, value in enumerate(np.asarray(mode.shape, complex)):
            point = int(scan.channel_point[channel])
            direction = scan.channel_direction[channel]
            x, y, z = scan.positions[point]
            rows.append({"test_mode": mode.test_mode, "freq_hz": mode.freq_hz,
                         "node": int(scan.nodes[point]), "x_m": x, "y_m": y, "z_m": z,
                         "direction_x": direction[0], "direction_y": direction[1],
                         "direction_z": direction[2], "shape_real": value.real,
                         "shape_imag": value.imag, "shape_abs": abs(value),
                         "shape_phase_deg": math.degrees(math.atan2(value.imag, value.real))})
    return rows


def _write_csv(path: Path, columns, rows) -> None:
    """``rows`` (dicts) under ``columns``: floats to 8 significant digits, NaN empty."""
    import csv

    def text(value):
        if isinstance(value, float):
            return f"{value:.8g}" if math.isfinite(value) else ""
        return value

    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        writer.writerows([text(row[key]) for key in columns] for row in rows)


def write_export_identification(folder, result: ExportIdentification, title: str) -> None:
    """modes.csv, shapes.csv, stabilisation.png and (with a geometry) shapes/ in
    ``folder`` (a staging folder: the caller's ``write`` owns it); module notes."""
    from copdea_fem.vibrometer.identification_files import plot_stabilisation
    from copdea_fem.vtu import write_all, write_pvd

    folder = Path(folder)
    _write_csv(folder / "modes.csv", MODES_COLUMNS,
               [{"test_mode": m.test_mode, "freq_hz": m.freq_hz,
                 "damping_ratio": m.damping_ratio, "mpc": m.mpc} for m in result.modes])
    _write_csv(folder / "shapes.csv", SHAPE_COLUMNS, shape_rows(result))
    plot_stabilisation(folder / "stabilisation.png", result.identification.diagram,
                       f"{title}: {len(result.modes)} modes")
    if not result.has_geometry:
        logger.info("%s: no geometry (dataset 2411/15): shapes by node in shapes.csv, no "
                    "VTU", title)
        return
    if not result.modes:
        return
    shapes = folder / "shapes"
    shapes.mkdir()
    meshes = export_meshes(result)
    if meshes[0][1].cells[0].type == "vertex":
        logger.info("%s: no trace lines (dataset 82) between measured nodes: the shapes "
                    "written as points (VTK vertices)", title)
    files = write_all(shapes, meshes)
    write_pvd(shapes / "shapes.pvd", files, [m.test_mode for m in result.modes])


__all__ = ["MODES_COLUMNS", "SHAPE_COLUMNS", "ExportIdentification", "export_meshes",
           "shape_rows", "trace_segments", "write_export_identification"]
