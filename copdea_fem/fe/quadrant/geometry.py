"""Flat pre-stretched reference geometry and its Netgen mesh (Sect. 2, 5.1).

Everything lives in the plane z = 0 of the flat pre-stretched configuration:
the membrane annulus r_i < r < r_o, the rigid disc r < r_i, and the rigid
frame (a square of side ``frame_side`` around the membrane, an infinite
baffle, or nothing).  With air, the plane splits a sphere of radius R (air)
and a spherical shell R < r < R + t (PML) into upper and lower halves; the
plane faces are glued in as internal faces so that the pressure may jump
across them.

Named regions (the rest of the package refers to them only by these names):

volumes   ``air_upper``, ``air_lower``, ``pml_upper``, ``pml_lower``
faces     ``membrane``, ``disc``, ``frame`` (screens, z = 0),
          ``aperture`` (open part of the plane inside the air sphere),
          ``pml_plane`` (the plane inside the PML), ``interface`` (air|PML
          sphere), ``outer`` (outside of the PML), ``ale_guide`` (internal
          cylinders r = r_i, r_o, |z| < L: no physics, they make the mesh
          conform to the kinks of the air-mesh motion, see
          :mod:`copdea_fem.fe.ale`)
edges     ``outer_rim`` (r = r_o), ``inner_rim`` (r = r_i), ``frame_edge``

With ``symmetry = "quarter"`` (air meshes only) the shape is cut to the
quadrant x >= 0, y >= 0: circle, square frame and sphere are symmetric about
both planes, so every mode is even or odd about each (:mod:`copdea_fem.fe.symmetry`).  The
cut faces are ``mirror_x`` (x = 0) and ``mirror_y`` (y = 0); the cut edges
``mirror_x_edge`` and ``mirror_y_edge``.

Without air only the plane faces are meshed (a surface mesh in 3-D space):
the membrane field and its forms are the same in both cases.

Enclosure (``enclosure`` cylinder, bowl or box; with air): a rigid closed back on
z < 0 sealed to the membrane's rim, its inside air the volume ``cavity`` (depth
``enclosure_depth``; cylinder and bowl of rim radius ``enclosure_radius``, the bowl a
spherical cap whose depth at the centre is the depth; the box as wide as the square
frame).  The outside air is the sphere less the enclosure (it reflects off the
walls); with a baffle the enclosure replaces the lower half-space (no ``air_lower``,
``pml_lower``); without the outside air (``outside`` False) only the cavity and the
plane faces over it are meshed.  Its walls are the faces ``enclosure`` (with frame
none also the top between r_o and the rim; under a frame that top is ``frame``), a
hole of radius ``enclosure_vent_radius`` in its bottom the face ``vent`` (on the bowl
cut out by a short cylinder, the internal faces ``vent_guide``).  The walls are meshed
at twice the membrane's size, as the disc and the frame, the vent at the membrane's size
or half its radius if finer.  The ``ale_guide`` cylinders run above the plane and, inside
the cavity, down to its bottom, where the air mesh's motion stops (:mod:`copdea_fem.fe.ale`).
"""

from __future__ import annotations

import gzip
import hashlib
import json
import logging
import math
import os
import uuid
from dataclasses import asdict, dataclass
from pathlib import Path

from copdea_fem.fe.airbox import ale_decay_length, bowl_sphere_radius, cavity_depth
from copdea_fem.fe.quadrant import mirrored
from copdea_fem.fe.symmetry import mirror_breaking
from copdea_fem.fingerprint import mesh_fingerprint
from copdea_fem.inputs import preview
from copdea_fem.study import StudyError
from copdea_fem.study.imperfections import is_imperfect

SCREENS = "membrane|disc|frame"
SYMMETRIES = ("quarter", "none")
ENCLOSURES = ("none", "cylinder", "bowl", "box")

GEOMETRY_VERSION = 2  # keys the mesh cache with the code fingerprint (GeometrySpec.key)
CACHE_VARIABLE = "COPDEA_FEM_MESH_CACHE"


logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class GeometrySpec:
    """All that determines the mesh [m]; its hash keys the mesh cache."""

    outer_radius: float
    inner_radius: float
    frame: str
    frame_side: float
    with_air: bool
    domain_radius: float
    pml_thickness: float
    membrane_size: float
    air_size: float
    grading: float
    symmetry: str = "none"
    enclosure: str = "none"
    enclosure_depth: float = 0.0
    enclosure_radius: float = 0.0
    enclosure_vent_radius: float = 0.0
    outside: bool = True
    # one octant meshed and mirrored (copdea_fem.fe.quadrant.mirrored): every frame and
    # enclosure is symmetric about x = y (circle, square, sphere; the box is the square
    # frame's).  Imperfections do not change it: they are coefficients on the mesh, and a
    # perfect and an imperfect device are compared on one mesh.
    diagonal: bool = True

    @classmethod
    def from_study(cls, study, with_air: bool | None = None) -> "GeometrySpec":
        g, a, m = study.geometry, study.air, study.mesh
        air = a.enabled if with_air is None else with_air
        enclosure = g.enclosure if air else "none"
        if enclosure != "none":
            # the cavity's depth where the lift is whole (the disc's rim); beyond, the lift
            # and a bowl's depth both fall towards the rim (the Jacobians are checked)
            under_disc = cavity_depth(enclosure, g.enclosure_depth, g.enclosure_radius,
                                      g.inner_radius)
            if abs(study.load.z) >= 0.45 * under_disc:
                raise StudyError(
                    f"load.z = {preview(study.load.z)} is not allowed with geometry."
                    f"enclosure = {enclosure} on the 3-D engine; allowed: below "
                    f"{0.45 * under_disc:g} m = 0.45 times the cavity's depth under the "
                    "disc's rim (the air inside follows the membrane down to the bottom, "
                    "copdea_fem.fe.ale)")
        closed = {} if enclosure == "none" else {
            "enclosure": enclosure, "enclosure_depth": g.enclosure_depth,
            "enclosure_radius": 0.5 * g.frame_side if enclosure == "box"
            else g.enclosure_radius,
            "enclosure_vent_radius": g.enclosure_vent_radius, "outside": a.outside}
        return cls(**closed, outer_radius=g.outer_radius, inner_radius=g.inner_radius,
                   frame=g.frame, frame_side=g.frame_side,
                   with_air=a.enabled if with_air is None else with_air,
                   domain_radius=a.domain_radius, pml_thickness=a.pml_thickness,
                   membrane_size=m.membrane_size, air_size=m.air_size,
                   grading=m.grading,
                   symmetry=m.symmetry if (a.enabled if with_air is None else with_air)
                   and not mirror_breaking(study) else "none")

    def key(self) -> str:
        data = asdict(self)
        if not self.with_air:  # the air keys do not change a plane-only mesh
            for name in ("domain_radius", "pml_thickness", "air_size"):
                data.pop(name)
        if self.symmetry == "none":    # full meshes keep the keys they had before the key
            data.pop("symmetry")
        if not self.diagonal:          # the scheme of the mesh: octant mirrored or not
            data.pop("diagonal")
        if self.enclosure == "none":   # open meshes keep the keys they had before the keys
            for name in ("enclosure", "enclosure_depth", "enclosure_radius",
                         "enclosure_vent_radius", "outside"):
                data.pop(name)
        data["version"] = GEOMETRY_VERSION
        # the code that builds and meshes the shapes (copdea_fem.fingerprint): a change
        # there gives new keys, never a stale mesh
        data["code"] = mesh_fingerprint()
        text = json.dumps(data, sort_keys=True)
        return hashlib.sha1(text.encode()).hexdigest()[:12]


def _extent(shape) -> float:
    """Largest |x| or |y| of a shape's bounding box [m] (OCC pads it by ~1e-7)."""
    lo, hi = shape.bounding_box
    return max(abs(lo[0]), abs(hi[0]), abs(lo[1]), abs(hi[1]))


