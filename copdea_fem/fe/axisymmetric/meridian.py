r"""Meridian (r, z) geometry of an axisymmetric device and its Netgen mesh.

Every field of an axisymmetric device separates as ``cos(m theta)`` /
``sin(m theta)`` (:mod:`copdea_fem.fe.axisymmetric`), so the 3-D air sphere of
:mod:`copdea_fem.fe.quadrant.geometry` becomes its meridian half-disc ``r >= 0``,
``r^2 + z^2 < (R + t)^2`` and the membrane plane the line ``z = 0``.  The
names are those of the 3-D mesh, so the forms of :mod:`copdea_fem.fe.acoustics`
find the same regions:

domains   ``air_upper``, ``air_lower`` (``rho < R``), ``pml_upper``, ``pml_lower``
          (``R < rho < R + t``), split at ``z = 0``
lines     ``disc`` (0 < r < r_i), ``membrane`` (r_i < r < r_o), ``frame``
          (r_o < r < frame radius; ``baffle``: up to R), ``aperture`` (the
          open rest of z = 0 inside the air), ``pml_plane`` (z = 0 in the PML),
          ``axis`` (r = 0), ``interface`` (rho = R), ``outer`` (rho = R + t),
          ``ale_guide`` (r = r_i, r_o and z = +-L: the mesh conforms to the
          kinks of the air-mesh motion, :mod:`copdea_fem.fe.ale`)
points    ``inner_rim`` (r_i, 0), ``outer_rim`` (r_o, 0), ``centre`` (0, 0)

The ``frame`` is the square frame's rotationally symmetric counterpart: a
rigid ring plane from r_o to ``geometry.frame_radius`` (``frame: circle``), the
whole plane (``baffle``) or nothing (``none``).  Netgen meshes the half-disc
quickly, so meridian meshes are not cached.
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass

import numpy as np

from copdea_fem.fe.airbox import ale_decay_length

#: frames with a meridian geometry (the square frame needs the 3-D engine)
AXISYMMETRIC_FRAMES = ("none", "baffle", "circle")
#: enclosures with a meridian geometry (a box needs the 3-D engine)
ENCLOSURES = ("none", "cylinder", "bowl")

#: Largest meridian air element as a share of ``mesh.air_size`` (a bound, so the key
#: still holds).  Flat G1 in a baffle, default keys, against a converged meridian run
#: (1.5 mm membrane, air 8.9 mm, pressure order 3; 340.109 Hz, zeta 1.942e-2): with the
#: full air_size (0,1) is +0.15 % and its zeta -3.7 %, (1,1)'s zeta (1.4e-4) +99 %;
#: with half of it +0.009 %, +0.07 % and -2 %, for little more time per order.
MERIDIAN_AIR_REFINEMENT = 0.5


logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class MeridianSpec:
    """All that determines the meridian mesh [m]."""

    outer_radius: float
    inner_radius: float
    frame: str
    frame_radius: float
    domain_radius: float
    pml_thickness: float
    membrane_size: float
    air_size: float
    grading: float
    enclosure: str = "none"
    enclosure_depth: float = 0.0
    enclosure_radius: float = 0.0
    vent_radius: float = 0.0
    outside: bool = True

    @classmethod
    def from_study(cls, study) -> "MeridianSpec":
        g, a, m = study.geometry, study.air, study.mesh
        if g.frame not in AXISYMMETRIC_FRAMES:
            raise ValueError(f"geometry.frame = {g.frame!r} has no meridian geometry; "
                             f"allowed: {', '.join(AXISYMMETRIC_FRAMES)}")
        if g.enclosure not in ENCLOSURES:
            raise ValueError(f"geometry.enclosure = {g.enclosure!r} has no meridian "
                             f"geometry; allowed: {', '.join(ENCLOSURES)}")
        enclosed = g.enclosure != "none" and a.enabled
        # radii equal within round-off ("35.5 mm" = 0.035500000000000004 m) are one radius
        radius = snapped(g.enclosure_radius, (g.outer_radius, g.frame_radius))
        vent = snapped(g.enclosure_vent_radius, (g.inner_radius, g.outer_radius))
        return cls(outer_radius=g.outer_radius, inner_radius=g.inner_radius,
                   frame=g.frame, frame_radius=g.frame_radius,
                   domain_radius=a.domain_radius, pml_thickness=a.pml_thickness,
                   membrane_size=m.membrane_size, air_size=m.air_size,
                   grading=m.grading,
                   enclosure=g.enclosure if enclosed else "none",
                   enclosure_depth=g.enclosure_depth if enclosed else 0.0,
                   enclosure_radius=radius if enclosed else 0.0,
                   vent_radius=vent if enclosed else 0.0,
                   outside=a.outside or not enclosed)

    @property
    def cavity(self) -> Cavity | None:
        """The enclosure's inside (None: open back)."""
        if self.enclosure == "none":
            return None
        return Cavity(self.enclosure, self.enclosure_radius, self.enclosure_depth,
                      self.vent_radius)


