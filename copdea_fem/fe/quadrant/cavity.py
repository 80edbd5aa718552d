"""The 3-D engine's cavity modes: the pressure inside an enclosure sampled on the quadrant,
unfolded by the mode's mirror class, and counted into ``cavity(m,n,p)`` labels
(:mod:`copdea_fem.fe.cavity`, shared with the axisymmetric engine).

An air mode (:data:`copdea_fem.fe.modes.AIR`) is a cavity mode when more than
:data:`copdea_fem.fe.cavity.CAVITY_SHARE` of its air's potential energy
``int |p|^2 dV / (rho_a c_a^2)`` lies inside the enclosure.  Its pressure is sampled on
three lines through its largest sample, where no nodal surface passes:

* cylinder and bowl: the circle about the axis (``m`` = the dominant Fourier order,
  :func:`copdea_fem.fe.cavity.circumferential_order`), the radius (``n`` nodal circles)
  and the depth (``p`` nodal surfaces), each counted by
  :func:`copdea_fem.fe.cavity.sign_changes`; in a rigid cylinder
  ``J_m(j'_mn r / a) cos(p pi z / L) cos(m theta)`` gives exactly (m, n, p);
* box: the rigid box's modes ``cos(i pi x / L_x) cos(j pi y / L_y) cos(k pi z / L_z)``
  (origin at a corner): the label is ``cavity(i,j,k)`` of the one the pressure on a grid of
  the quadrant overlaps most (normalised), i, j, k up to :data:`BOX_ORDERS`.  The box is
  square, so (i, j, k) and (j, i, k) are one frequency, and where they share a mirror class
  (i, j of one parity) the mesh, symmetric under x <-> y, gives their sum and difference:
  both overlap the two equally, and the second of them in the sector is named (j, i, k)
  (:func:`copdea_fem.fe.quadrant.labels.label_cavity_orders`).

The quadrant holds x, y >= 0; the other quadrants follow from the mode's parities about
x = 0 and y = 0 (:mod:`copdea_fem.fe.symmetry`), so the lines run across the whole
enclosure.  Samples lie at cell centres of the lines, strictly inside the cavity.
"""

from __future__ import annotations

import math

import numpy as np

from copdea_fem.fe.airbox import bowl_sphere_radius
from copdea_fem.fe.cavity import (
    CAVITY_SHARE,
    circumferential_order,
    real_pattern,
    sign_changes,
)
from copdea_fem.fe.quadrant.geometry import GeometrySpec

#: Samples per line (and per side of the search grid).
SAMPLES = 48

#: Highest order along each side of a box tried (:meth:`QuadrantCavitySampler.orders`).
BOX_ORDERS = 8