def build_shape(spec: GeometrySpec):
    """OCC shape with every region, face and rim edge named (see module doc).

    With ``spec.diagonal`` it is the glued images of :func:`build_octant`
    (:func:`copdea_fem.fe.quadrant.mirrored.images`): the same device, each face split on the
    cut planes; the geometry the mirrored mesh is curved on."""
    from netgen.occ import Box, Pnt

    if spec.diagonal:
        return _glued_images(spec, build_octant(spec))
    shape = _device_shape(spec)
    if spec.symmetry == "quarter":
        big = 2 * (spec.domain_radius + spec.pml_thickness + spec.enclosure_depth)
        shape = shape * Box(Pnt(0, 0, -big), Pnt(big, big, big))
    _name_faces(shape, spec)
    return shape


def build_octant(spec: GeometrySpec):
    """The part 0 <= theta <= 45 deg of the device's shape (below z = 0 too), named: what
    the mesh of a ``spec.diagonal`` spec meshes (:mod:`copdea_fem.fe.quadrant.mirrored`)."""
    from netgen.occ import Axes, WorkPlane, X, Z

    big = 2 * (spec.domain_radius + spec.pml_thickness + spec.enclosure_depth
               + spec.frame_side + spec.outer_radius)
    wedge = (WorkPlane(Axes((0, 0, -big), n=Z, h=X)).MoveTo(0, 0).LineTo(big, 0)
             .LineTo(big, big).Close().Face().Extrude(2 * big))
    shape = _device_shape(spec) * wedge
    _name_faces(shape, spec)
    return shape


def _glued_images(spec: GeometrySpec, octant):
    from netgen.occ import Glue

    shape = Glue([mirrored.mirror_shape(octant, sequence)
                  for sequence in mirrored.images(spec.symmetry == "quarter")])
    _name_faces(shape, spec)
    return shape


def _device_shape(spec: GeometrySpec):
    """The whole device's glued OCC parts, materials named, faces not yet."""
    from netgen.occ import Box, Cylinder, Glue, Pnt, Sphere, WorkPlane, Z

    if spec.enclosure not in ENCLOSURES:
        raise ValueError(f"enclosure = {spec.enclosure!r} is not allowed; allowed: "
                         f"{', '.join(ENCLOSURES)}")
    r_o, r_i = spec.outer_radius, spec.inner_radius
    disc_hole = WorkPlane().Circle(r_i).Face() if r_i > 0 else None
    outer_disc = WorkPlane().Circle(r_o).Face()
    plane = [outer_disc - disc_hole if disc_hole else outer_disc]
    if disc_hole:
        plane.append(disc_hole)
    R, t = spec.domain_radius, spec.pml_thickness
    closed = spec.with_air and spec.enclosure != "none"
    outside = spec.outside or not closed
    rim = _enclosure_top(spec) if closed else None
    if closed and spec.enclosure != "box" and spec.enclosure_radius > r_o * (1 + 1e-9):
        plane.append(rim - outer_disc)      # the top between r_o and the enclosure's rim
    if spec.frame == "square":
        square = WorkPlane().RectangleC(spec.frame_side, spec.frame_side).Face()
        if not closed or spec.enclosure == "box":
            plane.append(square - outer_disc)
        elif outside:                           # the frame around a cylinder's or bowl's rim
            plane.append(square - rim)
        inner_of_aperture = square
    elif spec.frame == "baffle":
        plane.append(WorkPlane().Circle(R).Face() - (rim if closed else outer_disc)
                     if spec.with_air and outside else None)
        inner_of_aperture = None
    else:
        inner_of_aperture = rim if closed else outer_disc
    plane = [face for face in plane if face is not None]
    parts = list(plane)
    if spec.with_air and outside:
        if inner_of_aperture is not None:
            parts.append(WorkPlane().Circle(R).Face() - inner_of_aperture)
        parts.append(WorkPlane().Circle(R + t).Face() - WorkPlane().Circle(R).Face())
        ball = Sphere(Pnt(0, 0, 0), R)
        shell = Sphere(Pnt(0, 0, 0), R + t) - ball
        big = 2 * (R + t)
        upper = Box(Pnt(-big, -big, 0), Pnt(big, big, big))
        lower = Box(Pnt(-big, -big, -big), Pnt(big, big, 0))
        lower_half = not (closed and spec.frame == "baffle")  # a baffled enclosure: none
        lower_air = ball * lower - _enclosure_solid(spec) if closed else ball * lower
        # (the order of the parts is Netgen's meshing order: kept as without an enclosure)
        solids = [(ball * upper, "air_upper"), (lower_air, "air_lower") if lower_half else None,
                  (shell * upper, "pml_upper"), (shell * lower, "pml_lower") if lower_half
                  else None]
        for solid, name in filter(None, solids):
            solid.mat(name)
            parts.insert(0, solid)
        if not closed:
            half_height = ale_decay_length(R, r_o)
            for radius in (r_i, r_o) if r_i > 0 else (r_o,):
                cylinder = Cylinder(Pnt(0, 0, -half_height), Z, radius, 2 * half_height)
                parts += [face for face in cylinder.faces if _height(face) > half_height]
    if closed:
        parts = _cavity_parts(spec) + parts + _ale_guides(
            spec, ale_decay_length(R, r_o) if outside else 0.0)
    if spec.symmetry == "quarter" and not spec.with_air:
        raise ValueError("symmetry = 'quarter' is for meshes with air; allowed: none")
    if spec.symmetry not in SYMMETRIES:
        raise ValueError(f"symmetry = {spec.symmetry!r} is not allowed; allowed: "
                         f"{', '.join(SYMMETRIES)}")
    return Glue(parts)