def snapped(value: float, radii) -> float:
    """``value``, or the radius of ``radii`` it equals within round-off
    (:func:`copdea_fem.study.apart`): the meridian's lines then meet at one point."""
    from copdea_fem.study import apart
    return next((radius for radius in radii if not apart(value, radius)), value)


@dataclass(frozen=True)
class Cavity:
    """The inside of a rigid enclosure under the membrane plane [m] (docs/enclosures.md).

    ``shape``: ``cylinder`` (radius a, flat bottom at z = -depth) or ``bowl`` (a spherical
    cap of rim radius a at z = 0 and depth ``depth`` at r = 0: sphere radius
    ``(a^2 + depth^2) / (2 depth)``, centre on the axis at ``z = radius - depth``).
    ``vent_radius``: the open part of the bottom, r < vent_radius.
    """

    shape: str
    radius: float
    depth: float
    vent_radius: float = 0.0

    @property
    def sphere_radius(self) -> float:
        """Radius of the bowl's sphere [m]."""
        return (self.radius**2 + self.depth**2) / (2 * self.depth)

    def bottom(self, r, sqrt=np.sqrt):
        """Height of the bottom wall below radius ``r`` (<= radius) [m]; ``sqrt``:
        ``ngsolve.sqrt`` for a CoefficientFunction ``r``.  The radicand is taken as at
        least 0 (:func:`copdea_fem.fe.airbox.cavity_depth`: a hemisphere's rim)."""
        if self.shape == "cylinder":
            return -self.depth + 0 * r
        sphere = self.sphere_radius
        radicand = sphere**2 - r * r
        if sqrt is np.sqrt:
            radicand = np.maximum(radicand, 0.0)
        else:
            from ngsolve import IfPos
            radicand = IfPos(radicand, radicand, 0.0)
        return sphere - self.depth - sqrt(radicand)

    def volume(self) -> float:
        """Volume [m^3] (the spherical cap: pi d^2 (3 R_s - d) / 3)."""
        if self.shape == "cylinder":
            return math.pi * self.radius**2 * self.depth
        return math.pi * self.depth**2 * (3 * self.sphere_radius - self.depth) / 3


