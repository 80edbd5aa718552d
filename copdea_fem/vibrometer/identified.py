"""The modes identified in a scan (:mod:`copdea_fem.vibrometer.identification`), and their
shapes as a surface over the scan points (the VTU files of ``copdea-fem identify``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from copdea_fem.measured.scan import ScanData


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
    """The modes identified in one condition's scan (``diagram``: the
    :class:`~copdea_fem.vibrometer.identification.StabilisationDiagram` they were chosen from,
    None when not kept)."""

    condition: str
    scan: ScanData
    modes: tuple[IdentifiedMode, ...] = field(default_factory=tuple)
    diagram: object = None


def point_vectors(scan: ScanData, shape: np.ndarray) -> np.ndarray:
    """(P, 3) complex vector per point of a channel-wise shape: the least-squares (minimum
    norm) solution of ``d_c . v = shape_c`` over the point's channels (one channel of a
    1-D laser gives ``shape_c d_c``)."""
    vectors = np.zeros((scan.n_points, 3), complex)
    for point in range(scan.n_points):
        channels = np.flatnonzero(scan.channel_point == point)
        directions = np.asarray(scan.channel_direction[channels], float)
        vectors[point] = np.linalg.lstsq(directions, shape[channels], rcond=None)[0]
    return vectors


def scan_surface(scan: ScanData) -> np.ndarray:
    """Triangles (T, 3) over the scan points: Delaunay in the membrane plane (x, y)."""
    from scipy.spatial import Delaunay

    if scan.n_points < 3:
        return np.zeros((0, 3), int)
    try:
        return np.asarray(Delaunay(scan.positions[:, :2]).simplices, int)
    except Exception:  # noqa: BLE001 -- qhull's error for collinear points: no surface
        return np.zeros((0, 3), int)


def shape_meshes(scan: ScanData, modes: tuple[IdentifiedMode, ...]):
    """``(name, VtuMesh)`` per mode on the scan grid: point data ``shape_real``,
    ``shape_imag`` (P, 3) [residue units], ``shape_abs`` and ``normal_real`` (z)."""
    from copdea_fem.vtu import VtuMesh

    triangles = scan_surface(scan)
    cells = [("triangle", triangles)]
    out = []
    for mode in modes:
        vectors = point_vectors(scan, mode.shape)
        data = {"shape_real": vectors.real, "shape_imag": vectors.imag,
                "shape_abs": np.linalg.norm(np.abs(vectors), axis=1),
                "normal_real": vectors[:, 2].real}
        out.append((f"mode_{mode.test_mode:02d}_{mode.freq_hz:.1f}Hz".replace(".", "p"),
                    VtuMesh(scan.positions, cells, point_data=data)))
    return out


__all__ = ["IdentifiedMode", "IdentifiedSet", "point_vectors", "scan_surface", "shape_meshes"]