def _enclosure_top(spec: GeometrySpec):
    """The enclosure's opening in the plane z = 0: a disc of the rim radius, or the box's
    square (the frame's)."""
    from netgen.occ import WorkPlane

    if spec.enclosure == "box":
        return WorkPlane().RectangleC(spec.frame_side, spec.frame_side).Face()
    return WorkPlane().Circle(spec.enclosure_radius).Face()


def _ale_guides(spec: GeometrySpec, height: float) -> list:
    """The ``ale_guide`` cylinders r = r_i, r_o: above the plane up to ``height`` (0: no
    outside air), and over an enclosure down through the cavity to its bottom (where the
    mesh motion stops, so the mesh conforms to its kinks there too,
    :mod:`copdea_fem.fe.ale`); none at the enclosure's rim."""
    from netgen.occ import Cylinder, Pnt, Z

    r_o, r_i = spec.outer_radius, spec.inner_radius
    faces = []
    for radius in (r_i, r_o) if r_i > 0 else (r_o,):
        if height > 0:                                 # the outside air above
            faces += [face for face in Cylinder(Pnt(0, 0, 0), Z, radius, height).faces
                      if _height(face) > 0.5 * height]
        if spec.enclosure != "box" and radius >= spec.enclosure_radius * (1 - 1e-9):
            continue                                   # the rim is there
        depth = cavity_depth(spec.enclosure, spec.enclosure_depth, spec.enclosure_radius,
                             radius)
        faces += [face for face in Cylinder(Pnt(0, 0, -depth), Z, radius, depth).faces
                  if _height(face) > 0.5 * depth]
    return faces


def _enclosure_solid(spec: GeometrySpec):
    """The enclosure's inside (the cavity) as one OCC solid below the plane."""
    from netgen.occ import Box, Cylinder, Pnt, Sphere, Z

    depth, radius = spec.enclosure_depth, spec.enclosure_radius
    if spec.enclosure == "cylinder":
        return Cylinder(Pnt(0, 0, -depth), Z, radius, depth)
    if spec.enclosure == "box":
        half = 0.5 * spec.frame_side
        return Box(Pnt(-half, -half, -depth), Pnt(half, half, 0))
    sphere_radius = bowl_sphere_radius(radius, depth)
    big = 2 * (sphere_radius + depth)
    return (Sphere(Pnt(0, 0, sphere_radius - depth), sphere_radius)
            * Box(Pnt(-big, -big, -big), Pnt(big, big, 0)))


