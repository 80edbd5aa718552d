"""A mesh symmetric under the diagonal mirror x <-> y: one octant meshed, mirrored.

Netgen meshes a shape as it comes: the quadrant's unstructured mesh is not symmetric under
the reflection (x, y) -> (y, x), although the device (circle, square frame, sphere, the
enclosures) is.  On such a mesh the discrete operator does not commute with the reflection,
and the modes of the even-even sector mix the square's classes A1 (even under x <-> y) and
B1 (odd): an order-2 drive then reaches the pumping modes.  Here the octant
0 <= theta <= 45 deg is meshed once and its images under the reflections tile the meshed
part, nodes on the mirror planes shared:

* a quadrant (``symmetry = "quarter"``): the octant and its image across x = y;
* the whole plane: the eight images of the dihedral group D4 (the octant, across x = y, and
  each of those across x = 0, y = 0 or both).

Every node then maps to a node and every element to an element under x <-> y (and, on the
whole plane, under x -> -x and y -> -y), exactly: reflections of floating-point numbers are
exact, the octant's nodes on its cut planes are first put on them (they lie within OCC's
tolerance of them), and the nodes Netgen's projections moved are put back.

The images keep the octant's volume indices (materials) and boundary names; faces and edges
on a cut plane inside the meshed part (the diagonal, and on the whole plane x = 0, y = 0) are
internal and dropped.  Each image face gets the face of the curving geometry it lies on (the
glued images of the octant's shape, :func:`copdea_fem.fe.quadrant.geometry.build_shape`), and
its nodes that face's surface parameters (Netgen's projection), so ``mesh.Curve`` maps the
mirrored elements onto the true surfaces as it does the meshed ones.
"""

from __future__ import annotations

import numpy as np

#: Name of an octant face (edge: + ``"_edge"``) on a cut plane that is internal to the
#: meshed part: dropped from the mirrored mesh.
CUT = "octant_cut"

#: The reflections, as 2x2 matrices on (x, y).
REFLECTIONS = {"diagonal": np.array([[0.0, 1.0], [1.0, 0.0]]),
               "x": np.array([[-1.0, 0.0], [0.0, 1.0]]),
               "y": np.array([[1.0, 0.0], [0.0, -1.0]])}

#: Relative distance [-] (of the mesh's extent) within which an octant node counts as on a
#: cut plane and is put on it: far below any element, above the tolerance of OCC's Boolean
#: cut (a vertex of the cut lies up to ~3e-9 m off the plane).
ON_PLANE = 1e-6


def images(quarter: bool) -> list[tuple[str, ...]]:
    """The reflection sequences (applied left to right, names of :data:`REFLECTIONS`) whose
    images of the octant tile the quadrant (``quarter``) or the whole plane."""
    tiles = [(), ("diagonal",)]
    if quarter:
        return tiles
    return [tile + axes for axes in ((), ("x",), ("y",), ("x", "y")) for tile in tiles]


def matrix(sequence: tuple[str, ...]) -> np.ndarray:
    """The 2x2 matrix on (x, y) of a reflection sequence (the first applied first)."""
    result = np.eye(2)
    for name in sequence:
        result = REFLECTIONS[name] @ result
    return result