def build_geometry(spec: MeridianSpec):
    """netgen.geom2d.SplineGeometry of the meridian with every region named."""
    from netgen.geom2d import SplineGeometry

    if spec.cavity is not None:
        return build_enclosed_geometry(spec)

    r_o, r_i = spec.outer_radius, spec.inner_radius
    R, t = spec.domain_radius, spec.pml_thickness
    L = ale_decay_length(R, r_o)
    h_membrane, h_screen = spec.membrane_size, 2 * spec.membrane_size
    geo = SplineGeometry()
    points: dict = {}

    def point(r, z, name="", maxh=1e99):
        key = (round(r, 12), round(z, 12))
        if key not in points:
            points[key] = geo.AppendPoint(r, z, maxh=maxh, name=name)
        return points[key]

    def line(a, b, bc, left, right, maxh=1e99):
        geo.Append(["line", point(*a), point(*b)], bc=bc, leftdomain=left, rightdomain=right,
                   maxh=maxh)

    def arc(a, control, b, bc, left, right):
        geo.Append(["spline3", point(*a), point(*control), point(*b)], bc=bc, leftdomain=left,
                   rightdomain=right)

    # domains: 1 box under the disc, 2 box under the membrane, 3 rest of the air, 4 PML
    # (upper half); 5, 6, 7, 8 the same below
    has_disc = r_i > 0
    under_disc_u, under_disc_l = (1, 5) if has_disc else (2, 6)
    point(0, 0, "centre", h_screen)
    if has_disc:
        point(r_i, 0, "inner_rim", h_membrane)
    point(r_o, 0, "outer_rim", h_membrane)

    # plane z = 0, in +r: upper domain on the left
    if has_disc:
        line((0, 0), (r_i, 0), "disc", 1, 5, h_screen)
    line((r_i, 0), (r_o, 0), "membrane", 2, 6, h_membrane)
    frame_end = {"none": r_o, "baffle": R, "circle": spec.frame_radius}[spec.frame]
    if frame_end > r_o:
        line((r_o, 0), (frame_end, 0), "frame", 3, 7, h_screen)
    if frame_end < R:
        line((frame_end, 0), (R, 0), "aperture", 3, 7)
    line((R, 0), (R + t, 0), "pml_plane", 4, 8)
    # spheres (quarter arcs, exact conics)
    arc((R, 0), (R, R), (0, R), "interface", 3, 4)
    arc((R + t, 0), (R + t, R + t), (0, R + t), "outer", 4, 0)
    arc((0, -R), (R, -R), (R, 0), "interface", 7, 8)
    arc((0, -R - t), (R + t, -R - t), (R + t, 0), "outer", 8, 0)
    # axis r = 0 (domain on the +r side = left when going down)
    line((0, R + t), (0, R), "axis", 4, 0)
    line((0, R), (0, L), "axis", 3, 0)
    line((0, L), (0, 0), "axis", under_disc_u, 0)
    line((0, 0), (0, -L), "axis", under_disc_l, 0)
    line((0, -L), (0, -R), "axis", 7, 0)
    line((0, -R), (0, -R - t), "axis", 8, 0)
    # ALE guides: the boxes r < r_i and r_i < r < r_o, |z| < L
    if has_disc:
        line((r_i, 0), (r_i, L), "ale_guide", 1, 2)
        line((r_i, 0), (r_i, -L), "ale_guide", 6, 5)
        line((r_i, L), (0, L), "ale_guide", 1, 3)
        line((r_i, -L), (0, -L), "ale_guide", 7, 5)
    line((r_o, 0), (r_o, L), "ale_guide", 2, 3)
    line((r_o, L), (r_i, L), "ale_guide", 2, 3)
    line((r_o, 0), (r_o, -L), "ale_guide", 7, 6)
    line((r_o, -L), (r_i, -L), "ale_guide", 7, 6)
    for number, name in ((1, "air_upper"), (2, "air_upper"), (3, "air_upper"),
                         (4, "pml_upper"), (5, "air_lower"), (6, "air_lower"),
                         (7, "air_lower"), (8, "pml_lower")):
        if has_disc or number not in (1, 5):
            geo.SetMaterial(number, name)
    return geo


class _Builder:
    """Points and segments of a SplineGeometry, points shared by their coordinates."""

    def __init__(self):
        from netgen.geom2d import SplineGeometry
        self.geo = SplineGeometry()
        self.points: dict = {}

    def point(self, r, z, name="", maxh=1e99):
        key = (round(r, 12), round(z, 12))
        if key not in self.points:
            self.points[key] = self.geo.AppendPoint(r, z, maxh=maxh, name=name)
        return self.points[key]

    def line(self, a, b, bc, left, right, maxh=1e99):
        self.geo.Append(["line", self.point(*a), self.point(*b)], bc=bc, leftdomain=left,
                        rightdomain=right, maxh=maxh)

    def arc(self, a, control, b, bc, left, right, maxh=1e99):
        self.geo.Append(["spline3", self.point(*a), self.point(*control), self.point(*b)],
                        bc=bc, leftdomain=left, rightdomain=right, maxh=maxh)


#: Domain numbers of the enclosed meridian: upper air boxes (under the disc, under the
#: membrane, the rest), upper PML, the cavity's columns (under the disc, under the
#: membrane, beyond r_o), the outside lower air and its PML.
_UNDER_DISC, _UNDER_MEMBRANE, _UPPER_REST, _UPPER_PML = 1, 2, 3, 4
_CAVITY_DISC, _CAVITY_MEMBRANE, _CAVITY_RIM = 5, 6, 9
_LOWER_AIR, _LOWER_PML = 7, 8


