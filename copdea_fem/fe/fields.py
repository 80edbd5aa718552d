"""Coincident output points merged (no duplicate points on element edges or mirror planes),
the quadrant copies unfolded, and the air's two halves across the screens."""

from __future__ import annotations

import numpy as np


class PointMerge:
    """Coincident output points merged into one: ``labels[i]`` is the written point of
    sample point ``i``; :meth:`reduce` writes the mean of the values merged into a point.

    Slices, clips and integrals in ParaView need a conforming mesh: two copies of one
    point (an element edge sampled twice, a quadrant and its mirror image on the plane
    x = 0) make a slice exactly on the plane count faces twice or leave holes.
    """

    def __init__(self, labels: np.ndarray, size: int):
        import scipy.sparse as sp

        self.labels = np.asarray(labels, dtype=np.int64)
        self.size = int(size)
        self.identity = self.size == len(self.labels) and bool(
            np.all(self.labels == np.arange(self.size)))
        counts = np.bincount(self.labels, minlength=self.size).astype(float)
        self._mean = sp.csr_matrix((1.0 / counts[self.labels],
                                    (self.labels, np.arange(len(self.labels)))),
                                   shape=(self.size, len(self.labels)))

    @classmethod
    def coincident(cls, points: np.ndarray, groups=None, tolerance: float = 1e-9) -> "PointMerge":
        """Merge points closer than ``tolerance`` times the extent of ``points`` (n, d);
        points of different ``groups`` (e.g. the two sides of a pressure jump) stay apart.
        Written points keep the order of their first sample point."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        from scipy.spatial import cKDTree

        points = np.asarray(points, dtype=float)
        n = len(points)
        if n == 0:
            return cls(np.zeros(0, dtype=np.int64), 0)
        extent = float(np.ptp(points, axis=0).max()) or 1.0
        key = points if groups is None else np.column_stack(
            [points, 10.0 * extent * np.asarray(groups, dtype=float)])
        pairs = cKDTree(key).query_pairs(tolerance * extent, output_type="ndarray")
        if len(pairs) == 0:
            return cls(np.arange(n), n)
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
        _, component = connected_components(graph, directed=False)
        return cls.from_components(component)

    @classmethod
    def from_components(cls, component: np.ndarray) -> "PointMerge":
        """Points with equal ``component`` merged; numbered in order of first appearance."""
        _, first, inverse = np.unique(component, return_index=True, return_inverse=True)
        order = np.argsort(first)
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        return cls(rank[inverse.ravel()], len(first))

    def reduce(self, values) -> np.ndarray:
        """Per-sample values (n[, ...]) -> per-written-point means (size[, ...])."""
        values = np.asarray(values)
        if self.identity:
            return values
        flat = values.reshape(len(values), -1)
        dtype = np.result_type(values.dtype, np.float64)
        merged = np.asarray(self._mean @ flat.astype(dtype, copy=False))
        return merged.reshape(self.size, *values.shape[1:])


def _quadrants(symmetry):
    from copdea_fem.fe.symmetry import QUADRANTS
    return QUADRANTS if symmetry.quarter else QUADRANTS[:1]


def unfold_cells(cells: np.ndarray, n_points: int, symmetry) -> np.ndarray:
    """Cells of every quadrant copy; a copy reflected once has its orientation reversed."""
    copies = []
    for number, (qx, qy) in enumerate(_quadrants(symmetry)):
        copy = cells + number * n_points
        copies.append(copy if qx * qy > 0 else copy[:, [0, 2, 1, *range(3, cells.shape[1])]])
    return np.concatenate(copies)


def unfold_values(values: np.ndarray, symmetry, sector=None) -> np.ndarray:
    """Quadrant values -> all quadrants: f(q x) = s(q) R_q f(x) (vectors: x, y flipped)."""
    parts = []
    for qx, qy in _quadrants(symmetry):
        sign = 1.0 if sector is None else float(sector.sign(qx, qy))
        if values.ndim == 2 and values.shape[1] == 3:
            parts.append(values * (sign * np.array([qx, qy, 1.0])))
        else:
            parts.append(values * sign)
    return np.concatenate(parts)


class AirHalves:
    """The air's element corners with the lower half (an enclosure's cavity) on its own copy
    of the mesh vertices (the pressure jumps across the screens; values are taken inside each
    element), on the mesh moved by ``mesh_motion``; 3-D tetrahedra or meridian triangles
    (the dimension of ``mesh``).  ``copy[e, k]``: the vertex of corner k of element e,
    ``side * count + vertex`` with side 0 (``p``), 1 (``p + q``: the lower half, or the
    cavity) and 2 (``p + q_o``: the lower half of an enclosure's mesh with a third field,
    :func:`copdea_fem.fe.acoustics.pressure_space`); ``moved``: the moved coordinates of
    every copy; ``used``/``renumber``: the vertices a cell uses and their new numbers.
    ``split``: per mesh vertex, whether its side-1 copy is its own point (where the pressure
    jumps: :func:`jump_vertices`); None: every side-1 vertex (the open plane then carries
    two coincident copies of one pressure); ``outside_split`` the same for side 2 (None:
    no side 2)."""

    SIDES = 3

    def __init__(self, mesh, points, mesh_motion, split=None, outside_split=None):
        import ngsolve as ngs

        from copdea_fem.fe.acoustics import CAVITY, LOWER, PML_REGIONS, jump_side
        dim = mesh.dim
        elements = list(mesh.Elements(ngs.VOL))
        lower, in_pml = mesh.Materials(jump_side(mesh)).Mask(), mesh.Materials(PML_REGIONS).Mask()
        cavity, below = mesh.Materials(CAVITY).Mask(), mesh.Materials(LOWER).Mask()
        self.lower = np.array([lower[el.index] for el in elements], dtype=bool)
        #: elements of an enclosure's air (:data:`copdea_fem.fe.acoustics.CAVITY`; there
        #: the pressure is ``p + q``, so they are :attr:`lower` too)
        self.cavity = np.array([cavity[el.index] for el in elements], dtype=bool)
        self.in_pml = np.array([in_pml[el.index] for el in elements], dtype=bool)
        outside_lower = np.array([below[el.index] for el in elements], dtype=bool) \
            & self.cavity.any()
        reference = np.asarray(ngs.CF((ngs.x, ngs.y, ngs.z)[:dim])(points)).reshape(
            len(elements), -1, dim)
        corners = reference.shape[1]
        coordinates = mesh.ngmesh.Coordinates()[:, :dim]
        vertex_ids = np.array([[v.nr for v in el.vertices] for el in elements])
        corner_vertex = np.empty((len(elements), corners), dtype=int)
        for k in range(corners):      # which mesh vertex each reference corner is: by coordinates
            distance = np.linalg.norm(reference[:, k:k + 1, :] - coordinates[vertex_ids], axis=2)
            corner_vertex[:, k] = vertex_ids[np.arange(len(elements)), distance.argmin(axis=1)]
        self.count = count = len(coordinates)
        side = np.where(self.lower[:, None] if split is None else
                        self.lower[:, None] & np.asarray(split, dtype=bool)[corner_vertex], 1, 0)
        if outside_split is not None:
            side = np.where(outside_lower[:, None]
                            & np.asarray(outside_split, dtype=bool)[corner_vertex], 2, side)
        self.copy = side * count + corner_vertex
        motion = np.asarray(mesh_motion(points)).reshape(len(elements), corners, dim)
        total = self.SIDES * count
        self.moved = np.zeros((total, dim))
        self.moved[self.copy.ravel()] = (reference + motion).reshape(-1, dim)
        self.reference = np.zeros((total, dim))
        self.reference[self.copy.ravel()] = reference.reshape(-1, dim)
        self.used = np.unique(self.copy)
        self.renumber = -np.ones(total, dtype=int)
        self.renumber[self.used] = np.arange(len(self.used))


def jump_vertices(pressure_space, vertices: int, component: int = 1):
    """Per mesh vertex: whether the pressure jump ``q`` (``component`` 1; 2: the lower
    half's ``q_o`` beside an enclosure) of :func:`copdea_fem.fe.acoustics.pressure_space`
    has a free DOF there (a screen or wall vertex; that side needs its own copy); None when
    the space has no such component."""
    try:
        active = pressure_space.components[component].GetActiveDofs()
    except (AttributeError, IndexError):
        return None
    # H1 numbers the vertex DOFs first, one per mesh vertex
    return np.array([active[k] for k in range(vertices)], dtype=bool)


class CornerPressure:
    """The complex pressure [Pa] at the air's element corners of a vector of the pressure
    space ``P x Q`` (:func:`copdea_fem.fe.acoustics.pressure_space`; beside an enclosure
    maybe ``P x Q x Q_o``): ``__call__`` returns what
    :func:`copdea_fem.fe.acoustics.pressure_field` (``p + lower q [+ q_o]``) evaluates to at
    ``points`` (every element's corners, :meth:`ngsolve.Mesh.MapToAllElements`), as an
    (n,) array, read from the vector instead of evaluated.

    At a corner, H1's vertex shape function is 1 and every other shape function 0, to the
    bit (barycentric coordinates 0 and 1 exactly): the value there is ``p``'s vertex DOF,
    plus ``q``'s in the lower half.  Which DOF each corner reads is found once by
    evaluating the field of two probe vectors (the DOF numbers as values, in ``P`` and then
    in ``Q``) and checked against the evaluation of one random vector; where it is equal to
    the bit, each vector costs two gathers (far cheaper than an evaluation), else (a space
    where a corner is no single DOF) every vector is evaluated.
    """

    def __init__(self, space, points):
        import ngsolve as ngs

        from copdea_fem.fe.acoustics import pressure_field

        self.size = space.ndof
        self._gf = ngs.GridFunction(space)
        parts = list(self._gf.components) + [None]      # (p, q[, q_o]): pressure_space
        self._field = pressure_field(parts[0], parts[1], space.mesh, parts[2])
        self._points = points
        self._dofs = None
        ranges = [space.Range(k) for k in range(len(self._gf.components))]
        reads = []
        for start, stop in ((r.start, r.stop) for r in ranges):
            probe = np.zeros(self.size)
            probe[start:stop] = np.arange(1, stop - start + 1)
            values = self._evaluate(probe)
            read = np.rint(values.real).astype(np.int64)
            if not (np.array_equal(values, read) and np.all((read >= 0) & (read <= stop - start))):
                return                                   # not one DOF per corner
            reads.append(np.where(read > 0, start + read - 1, self.size))
        if np.any(reads[0] == self.size):
            return                                       # a corner without a DOF of P
        random = np.random.default_rng(0)
        check = random.standard_normal(self.size) + 1j * random.standard_normal(self.size)
        gathered = np.append(check, 0.0)
        if np.array_equal(sum(gathered[read] for read in reads), self._evaluate(check)):
            self._dofs = reads

    @property
    def gathered(self) -> bool:
        """Whether vectors are read at the corners' DOFs (else evaluated)."""
        return self._dofs is not None

    def _evaluate(self, vector) -> np.ndarray:
        """The field of ``vector`` evaluated at the corners, (n,) complex."""
        self._gf.vec.FV().NumPy()[:] = vector
        return np.asarray(self._field(self._points)).ravel()

    def __call__(self, vector) -> np.ndarray:
        """The pressure [Pa] at the corners of a full vector of the space, (n,) complex."""
        if self._dofs is None:
            return self._evaluate(vector)
        padded = np.zeros(self.size + 1, dtype=complex)
        padded[:-1] = vector
        return sum(padded[read] for read in self._dofs)