def mirror_shape(shape, sequence: tuple[str, ...]):
    """A copy of an OCC shape reflected by the sequence (planes through the z axis)."""
    from netgen.occ import Axes

    normals = {"diagonal": (1.0, -1.0, 0.0), "x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0)}
    for name in sequence:
        shape = shape.Mirror(Axes((0, 0, 0), n=normals[name], h=(0, 0, 1)))
    return shape


def rename(name: str, sequence: tuple[str, ...]) -> str | None:
    """An octant face's or edge's name on its image: None for a cut (internal) one; the
    quadrant's mirror planes swap their names across x = y."""
    if name.startswith(CUT):
        return None
    if sequence.count("diagonal") % 2:
        swap = {"mirror_x": "mirror_y", "mirror_y": "mirror_x"}
        for old, new in swap.items():
            if name == old or name == old + "_edge":
                return name.replace(old, new)
    return name


def _centres(shapes) -> tuple[np.ndarray, np.ndarray]:
    centres = np.array([[shape.center.x, shape.center.y, shape.center.z] for shape in shapes])
    return centres, np.array([shape.mass for shape in shapes])


class _Matcher:
    """Index (0-based) of the shape of the curving geometry that is a given octant shape's
    image: same centre of mass and size (length or area)."""

    def __init__(self, targets, scale: float):
        self.centres, self.sizes = _centres(targets)
        self.scale = scale

    def __call__(self, shape, sequence) -> int:
        centre, size = _centres([shape])
        centre = centre[0]
        centre[:2] = matrix(sequence) @ centre[:2]
        distance = np.linalg.norm(self.centres - centre, axis=1)
        index = int(np.argmin(distance))
        if distance[index] > 1e-6 * self.scale \
                or abs(self.sizes[index] - size[0]) > 1e-6 * max(abs(size[0]), 1e-30):
            raise RuntimeError(f"no image of an octant face or edge (centre {centre}) in the "
                               f"curving geometry: nearest at {distance[index]:g} m")
        return index


def snap_to_planes(points: np.ndarray) -> np.ndarray:
    """The octant's nodes with those within :data:`ON_PLANE` of x = y or y = 0 put on it."""
    points = np.array(points, dtype=float)
    tol = ON_PLANE * np.abs(points).max()
    on_diagonal = np.abs(points[:, 0] - points[:, 1]) < tol
    middle = 0.5 * (points[on_diagonal, 0] + points[on_diagonal, 1])
    points[on_diagonal, 0] = middle
    points[on_diagonal, 1] = middle
    on_axis = np.abs(points[:, 1]) < tol
    points[on_axis, 1] = 0.0
    points[on_axis & on_diagonal, 0] = 0.0
    return points


def mirrored_mesh(octant, octant_geometry, geometry, sequences):
    """The Netgen mesh of the images of the ``octant`` mesh (of ``octant_geometry``) under
    the reflection ``sequences``, on the curving ``geometry`` (the glued images); see the
    module doc."""
    from netgen import meshing

    points = snap_to_planes(octant.Coordinates())
    count = len(points)
    stacked = []
    for sequence in sequences:
        image = points.copy()
        image[:, :2] = points[:, :2] @ matrix(sequence).T
        stacked.append(image + 0.0)                         # -0.0 -> 0.0
    unique, first, inverse = np.unique(np.vstack(stacked), axis=0, return_index=True,
                                       return_inverse=True)
    order = np.argsort(first, kind="stable")                 # the octant's nodes first
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    node = rank[np.ravel(inverse)].reshape(len(sequences), count)   # 0-based, per image

    _check_no_crack(unique, ON_PLANE * float(np.abs(points).max()))
    mesh = meshing.Mesh(dim=3)
    mesh.AddPoints(np.ascontiguousarray(unique[order]))
    mesh.SetGeometry(geometry)
    for domain in range(1, octant.GetNDomains() + 1):
        mesh.SetMaterial(domain, octant.GetMaterial(domain))
    scale = float(np.abs(points).max())

    volumes = octant.Elements3D().NumPy()
    if len(volumes):
        _check_simplices(volumes, 4, "volume")
        nodes = volumes["nodes"][:, :4].astype(np.int64) - 1
        for image, sequence in enumerate(sequences):
            mapped = node[image][nodes]
            if len(sequence) % 2:                        # a reflection: keep the orientation
                mapped[:, [0, 1]] = mapped[:, [1, 0]]
            for domain in np.unique(volumes["index"]):
                chosen = np.ascontiguousarray(mapped[volumes["index"] == domain], np.int32)
                mesh.AddElements(3, int(domain), chosen, 0)

    faces = _Matcher(geometry.faces, scale)
    octant_faces = octant_geometry.faces
    surfaces = octant.Elements2D().NumPy()
    _check_simplices(surfaces, 3, "surface")
    nodes = surfaces["nodes"][:, :3].astype(np.int64) - 1
    for number, descriptor in enumerate(octant.FaceDescriptors(), start=1):
        chosen = surfaces["index"] == number
        for image, sequence in enumerate(sequences):
            name = rename(descriptor.bcname, sequence)
            if name is None:
                continue
            target = faces(octant_faces[descriptor.surfnr - 1], sequence)
            new = meshing.FaceDescriptor(surfnr=target + 1, domin=descriptor.domin,
                                         domout=descriptor.domout,
                                         bc=mesh.GetNFaceDescriptors() + 1)
            new.bcname = name
            index = mesh.Add(new)
            mapped = node[image][nodes[chosen]]
            if len(sequence) % 2:
                mapped[:, [1, 2]] = mapped[:, [2, 1]]
            if len(mapped):
                mesh.AddElements(2, index, np.ascontiguousarray(mapped, np.int32), 0, True)

    edges = _Matcher(geometry.edges, scale)
    octant_edges = octant_geometry.edges
    segments = octant.Elements1D().NumPy()
    nodes = segments["nodes"][:, :2].astype(np.int64) - 1
    seen: set = set()
    for number, descriptor in enumerate(octant.EdgeDescriptors(), start=1):
        chosen = segments["index"] == number
        for image, sequence in enumerate(sequences):
            name = rename(descriptor.name, sequence)
            if name is None:
                continue
            mapped = node[image][nodes[chosen]]
            fresh = [k for k, pair in enumerate(map(tuple, np.sort(mapped, axis=1)))
                     if pair not in seen]
            seen.update(tuple(pair) for pair in np.sort(mapped[fresh], axis=1))
            if not fresh:                      # an edge on the mirror plane: its own image
                continue
            new = meshing.EdgeDescriptor()
            new.edgenr = edges(octant_edges[descriptor.edgenr - 1], sequence) + 1
            new.name = name
            index = mesh.Add(new)
            mesh.AddElements(1, index, np.ascontiguousarray(mapped[fresh], np.int32), 0, True)
    # Netgen's projections (the surface parameters) move nodes by its Newton tolerance
    # (~3e-9 m): put them back on their exact, mirrored positions
    exact = unique[order]
    table = mesh.Points()
    for moved in np.flatnonzero(np.any(mesh.Coordinates() != exact, axis=1)):
        table[meshing.PointId(int(moved) + 1)] = meshing.MeshPoint(
            meshing.Pnt(*map(float, exact[moved])))
    return mesh


def _check_simplices(elements, corners: int, kind: str) -> None:
    if len(np.unique(elements["type"])) > 1 or elements["nodes"].shape[1] < corners:
        raise RuntimeError(f"the octant mesh has {kind} elements other than simplices")


def _check_no_crack(points: np.ndarray, distance: float) -> None:
    """Two distinct nodes closer than ``distance`` [m] would be a node on a cut plane that was
    not put on it: its images would not be shared (a crack in the mesh)."""
    from scipy.spatial import cKDTree

    pairs = cKDTree(points).query_pairs(distance)
    if pairs:
        first = points[list(next(iter(pairs)))]
        raise RuntimeError(f"the mirrored mesh has {len(pairs)} pair(s) of nodes closer than "
                           f"{distance:g} m (e.g. {first.tolist()}): a node of the octant off "
                           "its cut plane")