def _cavity_parts(spec: GeometrySpec) -> list:
    """The cavity solid(s), material ``cavity``, and the vent's outline on its bottom: a
    flat disc glued into the flat bottom (cylinder, box), or, on the bowl, the cap cut by a
    short cylinder of the vent radius (the internal faces are ``vent_guide``)."""
    from netgen.occ import Axes, Cylinder, Pnt, WorkPlane, Z

    cavity = _enclosure_solid(spec)
    vent, depth = spec.enclosure_vent_radius, spec.enclosure_depth
    parts = [cavity]
    if vent > 0 and spec.enclosure == "bowl":
        sphere_radius = bowl_sphere_radius(spec.enclosure_radius, depth)
        sagitta = sphere_radius - (sphere_radius**2 - vent**2) ** 0.5
        height = min(2 * sagitta + 0.05 * depth, 0.5 * depth)
        lens = cavity * Cylinder(Pnt(0, 0, -depth), Z, vent, height)
        parts = [cavity - lens, lens]
    elif vent > 0:
        parts.append(WorkPlane(Axes((0, 0, -depth), n=Z, h=(1, 0, 0))).Circle(vent).Face())
    for part in parts:
        if part.solids:
            part.mat("cavity")
    return parts


def _height(shape) -> float:
    lo, hi = shape.bounding_box
    return hi[2] - lo[2]


def _is_guide(face, spec: GeometrySpec, tol: float) -> bool:
    """Whether a face below the plane is an ``ale_guide`` cylinder in the cavity: vertical,
    at r_i or r_o, not the cylinder's wall."""
    lo, hi = face.bounding_box
    extent = _extent(face)
    radii = (spec.inner_radius, spec.outer_radius) if spec.inner_radius > 0 else \
        (spec.outer_radius,)
    on_radius = any(abs(extent - radius) < tol + 1e-9 for radius in radii)
    wall = spec.enclosure == "cylinder" and abs(extent - spec.enclosure_radius) < tol + 1e-9
    # a guide spans the cavity's depth at its radius; the bowl's cap at r < r_o is lower
    depth = cavity_depth(spec.enclosure, spec.enclosure_depth, spec.enclosure_radius, extent) \
        if extent < spec.enclosure_radius else 0.0
    return on_radius and not wall and abs(hi[2]) < tol and abs(lo[2] + depth) < tol \
        and hi[2] - lo[2] > tol


