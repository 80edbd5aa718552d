"""The data of one scan, as every reader makes it (:func:`copdea_fem.measured.read_scan`) and
every part of :mod:`copdea_fem.vibrometer` sees it.

A scan is a set of points on the device (membrane or disc), each measured along one or
more directions (channels).  Positions are in the model's frame: the membrane's outer rim
in the plane z = 0 centred on the z axis, the disc at z = +load.z, lengths in m.  A
channel's value is the velocity along its unit direction per volt of drive
(FRF, m/s/V) or a spectrum of velocity (m/s) - ``quantity`` says which.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: What a channel's response is, and the FRF form of the modal model for it
#: (``H = sum A / (i w - s)`` times 1, ``i w`` or ``-w^2``: receptance, mobility, accelerance).
RESPONSES = {"displacement": "receptance", "velocity": "mobility",
             "acceleration": "accelerance"}


@dataclass(frozen=True)
class ScanFrame:
    """Where the model's frame lies in a scan file's coordinates (``scan_frame:``).

    ``p_model = R (s p_file - s origin)`` with ``s`` the file's length unit [m] and the
    rows of ``R`` the model's unit axes x, y = z x x, z written in the file's axes.

    Attributes
    ----------
    origin : (3,) float array
        The model's origin (centre of the membrane's outer rim) in file coordinates
        [file length unit].
    x_axis, z_axis : (3,) float arrays
        The model's x axis and axis of symmetry (towards the disc) in file axes; made
        unit length, ``x_axis`` must be perpendicular to ``z_axis``.
    length_unit : float or None
        Metres per file length unit; None: from the file's dataset 164 (else metres).
    """

    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    x_axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    z_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    length_unit: float | None = None

    def rotation(self) -> np.ndarray:
        """(3, 3) rows: the model's unit axes in the file's axes."""
        z_axis = np.asarray(self.z_axis, float) / np.linalg.norm(self.z_axis)
        x_axis = np.asarray(self.x_axis, float) / np.linalg.norm(self.x_axis)
        return np.array([x_axis, np.cross(z_axis, x_axis), z_axis])


@dataclass(frozen=True)
class ScanData:
    """One condition's scan (a UFF export, read and converted to SI).

    Attributes
    ----------
    path : Path
        The file read (named in every error about it).
    nodes : (P,) int array
        The export's node numbers of the scan points (dataset 2411/15).
    positions : (P, 3) float array
        Point coordinates [m] in the model's frame.
    channel_point : (C,) int array
        Index into ``nodes``/``positions`` of each channel (response ``rsp_node``).
    channel_direction : (C, 3) float array
        Unit vector along which each channel measures (global axis from ``rsp_dir``,
        or a per-point direction of a 1-D laser given in measured.yaml).
    frequencies : (F,) float array
        The common frequency axis [Hz], strictly increasing.
    values : (C, F) complex array
        FRFs [m/s/V] (UFF function type 4) or spectra [m/s] (type 12), SI.
    quantity : str
        ``"frf"`` or ``"spectrum"``; ``"modes"``: the channels of a mode set
        (:mod:`copdea_fem.measured.mode_sets`), no lines.
    response : str
        What the ordinate is: ``"velocity"`` (a vibrometer), ``"acceleration"`` or
        ``"displacement"`` (a key of :data:`RESPONSES`).
    """

    path: Path
    nodes: np.ndarray
    positions: np.ndarray
    channel_point: np.ndarray
    channel_direction: np.ndarray
    frequencies: np.ndarray
    values: np.ndarray
    quantity: str = "frf"
    response: str = "velocity"

    @property
    def n_points(self) -> int:
        return len(self.nodes)

    @property
    def n_channels(self) -> int:
        return len(self.channel_point)


__all__ = ["RESPONSES", "ScanData", "ScanFrame"]