def build_enclosed_geometry(spec: MeridianSpec):
    r"""The meridian with an enclosure (``spec.cavity``) under the membrane plane.

    Regions as :func:`build_geometry`'s, and: domain ``cavity`` (the enclosure's inside,
    split into columns r < r_i, r_i < r < r_o, r_o < r < a at the ``ale_guide`` lines
    r = r_i, r_o, which reach down to the bottom), lines ``enclosure`` (the rigid walls
    that are not the frame: the top r_o < r < a with frame none, the side r = a, the
    bottom outside the vent) and ``vent`` (the bottom r < vent radius, open).  With
    ``frame: baffle`` the cavity replaces the lower half-space (no ``air_lower``,
    ``pml_lower``); with ``air.outside: false`` there is only the cavity (no upper air,
    no PML).  The walls have no thickness: the pressure jumps across them
    (:func:`copdea_fem.fe.acoustics.pressure_space`).
    """
    cavity = spec.cavity
    r_o, r_i, a = spec.outer_radius, spec.inner_radius, cavity.radius
    R, t = spec.domain_radius, spec.pml_thickness
    L = ale_decay_length(R, r_o)
    h_membrane, h_screen = spec.membrane_size, 2 * spec.membrane_size
    b = _Builder()
    has_disc = r_i > 0
    outside, lower_outside = spec.outside, spec.outside and spec.frame != "baffle"
    up = (lambda number: number) if outside else (lambda number: 0)
    below = _LOWER_AIR if lower_outside else 0
    b.point(0, 0, "centre", h_screen)
    if has_disc:
        b.point(r_i, 0, "inner_rim", h_membrane)
    b.point(r_o, 0, "outer_rim", h_membrane)

    def column(r):
        """The cavity column at radius r."""
        return _CAVITY_DISC if r < r_i else (_CAVITY_MEMBRANE if r < r_o else _CAVITY_RIM)

    # plane z = 0, in +r: upper domain on the left, below the cavity (then outside air)
    if has_disc:
        b.line((0, 0), (r_i, 0), "disc", up(_UNDER_DISC), _CAVITY_DISC, h_screen)
    b.line((r_i, 0), (r_o, 0), "membrane", up(_UNDER_MEMBRANE), _CAVITY_MEMBRANE, h_membrane)
    top = "frame" if spec.frame in ("baffle", "circle") else "enclosure"
    if a > r_o:
        b.line((r_o, 0), (a, 0), top, up(_UPPER_REST), _CAVITY_RIM, h_screen)
    if outside:
        if spec.frame == "baffle":
            b.line((a, 0), (R, 0), "frame", _UPPER_REST, 0, h_screen)
            b.line((R, 0), (R + t, 0), "pml_plane", _UPPER_PML, 0)
        else:
            frame_end = spec.frame_radius if spec.frame == "circle" else a
            if frame_end > a:
                b.line((a, 0), (frame_end, 0), "frame", _UPPER_REST, _LOWER_AIR, h_screen)
            b.line((frame_end, 0), (R, 0), "aperture", _UPPER_REST, _LOWER_AIR)
            b.line((R, 0), (R + t, 0), "pml_plane", _UPPER_PML, _LOWER_PML)
        b.arc((R, 0), (R, R), (0, R), "interface", _UPPER_REST, _UPPER_PML)
        b.arc((R + t, 0), (R + t, R + t), (0, R + t), "outer", _UPPER_PML, 0)
        b.line((0, R + t), (0, R), "axis", _UPPER_PML, 0)
        b.line((0, R), (0, L), "axis", _UPPER_REST, 0)
        b.line((0, L), (0, 0), "axis", _UNDER_DISC if has_disc else _UNDER_MEMBRANE, 0)
        if has_disc:
            b.line((r_i, 0), (r_i, L), "ale_guide", _UNDER_DISC, _UNDER_MEMBRANE)
            b.line((r_i, L), (0, L), "ale_guide", _UNDER_DISC, _UPPER_REST)
        b.line((r_o, 0), (r_o, L), "ale_guide", _UNDER_MEMBRANE, _UPPER_REST)
        b.line((r_o, L), (r_i, L), "ale_guide", _UNDER_MEMBRANE, _UPPER_REST)
    if lower_outside:
        b.arc((0, -R), (R, -R), (R, 0), "interface", _LOWER_AIR, _LOWER_PML)
        b.arc((0, -R - t), (R + t, -R - t), (R + t, 0), "outer", _LOWER_PML, 0)
        b.line((0, -R), (0, -R - t), "axis", _LOWER_PML, 0)
        b.line((0, cavity.bottom(0.0)), (0, -R), "axis", _LOWER_AIR, 0)
    # the cavity: axis, guides and walls (walls walked with the cavity on the right)
    b.line((0, 0), (0, cavity.bottom(0.0)), "axis", column(0.0), 0)
    for guide in ((r_i,) if has_disc else ()) + ((r_o,) if r_o < a else ()):
        b.line((guide, 0), (guide, float(cavity.bottom(guide))), "ale_guide",
               column(guide), column(0.5 * guide if guide == r_i else r_i + 0.5 * (r_o - r_i)))
    if cavity.shape == "cylinder":
        b.line((a, 0), (a, -cavity.depth), "enclosure", below, _CAVITY_RIM if a > r_o
               else _CAVITY_MEMBRANE)
    breaks = sorted({0.0, a, r_o, *((r_i,) if has_disc else ()),
                     *((cavity.vent_radius,) if cavity.vent_radius > 0 else ())}, reverse=True)
    for start, end in itertools.pairwise(breaks):
        middle = 0.5 * (start + end)
        name = "vent" if middle < cavity.vent_radius else "enclosure"
        ends = (start, float(cavity.bottom(start))), (end, float(cavity.bottom(end)))
        size = min(h_screen, 0.5 * cavity.vent_radius) if name == "vent" else h_screen
        if cavity.shape == "cylinder":
            b.line(*ends, name, below, column(middle), size)
        else:
            b.arc(ends[0], _tangent_intersection(cavity, start, end), ends[1], name, below,
                  column(middle), size)
    names = {_UNDER_DISC: "air_upper", _UNDER_MEMBRANE: "air_upper", _UPPER_REST: "air_upper",
             _UPPER_PML: "pml_upper", _CAVITY_DISC: "cavity", _CAVITY_MEMBRANE: "cavity",
             _CAVITY_RIM: "cavity", _LOWER_AIR: "air_lower", _LOWER_PML: "pml_lower"}
    used = {_CAVITY_MEMBRANE} | ({_CAVITY_DISC} if has_disc else set()) | (
        {_CAVITY_RIM} if a > r_o else set())
    if outside:
        used |= {_UNDER_MEMBRANE, _UPPER_REST, _UPPER_PML} | ({_UNDER_DISC} if has_disc else set())
    if lower_outside:
        used |= {_LOWER_AIR, _LOWER_PML}
    for number in sorted(used):
        b.geo.SetMaterial(number, names[number])
    return b.geo


