r"""Where a microphone of ``copdea-fem response`` sits, and how its pressure is found.

The Kirchhoff-Helmholtz integral (Rayleigh in a baffle) over the sphere of radius
``rho_s = KIRCHHOFF_FRACTION R`` (:mod:`copdea_fem.fe.forced.radiation`) gives the pressure
of the field radiated by what the sphere encloses at a point *outside* it: the free-field
continuation of the FE's pressure, valid in the physical air beyond the sphere, in the
PML's shell and beyond the mesh alike.  At a point inside the sphere the same integral is
no pressure at all (for a source inside, it is 0 up to the discretisation), so there the
pressure is the FE's own field (:class:`FieldPressure`):

- ``far``: ``|x| >= rho_s``, the Kirchhoff-Helmholtz integral;
- ``field``: ``|x| < rho_s`` in the air: the outside air near the device, or the air
  inside an enclosure (the cavity's pressure ``p + q``, :func:`copdea_fem.fe.acoustics.
  region_pressures`), read at the point of the undeformed mesh that the air's motion
  (ALE) carries to the microphone.

Refused (key ``response.microphones``, or ``response.microphone_distance`` for the default
microphone), before any work: a point inside the sphere that lies on a rigid or moving
surface -- an enclosure's wall (cylinder, bowl or box, within round-off), the membrane
plane z = 0 where the membrane, the disc or a frame is (r <= r_o; within the frame's extent
for a circle or square frame; everywhere with a baffle) -- or below the plane outside an enclosure without the outside
air there (``air.outside: false``: the enclosure's inside is the only air below).
"""

from __future__ import annotations

import math

import numpy as np

from copdea_fem.fe.airbox import cavity_depth
from copdea_fem.study import StudyError

#: A microphone's pressure from the Kirchhoff-Helmholtz integral (module doc).
FAR = "far"
#: A microphone's pressure from the FE's own field at its point (module doc).
FIELD = "field"

#: A point within this share of r_o of a surface lies on it [-] (round-off of the lengths
#: written with units and of the distances taken here).
ON_SURFACE = 1e-9

#: Fixed-point steps that find the undeformed point the air's motion carries to a
#: microphone (the transfinite map contracts by >= 2 per step while |w| < L/2).
MOTION_STEPS = 40


def _inside_enclosure(geometry, position) -> str:
    """``"inside"``, ``"wall"`` or ``"outside"`` of the enclosure's cavity (z <= 0)."""
    x, y, z = position
    enclosure, depth = geometry.enclosure, geometry.enclosure_depth
    tolerance = ON_SURFACE * geometry.outer_radius
    if enclosure == "none" or z > tolerance:
        return "outside"
    if enclosure == "box":
        half = 0.5 * geometry.frame_side
        distances = (half - abs(x), half - abs(y), z + depth)
    else:
        radius = math.hypot(x, y)
        rim = geometry.enclosure_radius
        if radius - rim > tolerance:
            return "outside"
        bottom = cavity_depth(enclosure, depth, rim, min(radius, rim))
        distances = (rim - radius, z + bottom)
    if any(abs(distance) <= tolerance for distance in distances):
        return "wall"
    return "inside" if all(distance > 0 for distance in distances) else "outside"


def _on_plane_surface(geometry, position) -> bool:
    """Whether a point of the plane z = 0 lies on the membrane, the disc or a frame."""
    x, y, _ = position
    radius = math.hypot(x, y)
    if radius <= geometry.outer_radius or geometry.frame == "baffle":
        return True
    if geometry.frame == "circle":
        return radius <= geometry.frame_radius
    if geometry.frame == "square":
        half = 0.5 * geometry.frame_side
        return abs(x) <= half and abs(y) <= half
    return False