def _name_faces(shape, spec: GeometrySpec) -> None:
    r_o, r_i, R, t = spec.outer_radius, spec.inner_radius, spec.domain_radius, spec.pml_thickness
    tol = 1e-5 * (R + t)     # OCC pads bounding boxes by ~1e-7 m, more after a cut
    closed = spec.with_air and spec.enclosure != "none"
    depth, vent = spec.enclosure_depth, spec.enclosure_vent_radius

    def near(value, target):
        return abs(value - target) < tol + 1e-9

    def on_diagonal(item):
        """Whether a face or edge lies in the plane x = y or x = -y (its vertices and centre
        of mass do; its bounding box cannot tell)."""
        points = [vertex.p for vertex in item.vertices] + [item.center]
        return any(all(abs(p.x - sign * p.y) < tol for p in points) for sign in (1, -1))

    def mirror(item, lo, hi):
        """``"mirror_x"`` / ``"mirror_y"`` for a shape in the plane x = 0 / y = 0 of a
        quadrant, :data:`~copdea_fem.fe.quadrant.mirrored.CUT` for one on a plane the
        octant's images meet on inside the meshed part (the diagonals; on the whole plane
        also x = 0, y = 0), else None."""
        on_x = abs(lo[0]) < tol and abs(hi[0]) < tol
        on_y = abs(lo[1]) < tol and abs(hi[1]) < tol
        if spec.symmetry == "quarter" and (on_x or on_y):
            return "mirror_x" if on_x else "mirror_y"
        if spec.diagonal and (on_x or on_y or on_diagonal(item)):
            return mirrored.CUT
        return None

    for face in shape.faces:
        lo, hi = face.bounding_box
        extent = _extent(face)
        if mirror(face, lo, hi):
            face.name = mirror(face, lo, hi)
        elif abs(lo[2]) < tol and abs(hi[2]) < tol:         # in the plane z = 0
            if near(extent, r_o):
                name = "membrane"
            elif r_i > 0 and near(extent, r_i):
                name = "disc"
            elif closed and spec.enclosure != "box" and near(extent, spec.enclosure_radius):
                name = "enclosure" if spec.frame == "none" else "frame"
            elif spec.frame == "square" and near(extent, spec.frame_side / 2):
                name = "frame"
            elif near(extent, R):
                name = "frame" if spec.frame == "baffle" else "aperture"
            elif near(extent, R + t):
                name = "pml_plane"
            else:
                raise RuntimeError(f"unclassified plane face of extent {extent:g} m")
            face.name = name
            if name == "membrane":
                face.maxh = spec.membrane_size
            elif name in ("disc", "frame", "enclosure"):
                face.maxh = 2 * spec.membrane_size
        elif closed and hi[2] < tol and lo[2] > -depth - tol and _is_guide(face, spec, tol):
            face.name = "ale_guide"
        elif closed and hi[2] < tol and lo[2] > -depth - tol \
                and extent < spec.enclosure_radius + tol:
            if extent < vent + tol and near(lo[2], -depth):
                face.name = "vent"        # the air's neck: resolved (its mass is the vent's)
                face.maxh = min(spec.membrane_size, 0.5 * vent)
            elif extent < vent + tol:
                face.name = "vent_guide"
            else:
                face.name = "enclosure"
                face.maxh = 2 * spec.membrane_size
        elif _height(face) < 2 * ale_decay_length(R, r_o) + tol and extent < R - tol:
            face.name = "ale_guide"
        else:
            face.name = "interface" if near(extent, R) else "outer"
    for edge in shape.edges:
        lo, hi = edge.bounding_box
        extent = _extent(edge)
        in_plane = abs(lo[2]) < tol and abs(hi[2]) < tol
        if mirror(edge, lo, hi):
            edge.name = mirror(edge, lo, hi) + "_edge"
        elif in_plane and near(extent, r_o):
            edge.name = "outer_rim"
        elif in_plane and r_i > 0 and near(extent, r_i):
            edge.name = "inner_rim"
        elif in_plane and spec.frame == "square" and near(extent, spec.frame_side / 2):
            edge.name = "frame_edge"
        else:
            edge.name = "far_edge"


def generate_mesh(spec: GeometrySpec):
    """Netgen mesh of the spec (uncurved), and the OCC geometry it came from."""
    from netgen.occ import OCCGeometry

    maxh = spec.air_size if spec.with_air else 2 * spec.membrane_size
    what = 'air + PML' if spec.with_air else 'plane faces only'
    if spec.diagonal:
        octant = build_octant(spec)
        octant_geometry = OCCGeometry(octant, dim=3)
        logger.info(f"meshing ({what}) one octant, mirrored ...")
        octant_mesh = octant_geometry.GenerateMesh(maxh=maxh, grading=spec.grading)
        geometry = OCCGeometry(_glued_images(spec, octant), dim=3)
        sequences = mirrored.images(spec.symmetry == "quarter")
        return mirrored.mirrored_mesh(octant_mesh, octant_geometry, geometry,
                                      sequences), geometry
    geometry = OCCGeometry(build_shape(spec), dim=3)
    logger.info(f"meshing ({what}) ...")
    ngmesh = geometry.GenerateMesh(maxh=maxh, grading=spec.grading)
    return ngmesh, geometry


def mesh_cache_dir() -> Path:
    """Folder of the mesh cache.

    ``$COPDEA_FEM_MESH_CACHE`` when set (``--mesh-cache`` of the CLI sets it);
    else ``meshes/`` of the source checkout this package is imported from (an
    editable install); else the user cache folder (``platformdirs``:
    ``~/.cache/copdea-fem/meshes`` on Linux).
    """
    if os.environ.get(CACHE_VARIABLE):
        return Path(os.environ[CACHE_VARIABLE]).expanduser()
    checkout = Path(__file__).resolve().parents[3]       # copdea_fem/fe/quadrant/ -> root
    if (checkout / "pyproject.toml").is_file() and (checkout / "meshes").is_dir():
        return checkout / "meshes"
    import platformdirs
    return Path(platformdirs.user_cache_dir("copdea-fem")) / "meshes"