def _tangent_intersection(cavity: Cavity, r_1: float, r_2: float) -> tuple[float, float]:
    """Control point of the rational quadratic arc of the bowl between radii r_1, r_2: where
    the tangents at its ends meet (Netgen's ``spline3`` then follows the circle exactly)."""
    sphere = cavity.sphere_radius
    centre = sphere - cavity.depth
    angle_1, angle_2 = (math.asin(min(r / sphere, 1.0)) for r in (r_1, r_2))   # from the downward axis
    half = 0.5 * (angle_1 - angle_2)
    middle = 0.5 * (angle_1 + angle_2)
    distance = sphere / math.cos(half)
    return distance * math.sin(middle), centre - distance * math.cos(middle)


def meridian_mesh(spec: MeridianSpec, curve_order: int):
    """The NGSolve mesh of the meridian, curved to ``curve_order``."""
    import ngsolve

    logger.info("meshing the meridian (r, z) half-plane ...")
    geometry = build_geometry(spec)
    mesh = ngsolve.Mesh(geometry.GenerateMesh(maxh=MERIDIAN_AIR_REFINEMENT * spec.air_size,
                                               grading=spec.grading))
    mesh.Curve(curve_order)
    return mesh


def estimate_size(spec: MeridianSpec, order: int, pressure_order: int) -> tuple[float, float]:
    """Rough triangle count and unknowns of one order's pencil [-], before meshing.

    Membrane: (r_o - r_i)/h line elements of order p, three components.  Air:
    triangles of size h next to the screens, grading g up to H = MERIDIAN_AIR_REFINEMENT
    * air_size (about L / (0.43 g h) per side of a screen line of length L) plus the
    half-disc of radius R + t filled at size H; pressure order q: q^2/2 unknowns per
    triangle (the jump adds a few on the screens).  Within a factor ~2-3 of the real
    counts (G1 default: ~2.5k unknowns estimated ~3k); meant to catch sizes far out.
    """
    h, coarse = spec.membrane_size, MERIDIAN_AIR_REFINEMENT * spec.air_size
    screen = spec.outer_radius if spec.frame == "none" else (
        spec.frame_radius if spec.frame == "circle" else spec.domain_radius)
    radius = spec.domain_radius + spec.pml_thickness
    membrane_elements = (spec.outer_radius - spec.inner_radius) / h
    triangles = 2 * screen / (0.43 * spec.grading * h) + \
        0.5 * math.pi * radius**2 / (0.43 * coarse**2)
    unknowns = 3 * order * membrane_elements + triangles * pressure_order**2 / 2
    return triangles + membrane_elements, unknowns