class QuadrantCavitySampler:
    """The cavity pressure of a mode vector of the pressure space, its energy share and its
    (m, n, p) (module doc).

    Parameters
    ----------
    pressure_space : ngsolve.FESpace
        The ``(p, q[, q_o])`` space of :func:`copdea_fem.fe.acoustics.pressure_space` on a
        quadrant mesh with an enclosure; the cavity's pressure is ``p + q``.
    spec : GeometrySpec
        The mesh's geometry (the enclosure's shape and size).
    """

    def __init__(self, pressure_space, spec: GeometrySpec):
        import ngsolve as ngs

        from copdea_fem.fe.acoustics import CAVITY, region_pressures

        self.mesh = pressure_space.mesh
        self.spec = spec
        self.function = ngs.GridFunction(pressure_space)
        parts = region_pressures(tuple(self.function.components))
        self.inside = next(value for air, _, value in parts if air == CAVITY)
        outside = [(air, value) for air, _, value in parts if air != CAVITY]
        self.inside_energy = ngs.Norm(self.inside) ** 2 * ngs.dx(CAVITY)
        self.outside_energy = [ngs.Norm(value) ** 2 * ngs.dx(air) for air, value in outside]

    def _set(self, free_dofs, vector) -> None:
        values = self.function.vec.FV().NumPy()
        values[:] = 0
        values[free_dofs] = vector

    def _evaluate(self, points: np.ndarray) -> np.ndarray:
        """Cavity pressure [Pa] at quadrant points (n, 3) inside the cavity."""
        mapped = self.mesh(points[:, 0], points[:, 1], points[:, 2])
        return np.asarray(self.inside(mapped)).ravel()

    def _unfolded(self, points: np.ndarray, sector) -> np.ndarray:
        """Pressure at points anywhere in the enclosure (n, 3), read in the quadrant and
        multiplied by the mode's parities (``sector`` None: a whole mesh)."""
        values = self._evaluate(np.column_stack([np.abs(points[:, 0]), np.abs(points[:, 1]),
                                                 points[:, 2]]))
        if sector is not None:
            values = values * np.where(points[:, 0] < 0, sector.parity_x, 1) \
                * np.where(points[:, 1] < 0, sector.parity_y, 1)
        return values

    def share(self, free_dofs, vector) -> float:
        """The cavity's share of the air's potential energy (no PML) of a mode."""
        import ngsolve as ngs

        self._set(free_dofs, vector)
        inside = abs(ngs.Integrate(self.inside_energy, self.mesh))
        outside = sum(abs(ngs.Integrate(form, self.mesh)) for form in self.outside_energy)
        return inside / (inside + outside) if inside + outside > 0 else 0.0

    def orders(self, sector, free_dofs, vector) -> tuple:
        """(m, n, p) of a cavity mode (cylinder, bowl) or (i, j, k) (box); () when most of
        its air's energy lies outside the enclosure (module doc)."""
        if self.share(free_dofs, vector) <= CAVITY_SHARE:
            return ()
        if self.spec.enclosure == "box":
            return self._box_orders(sector)
        return self._round_orders(sector)

    def _depth(self, radius):
        """Depth [m] of the cavity's bottom below the plane at the radius (bowl: the cap)."""
        depth = self.spec.enclosure_depth
        if self.spec.enclosure != "bowl":
            return np.full_like(np.asarray(radius, dtype=float), depth)
        sphere = bowl_sphere_radius(self.spec.enclosure_radius, depth)
        return np.sqrt(sphere**2 - np.asarray(radius) ** 2) - (sphere - depth)

    def _rim(self, height):
        """Radius [m] of the cavity at the height (< 0) below the plane."""
        radius, depth = self.spec.enclosure_radius, self.spec.enclosure_depth
        if self.spec.enclosure != "bowl":
            return radius
        sphere = bowl_sphere_radius(radius, depth)
        return math.sqrt(max(sphere**2 - (height + depth - sphere) ** 2, 0.0))

    def _round_orders(self, sector) -> tuple:
        cells = (np.arange(SAMPLES) + 0.5) / SAMPLES
        # the strongest point of a (radius, angle, depth) grid of the quadrant
        radii = self.spec.enclosure_radius * cells
        angles = 0.5 * math.pi * cells
        fractions = cells
        rr, tt, ff = np.meshgrid(radii, angles, fractions, indexing="ij")
        heights = -ff * self._depth(rr)
        points = np.column_stack([(rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel(),
                                  heights.ravel()])
        grid = real_pattern(self._evaluate(points)).reshape(rr.shape)
        i, j, k = np.unravel_index(np.argmax(np.abs(grid)), grid.shape)
        radius, angle, height = radii[i], angles[j], heights[i, j, k]
        around = 2 * math.pi * np.arange(4 * SAMPLES) / (4 * SAMPLES)
        ring = self._unfolded(np.column_stack([radius * np.cos(around),
                                               radius * np.sin(around),
                                               np.full(around.size, height)]), sector)
        along = self._rim(height) * cells
        radial = self._evaluate(np.column_stack([along * math.cos(angle), along * math.sin(angle),
                                                 np.full(SAMPLES, height)]))
        down = -self._depth(radius) * cells
        depth = self._evaluate(np.column_stack([np.full(SAMPLES, radius * math.cos(angle)),
                                                np.full(SAMPLES, radius * math.sin(angle)),
                                                down]))
        return (circumferential_order(ring), sign_changes(real_pattern(radial)),
                sign_changes(real_pattern(depth)))

    def _box_orders(self, sector) -> tuple:
        half, depth = 0.5 * self.spec.frame_side, self.spec.enclosure_depth
        cells = (np.arange(SAMPLES) + 0.5) / SAMPLES
        xx, yy, zz = np.meshgrid(half * cells, half * cells, -depth * cells, indexing="ij")
        grid = real_pattern(self._evaluate(np.column_stack([xx.ravel(), yy.ravel(),
                                                            zz.ravel()]))).reshape(xx.shape)
        # the rigid box's modes (origin at a corner), on the quadrant's samples: separable,
        # so each overlap is one contraction per axis
        orders = np.arange(BOX_ORDERS + 1)[:, None]
        across = np.cos(orders * np.pi * (half * cells + half) / (2 * half))
        down = np.cos(orders * np.pi * (depth - depth * cells) / depth)
        overlap = np.einsum("abc,ia,jb,kc->ijk", grid, across, across, down)
        norms = np.sqrt(np.einsum("ia,ia->i", across, across))
        down_norms = np.sqrt(np.einsum("ka,ka->k", down, down))
        overlap = np.abs(overlap) / (norms[:, None, None] * norms[None, :, None]
                                     * down_norms[None, None, :])
        return tuple(int(n) for n in np.unravel_index(np.argmax(overlap), overlap.shape))