def load_mesh(spec: GeometrySpec, curve_order: int, cache_dir: Path | None = None):
    """The NGSolve mesh of the spec, curved to ``curve_order``, from the cache if there.

    The cache file ``<cache_dir>/<hash>.vol.gz`` (default :func:`mesh_cache_dir`)
    is keyed by :meth:`GeometrySpec.key`, so a sweep over z and V_b reuses one
    mesh.  Its sidecar ``<hash>.json`` holds the spec and the file's size and
    SHA-256, checked before Netgen reads the file (Netgen crashes on a truncated
    one); a damaged entry is reported, discarded and meshed again.  The
    geometry is rebuilt (cheap) to curve the loaded mesh.
    """
    import netgen.meshing
    import ngsolve
    from netgen.occ import OCCGeometry

    say = logger.info
    folder = Path(cache_dir) if cache_dir is not None else mesh_cache_dir()
    path = folder / f"{spec.key()}.vol.gz"
    problem = _cache_problem(path) if path.exists() else None
    if problem:
        say(f"mesh cache entry {path} is damaged ({problem}); discarded, meshing again")
        for damaged in (path, _sidecar(path)):
            damaged.unlink(missing_ok=True)
    if path.is_file():
        geometry = OCCGeometry(build_shape(spec), dim=3)
        ngmesh = netgen.meshing.Mesh(dim=3)
        ngmesh.Load(str(path))
        ngmesh.SetGeometry(geometry)
        say(f"mesh from cache {path.name}")
    else:
        ngmesh, geometry = generate_mesh(spec)
        try:
            _store(ngmesh, spec, path)
        except OSError as error:
            say(f"mesh cache {folder} cannot be written ({error.strerror or error}); "
                "continuing without it")
    mesh = ngsolve.Mesh(ngmesh)
    mesh.Curve(curve_order)
    return mesh


def _sidecar(path: Path) -> Path:
    return path.with_name(path.name.removesuffix(".vol.gz") + ".json")


def _cache_problem(path: Path) -> str | None:
    """Why a cache entry cannot be trusted, or None when its size and SHA-256 match."""
    try:
        record = json.loads(_sidecar(path).read_text())
        expected_size, expected_hash = record["file_bytes"], record["file_sha256"]
        data = path.read_bytes()
    except (OSError, ValueError, KeyError, TypeError):
        return "no valid sidecar with its size and SHA-256"
    if len(data) != expected_size:
        return f"{len(data)} bytes, the sidecar says {expected_size}"
    if hashlib.sha256(data).hexdigest() != expected_hash:
        return "SHA-256 differs from the sidecar"
    return None