def microphone_places(study, microphones) -> list[str]:
    """:data:`FAR` or :data:`FIELD` per microphone ``(name, (x, y, z) [m])``; a microphone
    where no air is refused by name (module doc).  Needs no mesh: called before any work."""
    from copdea_fem.fe.forced.radiation import KIRCHHOFF_FRACTION
    from copdea_fem.study import DEFAULT_MICROPHONE

    geometry = study.geometry
    sphere = KIRCHHOFF_FRACTION * study.air.domain_radius
    places = []
    for name, position in microphones:
        position = tuple(float(value) for value in position)
        key = ("response.microphone_distance" if name == DEFAULT_MICROPHONE
               else "response.microphones")
        shown = f"microphone {name!r} at {[float(f'{v:.6g}') for v in position]} m"
        if math.hypot(*position) >= sphere:
            places.append(FAR)
            continue
        where = _inside_enclosure(geometry, position)
        if where == "wall":
            raise StudyError(f"{key}: {shown} is not allowed (it lies on the enclosure's rigid "
                             f"wall); allowed: a point in the air, inside or outside the "
                             f"{geometry.enclosure}")
        if abs(position[2]) <= ON_SURFACE * geometry.outer_radius \
                and _on_plane_surface(geometry, position):
            raise StudyError(f"{key}: {shown} is not allowed (it lies on the plane z = 0 of "
                             "the membrane, disc or frame); allowed: a point above or below it")
        if where == "outside" and position[2] < 0 and geometry.enclosure != "none" \
                and not study.air.outside:
            raise StudyError(f"{key}: {shown} is not allowed (below the plane outside the "
                             f"{geometry.enclosure}, and air.outside = false keeps no air "
                             "there); allowed: a point inside the enclosure or above the plane")
        places.append(FIELD)
    return places


class FieldPressure:
    """The FE's pressure [Pa] of a driven part at points of the air (module doc).

    Parameters
    ----------
    coupled : copdea_fem.fe.forced.harmonic.CoupledPencil
        The part's coupled operators (either engine: its ``pressure_space``,
        ``pressure_free`` and ``mesh_motion``; a 3-D quadrant's ``membrane.sector``).
    positions : (k, 3) array
        The points [m] on the deformed (prestressed) device.
    """

    def __init__(self, coupled, positions):
        import ngsolve as ngs

        from copdea_fem.fe.acoustics import region_pressures

        self.coupled = coupled
        mesh = coupled.pressure_space.mesh
        positions = np.atleast_2d(np.asarray(positions, float))
        sector = getattr(coupled.membrane, "sector", None)
        if mesh.dim == 2:                                   # the meridian (r, z)
            reference = np.column_stack([np.hypot(positions[:, 0], positions[:, 1]),
                                         positions[:, 2]])
            self.sign = np.ones(len(positions))
        else:
            folded = sector is not None
            reference = positions.copy()
            if folded:
                reference[:, :2] = np.abs(reference[:, :2])
            parity_x = getattr(sector, "parity_x", 1) if folded else 1
            parity_y = getattr(sector, "parity_y", 1) if folded else 1
            self.sign = (np.where(positions[:, 0] < 0, parity_x, 1)
                         * np.where(positions[:, 1] < 0, parity_y, 1)).astype(float)
        self.points = [self._undeformed(mesh, coupled.mesh_motion, point) for point in reference]
        self.gf = ngs.GridFunction(coupled.pressure_space)
        parts = region_pressures(tuple(self.gf.components))
        self.field = mesh.MaterialCF({air: value for air, _, value in parts if air},
                                     default=0.0)

    @staticmethod
    def _undeformed(mesh, motion, target):
        """The mesh point X with ``X + D(X) = target`` (fixed point; module doc)."""
        point = np.array(target, float)
        for _ in range(MOTION_STEPS):
            moved = np.asarray(motion(mesh(*point))).ravel()
            point = np.asarray(target, float) - moved
        return mesh(*point)

    def sample(self, pressure_vectors) -> np.ndarray:
        """Pressure (points, columns) [Pa] of free-pressure vectors (n_p, columns)."""
        from copdea_fem.fe.forced.radiation import pressure_parts

        pressure_vectors = np.atleast_2d(np.asarray(pressure_vectors).T).T
        values = np.zeros((len(self.points), pressure_vectors.shape[1]), complex)
        for k, factor in pressure_parts(self.gf, self.coupled.pressure_free, pressure_vectors):
            values[:, k] += factor * np.array([complex(np.asarray(self.field(point)).ravel()[0])
                                               for point in self.points])
        return values * self.sign[:, None]


__all__ = ["FAR", "FIELD", "FieldPressure", "microphone_places"]
