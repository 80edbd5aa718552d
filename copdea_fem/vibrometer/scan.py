"""The data of one scan, as every part of :mod:`copdea_fem.vibrometer` sees it.

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
        ``"frf"`` or ``"spectrum"``.
    """

    path: Path
    nodes: np.ndarray
    positions: np.ndarray
    channel_point: np.ndarray
    channel_direction: np.ndarray
    frequencies: np.ndarray
    values: np.ndarray
    quantity: str = "frf"

    @property
    def n_points(self) -> int:
        return len(self.nodes)

    @property
    def n_channels(self) -> int:
        return len(self.channel_point)


@dataclass(frozen=True)
class IdentifiedMode:
    """One mode identified from a scan (LSCF pole, LSFD residues).

    Attributes
    ----------
    test_mode : int
        1-based number in order of frequency within its condition.
    freq_hz : float
        Damped natural frequency [Hz] (``|Im s| / 2 pi`` of the pole).
    damping_ratio : float
        ``-Re s / |s|`` [-].
    shape : (C,) complex array
        Residue per channel of the scan (the channel order of :class:`ScanData`).
    mpc : float
        Modal phase collinearity of ``shape`` in [0, 1].
    """

    test_mode: int
    freq_hz: float
    damping_ratio: float
    shape: np.ndarray
    mpc: float


@dataclass(frozen=True)
class IdentifiedSet:
    """The modes identified in one condition's scan."""

    condition: str
    scan: ScanData
    modes: tuple[IdentifiedMode, ...] = field(default_factory=tuple)
