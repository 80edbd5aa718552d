"""Nodal coordinate systems of a UFF export (datasets 18 and 2420), applied to the nodes'
coordinates and to the directions of their responses.

A node record (dataset 15 or 2411) names two systems: the one its coordinates are written
in (``def_cs``) and the one its responses' directions refer to (``disp_cs``).  System 0
is the global frame.  Only Cartesian systems are read (type 0); a cylindrical or spherical
one is refused by name.

Dataset 18 (I-DEAS "Coordinate Systems", SDRC universal file description) gives each
system by three points written in the frame of its reference system ``ref_cs_num``: the
origin ``o``, a point on the +x axis ``p_x`` and a point in the xz plane ``p_xz``:

    e_x = (p_x - o) / |p_x - o|,
    e_z = w / |w|  with  w = (p_xz - o) - ((p_xz - o) . e_x) e_x,
    e_y = e_z x e_x.

Dataset 2420 ("Coordinate Systems", same description) gives each system by a 4 x 3
transformation matrix: rows 1-3 the local unit axes x, y, z written in the global frame,
row 4 the origin in the global frame.

Either way a system is ``(origin, axes)`` with ``axes`` (3, 3) whose rows are the local
unit axes in the global frame:

    p_global = origin + axes.T @ p_local,      d_global = axes.T @ d_local.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from copdea_fem.measured.errors import MeasuredDataError

#: Coordinate system types of datasets 18 and 2420 (only Cartesian is read).
SYSTEM_TYPES = {0: "Cartesian", 1: "cylindrical", 2: "spherical"}


@dataclass(frozen=True)
class CoordinateSystem:
    """One Cartesian system: ``origin`` (3,) [m, global] and ``axes`` (3, 3), rows the
    local unit axes x, y, z in the global frame (module notes)."""

    origin: np.ndarray
    axes: np.ndarray

    def point(self, local: np.ndarray) -> np.ndarray:
        """Points (n, 3) [m] given in this system, in the global frame."""
        return self.origin + np.asarray(local, float) @ self.axes

    def direction(self, local: np.ndarray) -> np.ndarray:
        """Directions (n, 3) given in this system, in the global frame."""
        return np.asarray(local, float) @ self.axes


GLOBAL = CoordinateSystem(np.zeros(3), np.eye(3))


def _unit(vector, where: str) -> np.ndarray:
    norm = float(np.linalg.norm(vector))
    if not math.isfinite(norm) or norm == 0:
        raise MeasuredDataError(f"{where}: degenerate axes (a point on an axis at the "
                                "origin); allowed: three points spanning an xz plane")
    return np.asarray(vector, float) / norm


def _checked_type(kind: int, label: int, where: str) -> None:
    if int(kind) != 0:
        name = SYSTEM_TYPES.get(int(kind), "of an unknown type")
        raise MeasuredDataError(f"{where}: coordinate system {label} is {name} (type "
                                f"{int(kind)}) is not allowed; allowed: Cartesian systems "
                                "(type 0)")


def systems_from_18(records: list[dict], where: str, length_scale: float) -> dict:
    """``{label: CoordinateSystem}`` of datasets 18 (pyuff's records; points scaled by
    ``length_scale`` [m per file unit]); a reference system must be defined before use
    or be the global frame."""
    systems: dict[int, CoordinateSystem] = {}
    for record in records:
        labels = np.atleast_1d(record.get("cs_num", []))
        kinds = np.atleast_1d(record.get("cs_type", np.zeros(labels.size)))
        references = np.atleast_1d(record.get("ref_cs_num", np.zeros(labels.size)))
        origins = np.atleast_2d(record.get("ref_o", np.zeros((labels.size, 3))))
        x_points = np.atleast_2d(record.get("x_point", np.zeros((labels.size, 3))))
        xz_points = np.atleast_2d(record.get("xz_point", np.zeros((labels.size, 3))))
        for k, label in enumerate(labels.astype(int)):
            here = f"{where} (system {label})"
            _checked_type(kinds[k], label, where)
            origin = origins[k] * length_scale
            e_x = _unit(x_points[k] * length_scale - origin, here)
            w = xz_points[k] * length_scale - origin
            e_z = _unit(w - (w @ e_x) * e_x, here)
            local = CoordinateSystem(origin, np.array([e_x, np.cross(e_z, e_x), e_z]))
            parent = int(references[k])
            if parent != 0 and parent not in systems:
                raise MeasuredDataError(f"{here}: reference system {parent} is not defined "
                                        "before it; allowed: 0 (global) or a system "
                                        "defined earlier in the file")
            outer = systems.get(parent, GLOBAL)
            systems[int(label)] = CoordinateSystem(outer.point(local.origin[None])[0],
                                                   local.axes @ outer.axes)
    return systems


def systems_from_2420(records: list[dict], where: str, length_scale: float) -> dict:
    """``{label: CoordinateSystem}`` of datasets 2420 (module notes; the origin scaled by
    ``length_scale`` [m per file unit])."""
    systems = {}
    for record in records:
        labels = record.get("CS_sys_labels", [])
        kinds = record.get("CS_types", [0] * len(labels))
        for label, kind, matrix in zip(labels, kinds, record.get("CS_matrices", [])):
            _checked_type(kind, label, where)
            matrix = np.asarray(matrix, float)
            axes = np.array([_unit(row, f"{where} (system {label})") for row in matrix[:3]])
            systems[int(label)] = CoordinateSystem(matrix[3] * length_scale, axes)
    return systems


def system_of(systems: dict, label: int, node: int, where: str) -> CoordinateSystem:
    """The system ``label`` (0: global) a node refers to, or a refusal naming both."""
    if label == 0:
        return GLOBAL
    if label not in systems:
        raise MeasuredDataError(
            f"{where}: node {node} refers to coordinate system {label}, which the file does "
            f"not define; allowed: 0 (global) or a system of dataset 18/2420 "
            f"({', '.join(str(k) for k in sorted(systems)) or 'none in this file'})")
    return systems[label]


__all__ = ["GLOBAL", "SYSTEM_TYPES", "CoordinateSystem", "system_of", "systems_from_18",
           "systems_from_2420"]
