"""Mode shapes identified by another program (a condition's ``modes: FILE.unv``): the
dataset 55 records of a UFF file and the points they sit on, as channels a model's shapes
can be sampled along.

A mode-shape export (PSV, ME'scope, LMS Test.Lab, ARTeMIS) holds the geometry (dataset
2411 or 15, lengths per dataset 164) and one dataset 55 per mode: its frequency, damping
ratio and a (real or complex) displacement per node along the file's x, y and z axes
(:func:`copdea_fem.measured.uff.read_mode_sets`).  The shapes become channels as a scan's
responses do (:class:`copdea_fem.measured.ScanData`): one channel per node and axis, the
points moved into the model's frame by ``scan_frame`` (``p_model = R (s p_file - s
origin)``, :class:`ScanFrame`) and each axis turned with them (``d_model = R e_axis``).  A
node-axis pair that is zero in every mode was not measured (a 1-D laser's export writes
0 for the two directions it did not see) and is left out: a zero there would count as a
measured node of every shape.  The channel order is node by node in the file's node order,
x, y, z within a node.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from copdea_fem.inputs import preview
from copdea_fem.measured import uff
from copdea_fem.measured.errors import MeasuredDataError
from copdea_fem.measured.scan import ScanData, ScanFrame

#: The suffixes of a mode-set file (the UFF reader's).
MODE_SET_SUFFIXES = (".uff", ".unv")


@dataclass(frozen=True)
class MeasuredModes:
    """A condition's mode set: the modes another program identified and where.

    Attributes
    ----------
    path : Path
        The file read.
    channels : ScanData
        The measured points and directions in the model's frame [m]; no spectral lines
        (``frequencies`` empty, ``values`` (C, 0), ``quantity`` ``"modes"``).
    freq_hz : (T,) float array
        Damped natural frequencies [Hz], increasing (dataset 55's eigenvalue
        ``|Im s| / 2 pi``, else its frequency).
    damping_ratio : (T,) float array
        ``-Re s / |s|`` [-] (else the record's viscous damping ratio).
    shapes : (C, T) complex array
        Each mode's displacement along each channel [the file's unit; only ratios count].
    file_modes : (T,) int array
        The mode number each mode has in the file (dataset 55's record 7).
    """

    path: Path
    channels: ScanData
    freq_hz: np.ndarray
    damping_ratio: np.ndarray
    shapes: np.ndarray
    file_modes: np.ndarray

    @property
    def n_modes(self) -> int:
        return len(self.freq_hz)


def _refusal(path: Path, where: str, problem: str, allowed: str) -> MeasuredDataError:
    return MeasuredDataError(f"modes file {preview(path)} dataset {where}: {problem} is not "
                             f"allowed; allowed: {allowed}")


def read_mode_set(path, *, frame: ScanFrame | None = None) -> MeasuredModes:
    """A mode-shape export as :class:`MeasuredModes` (module notes).

    Parameters
    ----------
    path : path-like
        A ``.uff``/``.unv`` file with a geometry (2411 or 15) and at least one dataset 55.
    frame : ScanFrame, optional
        Where the model's frame lies in the file's coordinates (default: they are the
        model's, lengths per dataset 164).

    Returns
    -------
    MeasuredModes

    Raises
    ------
    MeasuredDataError
        Another suffix, no dataset 55, no geometry, a mode on a node without coordinates,
        modes on different nodes, a frequency or shape that is not finite, or shapes that
        are zero everywhere: the message names the file and the dataset.
    """
    path = Path(path)
    if path.suffix.lower() not in MODE_SET_SUFFIXES:
        raise MeasuredDataError(f"modes file {preview(path)} suffix = {path.suffix!r} is not "
                                f"allowed; allowed: {', '.join(MODE_SET_SUFFIXES)}")
    records = uff.read_mode_sets(path)
    if not records:
        raise _refusal(path, "55", "no mode shape (no dataset 55)", "one dataset 55 per mode "
                       "(a mode-shape export); a file of FRFs (58) goes in scan:")
    frame = frame or ScanFrame()
    nodes, coordinates = uff.read_geometry(path)
    if frame.length_unit is not None:           # read_geometry's SI, back to the file's unit
        coordinates = coordinates * uff.read_units(path)["length"] * frame.length_unit
    point_of = {int(node): index for index, node in enumerate(nodes)}
    first = records[0]
    for record in records:
        where = f"55 #{record.dataset} (mode {record.mode})"
        if not np.array_equal(record.nodes, first.nodes):
            raise _refusal(path, where, f"{record.nodes.size} nodes unlike dataset 55 "
                           f"#{first.dataset}'s {first.nodes.size}", "every mode on the same "
                           "nodes")
        missing = [int(node) for node in record.nodes if int(node) not in point_of]
        if missing:
            raise _refusal(path, where, f"node {missing[0]} has no coordinates in the geometry "
                           "(dataset 2411/15)", "shapes of the geometry's nodes")
        if not (math.isfinite(record.frequency_hz) and record.frequency_hz > 0
                and math.isfinite(record.damping_ratio)):
            raise _refusal(path, where, f"frequency {record.frequency_hz!r} Hz, damping ratio "
                           f"{record.damping_ratio!r}", "a finite frequency > 0 and damping")
        if not np.all(np.isfinite(record.shape)):
            raise _refusal(path, where, "a shape value that is not a number", "finite shapes")
    order = sorted(range(len(records)), key=lambda k: records[k].frequency_hz)
    stacked = np.array([records[k].shape for k in order], dtype=complex)    # (T, P, 3)
    measured = np.any(np.abs(stacked) > 0, axis=0)                          # (P, 3)
    if not np.any(measured):
        raise _refusal(path, "55", "shapes that are zero at every node", "mode shapes")
    point_rows, axes = np.nonzero(measured)           # node by node, x, y, z within a node
    points = np.array([point_of[int(node)] for node in first.nodes])
    used = sorted(set(points[point_rows].tolist()))
    new_index = {point: index for index, point in enumerate(used)}
    rotation = frame.rotation()
    scale = frame.length_unit if frame.length_unit is not None else \
        1.0 / uff.read_units(path)["length"]
    origin = np.asarray(frame.origin, float) * scale
    positions = (coordinates[used] - origin) @ rotation.T
    directions = np.eye(3)[axes] @ rotation.T
    channels = ScanData(path=path, nodes=np.asarray(nodes)[used], positions=positions,
                        channel_point=np.array([new_index[p] for p in points[point_rows]],
                                               int),
                        channel_direction=directions, frequencies=np.zeros(0),
                        values=np.zeros((len(axes), 0), complex), quantity="modes",
                        response="displacement")
    return MeasuredModes(path=path, channels=channels,
                         freq_hz=np.array([records[k].frequency_hz for k in order]),
                         damping_ratio=np.array([records[k].damping_ratio for k in order]),
                         shapes=stacked[:, point_rows, axes].T,
                         file_modes=np.array([records[k].mode for k in order], int))


__all__ = ["MODE_SET_SUFFIXES", "MeasuredModes", "read_mode_set"]