def _store(ngmesh, spec: GeometrySpec, path: Path) -> None:
    """Write a cache entry atomically: temporary files, checked, then renamed into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    unique = f"{os.getpid()}-{uuid.uuid4().hex[:8]}"
    mesh_tmp = path.with_name(f".{path.name.removesuffix('.vol.gz')}.{unique}.vol.gz")
    sidecar_tmp = path.with_name(f".{_sidecar(path).name}.{unique}")
    try:
        ngmesh.Save(str(mesh_tmp))
        data = mesh_tmp.read_bytes()
        gzip.decompress(data)            # a complete gzip stream, or BadGzipFile/EOFError
        sidecar_tmp.write_text(json.dumps({**asdict(spec), "file_bytes": len(data),
                                           "file_sha256": hashlib.sha256(data).hexdigest()},
                                          indent=1))
        mesh_tmp.replace(path)
        sidecar_tmp.replace(_sidecar(path))
    except (EOFError, gzip.BadGzipFile) as error:
        raise OSError(f"Netgen wrote an incomplete file: {error}") from None
    finally:
        for leftover in (mesh_tmp, sidecar_tmp):
            leftover.unlink(missing_ok=True)


def estimate_size(spec: GeometrySpec, order: int, pressure_order: int) -> tuple[float, float]:
    """Rough element count and unknowns [-] of the mesh of ``spec``, before meshing it.

    Triangles of size h on the membrane, 2h on disc and frame (their ``maxh``);
    with air, tetrahedra graded away from those faces at Netgen's ``grading`` g
    up to ``air_size`` H (size h + g d at distance d: A (1 - h^2/H^2) / (0.236 g
    h^2) regular tetrahedra per side of a face of area A, times 3 as counted on
    the project's quadrant meshes; an enclosure's walls count as the frame, both sides),
    plus 0.3 of the air ball filled at size H.  Unknowns:
    3 p^2 / 2 per membrane triangle (order p, three components), q^3 / 6 per
    tetrahedron (pressure order q).  Within a factor ~2 of the real counts on
    the project's meshes; meant to catch sizes that are far out, not to budget.
    """
    r_o, r_i, h = spec.outer_radius, spec.inner_radius, spec.membrane_size
    fraction = 0.25 if spec.symmetry == "quarter" else 1.0
    membrane = math.pi * (r_o**2 - r_i**2) * fraction
    rest = math.pi * r_i**2
    if spec.frame == "square":
        rest += spec.frame_side**2 - math.pi * r_o**2
    elif spec.frame == "baffle" and spec.with_air:
        rest += math.pi * (spec.domain_radius**2 - r_o**2)
    rest *= fraction
    walls = enclosure_wall_area(spec) * fraction if spec.with_air else 0.0
    triangle = math.sqrt(3) / 4
    membrane_triangles = membrane / (triangle * h**2)
    elements = membrane_triangles + rest / (triangle * (2 * h)**2)
    unknowns = 1.5 * order**2 * membrane_triangles
    if spec.with_air:
        coarse = spec.air_size
        tetrahedra = 0.0
        for area, size in ((membrane, h), (rest, 2 * h), (walls, 2 * h)):
            size = min(size, coarse)
            tetrahedra += 3 * area / (0.118 * spec.grading * size**2) * (1 - (size / coarse)**2)
        radius = spec.domain_radius + spec.pml_thickness
        tetrahedra += 0.3 * 4 / 3 * math.pi * radius**3 * fraction / (0.118 * coarse**3)
        elements += tetrahedra
        unknowns += tetrahedra * pressure_order**3 / 6
    return elements, unknowns


def enclosure_wall_area(spec: GeometrySpec) -> float:
    """Area [m^2] of an enclosure's walls, both sides counted (air on each): the side and
    the bottom of a cylinder or box (a bowl as its cylinder: an upper bound), and the top
    between r_o and the rim; 0 without one."""
    if spec.enclosure == "none":
        return 0.0
    depth = spec.enclosure_depth
    if spec.enclosure == "box":
        side = spec.frame_side
        return 2 * (4 * side * depth + side**2)
    radius = spec.enclosure_radius
    top = math.pi * (radius**2 - spec.outer_radius**2)
    return 2 * (2 * math.pi * radius * depth + math.pi * radius**2) + top


def study_mesh(study, with_air=None, cache_dir=None):
    """The (cached) 3-D mesh of the study; ``cache_dir=None``: :func:`mesh_cache_dir`.
    An imperfection that breaks a mirror plane (:func:`copdea_fem.fe.symmetry.
    mirror_breaking`) meshes the whole device where ``mesh.symmetry`` asks for a quadrant
    (logged).  Either is one octant meshed and mirrored (``GeometrySpec.diagonal``)."""
    spec = GeometrySpec.from_study(study, with_air=with_air)
    breaking = mirror_breaking(study)
    if spec.with_air and study.mesh.symmetry == "quarter":
        if breaking:
            logger.info(f"the whole device is meshed, not a quadrant: {breaking}")
        elif is_imperfect(study.membrane, study.imperfections):
            logger.info("the imperfections keep both mirror planes: one quadrant is meshed")
    return load_mesh(spec, study.mesh.curve_order, cache_dir=cache_dir)


def membrane_area(spec: GeometrySpec) -> float:
    """Exact flat membrane area pi (r_o^2 - r_i^2) [m^2]."""
    return math.pi * (spec.outer_radius**2 - spec.inner_radius**2)