def theta_integral(m: int) -> float:
    """int_0^{2 pi} cos^2(m theta) d theta: 2 pi for m = 0, pi otherwise [-]."""
    return 2 * math.pi if m == 0 else math.pi


class LineSampler:
    """Exact evaluation of fields on a straight line of the meridian (the membrane, z = 0).

    Netgen's point search on boundary segments of a 2-D mesh is not reliable,
    so fields are evaluated at ``points_per_element`` equispaced reference
    points of every segment of the line (:meth:`ngsolve.Mesh.MapToAllElements`)
    and, at any other radius, by Lagrange interpolation through them: exact for
    a polynomial field of degree < ``points_per_element`` on a straight segment.
    """

    def __init__(self, mesh, region: str = "membrane", points_per_element: int = 9):
        import ngsolve as ngs

        k = points_per_element
        self.reference = np.linspace(0.0, 1.0, k)
        rule = ngs.IntegrationRule([(float(t),) for t in self.reference], [0.0] * k)
        self.points = mesh.MapToAllElements(rule, ngs.BND)
        names = mesh.GetBoundaries()
        on_line = np.array([names[el.index] == region for el in mesh.Elements(ngs.BND)])
        self.rows = (np.flatnonzero(on_line)[:, None] * k + np.arange(k)[None, :])
        coordinates = np.asarray(ngs.x(self.points)).ravel()[self.rows]     # (elements, k)
        order = np.argsort(coordinates.min(axis=1))
        self.rows, coordinates = self.rows[order], coordinates[order]
        self.start, self.end = coordinates[:, 0], coordinates[:, -1]
        self.lower = np.minimum(self.start, self.end)
        self.radii = coordinates          # (elements, k) [m], elements in increasing r
        # the line's own points only (the mesh's other boundaries hold ~30x more)
        self.points = self.points[self.rows.ravel()]
        # (radii bytes, (element, weights)) of the last radii :meth:`interpolation` asked
        self.held_interpolation = None

    def values(self, coefficient) -> np.ndarray:
        """Values at the sample points: (elements, k) or (elements, k, d)."""
        values = np.asarray(coefficient(self.points))
        values = values[:, 0] if values.ndim == 2 and values.shape[1] == 1 else values
        return values.reshape(*self.rows.shape, *values.shape[1:])

    def at(self, coefficient, radii) -> np.ndarray:
        """Values at arbitrary ``radii`` [m] on the line: (len,) or (len, d)."""
        element, basis = self.interpolation(radii)
        chosen = self.values(coefficient)[element]      # (len, k[, d])
        return np.einsum("nk,nk...->n...", basis, chosen)

    def interpolation(self, radii) -> tuple[np.ndarray, np.ndarray]:
        """``(element (len,), Lagrange weights (len, k))`` of ``radii`` [m] on the line
        (:meth:`at`); kept for the last radii asked (a sampler asks the same points for
        every field)."""
        radii = np.atleast_1d(np.asarray(radii, dtype=float))
        key = radii.tobytes()
        held = self.held_interpolation
        if held is not None and held[0] == key:
            return held[1]
        element = np.clip(np.searchsorted(self.lower, radii, side="right") - 1, 0,
                          len(self.lower) - 1)
        local = (radii - self.start[element]) / (self.end[element] - self.start[element])
        nodes = self.reference
        basis = np.ones((radii.size, nodes.size))
        for j in range(nodes.size):
            for i in range(nodes.size):
                if i != j:
                    basis[:, j] *= (local - nodes[i]) / (nodes[j] - nodes[i])
        self.held_interpolation = (key, (element, basis))
        return element, basis
