r"""Mirror symmetry of the device: one quadrant meshed, four parity classes solved apart.

Membrane (circle), disc, square frame, air sphere and PML are all symmetric
about the planes x = 0 and y = 0, and the prestress is axisymmetric.  The
linearised coupled operator therefore commutes with both reflections, and
every mode is even or odd about each plane: it belongs to one *sector*
``(parity_x, parity_y)`` with parities +1 (even) or -1 (odd).  On the quadrant
x >= 0, y >= 0 (:mod:`copdea_fem.fe.quadrant.geometry`, ``symmetry = "quarter"``) a sector is the
same pencil with its own conditions on the mirror planes:

=================  ====================================  ===========================
field              even about x = 0                      odd about x = 0
=================  ====================================  ===========================
u (membrane)       u_x = 0 on ``mirror_x_edge``          u_y = u_z = 0 there
p, q (air)         natural (dp/dx = 0)                   p = q = 0 on ``mirror_x``
disc DOF w_d       kept only in the even-even sector     --
=================  ====================================  ===========================

(the same with y).  In Fourier terms, a normal displacement ``cos(m theta)``
is even about y = 0 and has x-parity (-1)^m; ``sin(m theta)`` is odd about
y = 0 and has x-parity -(-1)^m.  So (even, even) holds m = 0 and cos 2 theta,
(odd, odd) sin 2 theta, and the two mixed sectors the cos/sin members of every
odd-m pair: the square frame can split m = 2 pairs (different sectors, different
operators) but not m = 1 pairs (the two mixed sectors map onto each other by
the 90-degree rotation, a symmetry of the square).

A field of sector s is rebuilt on the quadrant (q_x, q_y) in {+1, -1}^2 as
``f(q_x x, q_y y) = s(q) R_q f(x, y)`` with ``s(q) = parity_x^[q_x<0]
parity_y^[q_y<0]`` and ``R_q`` flipping the x (y) component of a vector when
q_x (q_y) is -1.  Sums over the whole device of products of two fields of
sectors s, t are ``sum_q s(q) t(q) = 4 delta_st`` times the quadrant's: the
quadrant's energies, masses and forces are a quarter of the device's
(:attr:`Symmetry.copies`), and fields of different sectors are orthogonal.
Lumped parts (disc mass, spring) enter the quadrant's pencil divided by 4.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

#: Relative inward offset of sample points on a mirror line (:meth:`Symmetry.fold`).
MIRROR_NUDGE = 1e-5

#: Quadrants of the device as (sign of x, sign of y); the first is the meshed one.
QUADRANTS = ((1, 1), (-1, 1), (-1, -1), (1, -1))


@dataclass(frozen=True)
class Sector:
    """Parities about x = 0 and y = 0 (+1 even, -1 odd) of the modes solved together."""

    parity_x: int
    parity_y: int

    @property
    def name(self) -> str:
        """``"even-even"``, ``"odd-even"``, ... (x parity first)."""
        word = {1: "even", -1: "odd"}
        return f"{word[self.parity_x]}-{word[self.parity_y]}"

    def sign(self, quadrant_x, quadrant_y):
        """s(q) of the module doc; works elementwise on arrays of +-1."""
        sx = np.where(np.asarray(quadrant_x) < 0, self.parity_x, 1)
        sy = np.where(np.asarray(quadrant_y) < 0, self.parity_y, 1)
        return sx * sy

    def signature(self) -> np.ndarray:
        """s(q) over :data:`QUADRANTS`: fields of two sectors are orthogonal on the
        device exactly when these are (``kron(signature, v)`` extends a quadrant
        vector ``v`` to an inner-product-faithful device vector)."""
        return np.array([int(self.sign(qx, qy)) for qx, qy in QUADRANTS], dtype=float)


#: The four sectors, in the order they are solved: the even-even one (pumping,
#: axisymmetric modes) first.
SECTORS = (Sector(1, 1), Sector(-1, 1), Sector(1, -1), Sector(-1, -1))


@dataclass(frozen=True)
class Symmetry:
    """How much of the device a mesh holds: ``"none"`` (all) or ``"quarter"``."""

    kind: str = "none"

    @classmethod
    def of_mesh(cls, mesh) -> "Symmetry":
        """The symmetry a mesh of :func:`copdea_fem.fe.quadrant.geometry.load_mesh` was cut to (by
    its face names)."""
        return cls("quarter" if "mirror_x" in mesh.GetBoundaries() else "none")

    @property
    def quarter(self) -> bool:
        return self.kind == "quarter"

    @property
    def copies(self) -> int:
        """Meshed parts that make up the device (4 for a quadrant)."""
        return 4 if self.quarter else 1

    @property
    def sectors(self) -> tuple:
        """Sectors to solve; ``(None,)`` on a whole mesh (no mirror conditions)."""
        return SECTORS if self.quarter else (None,)

    def angles(self, count: int) -> np.ndarray:
        """``count`` polar angles [rad] spread over the meshed part of the plane."""
        if self.quarter:
            return 0.5 * np.pi * (np.arange(count) + 0.5) / count
        return 2 * np.pi * np.arange(count) / count

    def fold(self, x, y):
        """Points of the whole plane -> (x, y) in the meshed part, and their quadrant signs.

        Points on a mirror line move into the quadrant by 1e-5 of their radius:
        a point search exactly on x = 0 returns the element of the mirror face,
        where the membrane fields are not defined (fields change by ~1e-5 there).
        """
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        if not self.quarter:
            return x, y, np.ones_like(x), np.ones_like(y)
        inward = MIRROR_NUDGE * np.hypot(x, y)
        return (np.maximum(np.abs(x), inward), np.maximum(np.abs(y), inward),
                np.where(x < 0, -1.0, 1.0), np.where(y < 0, -1.0, 1.0))


#: Angles [deg] closer than this to a multiple of the symmetric ones count as on it (the
#: keys are read in degrees; a unit conversion may round by an ulp).
ANGLE_TOLERANCE_DEG = 1e-9


def _multiple(angle_deg: float, period_deg: float) -> bool:
    remainder = angle_deg % period_deg
    return min(remainder, period_deg - remainder) <= ANGLE_TOLERANCE_DEG


def mirror_breaking(study) -> str:
    """Why the study's imperfections break a mirror plane x = 0 or y = 0 ("" if they keep
    both, so the quadrant's sectors still hold every mode; :mod:`copdea_fem.study.
    imperfections` for the keys).

    * An anisotropic pre-stretch ``B_p`` is even about both planes exactly when its axis is
      along x or y (``alpha`` a multiple of 90 deg): reflecting y -> -y flips the sign of
      ``B_xy = cos alpha sin alpha (along - across)``.
    * A thickness term ``cos k (theta - angle)``: even about y = 0 (theta -> -theta) iff
      ``sin(k angle) = 0``, i.e. ``k angle`` a multiple of 180 deg; then about x = 0
      (theta -> 180 - theta) it becomes ``(-1)^k`` times itself: ``k`` even.
    * A point mass on the membrane at ``r > 0`` has a mirror image that holds no mass; one
      at the centre (a full membrane) or on the disc (it only adds to the disc's axial mass)
      keeps both planes.
    """
    m = study.membrane
    if m.prestretch_anisotropy and not _multiple(m.prestretch_axis, 90.0):
        return (f"membrane.prestretch_axis = {m.prestretch_axis:g} deg is not along x or y "
                "(a multiple of 90 deg)")
    for index, term in enumerate(m.thickness_variation):
        if term.order % 2 or not _multiple(term.order * term.angle, 180.0):
            return (f"membrane.thickness_variation[{index}] (order {term.order}, angle "
                    f"{term.angle:g} deg) is not even about both axes (needs an even order "
                    "and order * angle a multiple of 180 deg)")
    r_i = study.geometry.inner_radius
    for index, point in enumerate(study.imperfections.point_masses):
        if point.r > 0 and not (r_i > 0 and point.r <= r_i):
            return (f"imperfections.point_masses[{index}] sits off the centre on the "
                    "membrane")
    return ""


def bitarray(mask: np.ndarray):
    """NGSolve BitArray of a boolean array."""
    import ngsolve as ngs

    return ngs.BitArray(np.asarray(mask, dtype=bool).tolist())


def membrane_mirror_dofs(space, mesh, order: int, sector: Sector | None) -> np.ndarray:
    """Indices of the membrane DOFs a sector fixes to zero (module table).

    ``space`` is :func:`copdea_fem.fe.membrane.displacement_space` (a compressed VectorH1 on
    ``membrane``); the uncompressed space is rebuilt to find each component's
    DOFs on the mirror edges.
    """
    if sector is None:
        return np.zeros(0, dtype=int)
    scalar_dofs, on_edges, active = _membrane_layout(mesh, order)
    fixed = np.zeros(3 * scalar_dofs, dtype=bool)
    for on_edge, parity, in_plane in ((on_edges[0], sector.parity_x, 0),
                                      (on_edges[1], sector.parity_y, 1)):
        # even: the component normal to the mirror plane vanishes; odd: the others
        components = (in_plane,) if parity > 0 else tuple(c for c in range(3) if c != in_plane)
        for component in components:
            fixed[component * scalar_dofs:(component + 1) * scalar_dofs] |= on_edge
    if int(active.sum()) != space.ndof:
        raise RuntimeError("membrane space layout differs from VectorH1 on 'membrane'")
    return np.flatnonzero(fixed[active])


_LAYOUTS: dict = {}     # (id(mesh), order) -> (weak reference to the mesh, layout)


def _membrane_layout(mesh, order: int):
    """The uncompressed VectorH1 on ``membrane``: DOFs per component, each mirror edge's
    scalar DOFs, and the DOFs ``Compress`` keeps; built once per mesh and order (the
    space on a 3-D air mesh is not cheap to build, and every sector asks twice)."""
    import ngsolve as ngs

    key = (id(mesh), order)       # NGSolve meshes are not hashable
    cached = _LAYOUTS.get(key)
    if cached is not None and cached[0]() is mesh:
        return cached[1]
    whole = ngs.VectorH1(mesh, order=order, definedon=mesh.Boundaries("membrane"))
    scalar = whole.components[0]
    on_edges = tuple(np.array(scalar.GetDofs(mesh.BBoundaries(edge)))
                     for edge in ("mirror_x_edge", "mirror_y_edge"))
    active = np.array(whole.GetDofs(mesh.Boundaries("membrane")))   # what Compress keeps
    layout = (scalar.ndof, on_edges, active)
    _LAYOUTS[key] = (weakref.ref(mesh), layout)
    weakref.finalize(mesh, _LAYOUTS.pop, key, None)
    return layout


def pressure_mirror_dofs(pressure_space, mesh, sector: Sector | None) -> np.ndarray:
    """Indices (in ``pressure_space``) of the pressure DOFs an odd parity fixes: p = q = 0
    on that mirror plane (:func:`copdea_fem.fe.acoustics.pressure_space`, a product P x Q)."""
    if sector is None:
        return np.zeros(0, dtype=int)
    fixed = np.zeros(pressure_space.ndof, dtype=bool)
    for plane, parity in (("mirror_x", sector.parity_x), ("mirror_y", sector.parity_y)):
        if parity < 0:
            fixed |= np.array(pressure_space.GetDofs(mesh.Boundaries(plane)))
    return np.flatnonzero(fixed)
