"""ParaView fields of the 3-D engine: the membrane sampled on its (curved, high-order)
elements and the air per mode, a quadrant mesh unfolded into the whole device."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from copdea_fem.fe.fields import (
    AirHalves,
    CornerPressure,
    PointMerge,
    jump_vertices,
    unfold_cells,
    unfold_values,
)
from copdea_fem.vtu import VtuMesh, membrane_mesh, pressure_point_data, safe_name, write_all


class MembraneSampler:
    """Points of a subdivided membrane surface for VTU output (curved, high order).

    Every membrane face element is split into ``subdivision**2`` triangles in
    its reference coordinates; fields are evaluated at the mapped points, so
    curved elements and high-order fields are drawn faithfully.  On a quadrant
    mesh (:mod:`copdea_fem.fe.symmetry`) the four quadrants are written: points,
    vectors and a sector's fields are unfolded by reflection.  Coincident points
    (shared element edges, the copies on the mirror planes) are merged
    (:class:`PointMerge`): a field continuous across them (the displacement) is
    written as it is, one taken inside each element (the prestress stretches, the
    normal) as the mean of the elements' values; on the mirror planes the copies
    agree by parity.
    """

    def __init__(self, mesh, subdivision: int = 3, region: str = "membrane"):
        import ngsolve as ngs

        from copdea_fem.fe.symmetry import Symmetry

        s = subdivision
        local = [(i / s, j / s) for j in range(s + 1) for i in range(s + 1 - j)]
        index = {key: k for k, key in enumerate((i, j) for j in range(s + 1)
                                                 for i in range(s + 1 - j))}
        triangles = []
        for j in range(s):
            for i in range(s - j):
                triangles.append((index[i, j], index[i + 1, j], index[i, j + 1]))
                if i + j < s - 1:
                    triangles.append((index[i + 1, j], index[i + 1, j + 1], index[i, j + 1]))
        rule = ngs.IntegrationRule([(a, b, 0) for a, b in local], [0.0] * len(local))
        # the region's elements only (an air mesh has ~10x more boundary elements)
        self.points = mesh.MapToAllElements(rule, mesh.Boundaries(region))
        names = mesh.GetBoundaries()
        count = sum(names[el.index] == region for el in mesh.Elements(ngs.BND))
        per_element = len(local)
        cells = (np.arange(count)[:, None, None] * per_element
                 + np.array(triangles)[None, :, :]).reshape(-1, 3)
        self.symmetry = Symmetry.of_mesh(mesh)
        reference = unfold_values(np.asarray(ngs.CF((ngs.x, ngs.y, ngs.z))(self.points)),
                                   self.symmetry)
        self.merge = PointMerge.coincident(reference)
        self.cells = self.merge.labels[unfold_cells(cells, count * per_element, self.symmetry)]
        self.coordinates = self.merge.reduce(reference)

    def evaluate(self, coefficient, sector=None) -> np.ndarray:
        """Values of a CoefficientFunction at the sample points, (n_points,) or (n_points, d).

        ``sector``: the symmetry class of a mode field on a quadrant mesh (None:
        even about both planes, like the prestress and the coordinates).  A point
        shared by several elements (or quadrant copies) gets the mean of their values.
        """
        values = np.asarray(coefficient(self.points))
        values = values[:, 0] if values.ndim == 2 and values.shape[1] == 1 else values
        return self.merge.reduce(unfold_values(values, self.symmetry, sector))


def write_mode_vtus(directory: Path, state, modes, sampler: MembraneSampler) -> list[Path]:
    """One .vtu per mode on the prestressed shape: displacement re/im/abs, normal velocity.

    Mode shapes are normalised to peak |u| = 1 (dimensionless); the normal
    velocity amplitude is omega |u.n| for that normalisation [1/s].  Field data: the
    mode's ``frequency_hz`` [Hz] and ``orientation_deg`` [deg] (modes.csv's: the angle of
    its first antinode line, NaN for m = 0), so that ParaView shows which member of a split
    pair a file holds.
    """
    return write_all(directory, mode_meshes(state, modes, sampler))


def mode_meshes(state, modes, sampler: MembraneSampler):
    """``(file stem, VtuMesh)`` of each mode of :func:`write_mode_vtus`, one at a time;
    every mesh holds the same points (the deformed membrane, sampled once) and triangles,
    which a :class:`~copdea_fem.vtu.VtuWriter` encodes once."""
    import ngsolve as ngs

    from copdea_fem.fe.membrane import deformed_normal

    mode_field = ngs.GridFunction(state.space)
    normal = sampler.evaluate(deformed_normal(state.displacement))
    deformed = sampler.coordinates + sampler.evaluate(state.displacement)
    for number, mode in enumerate(modes):
        parts = []
        for part in (np.real(mode.vector), np.imag(mode.vector)):
            mode_field.vec.FV().NumPy()[:] = part
            parts.append(sampler.evaluate(mode_field, mode.sector))
        shape = parts[0] + 1j * parts[1]
        normal_shape = np.sum(shape * normal, axis=1)
        omega = 2 * np.pi * abs(complex(mode.freq_hz, mode.freq_im_hz))
        fields = {"displacement_real": parts[0], "displacement_imag": parts[1],
                  "displacement_abs": np.linalg.norm(np.abs(shape), axis=1),
                  "normal_displacement_real": normal_shape.real,
                  "normal_displacement_imag": normal_shape.imag,
                  "normal_velocity_abs": omega * np.abs(normal_shape)}
        yield (f"mode_{number:03d}_{safe_name(mode.label)}",
               VtuMesh(deformed, [("triangle", sampler.cells)], point_data=fields,
                       field_data={"frequency_hz": mode.freq_hz,
                                   "orientation_deg": mode.orientation_deg}))


def write_air_vtus(directory: Path, operators, modes, pressures) -> list[Path]:
    """One .vtu per mode of the air (:func:`air_meshes`), ``air_NNN_<label>.vtu``."""
    return write_all(directory, air_meshes(operators, modes, pressures))


def air_meshes(operators, modes, pressures):
    """``(file stem, VtuMesh)`` per mode of the air on the deformed mesh: pressure
    re/im/abs, PML, lower-half and (with an enclosure) cavity flags.

    ``operators``: the :class:`copdea_fem.fe.coupled.CoupledOperators` of each
    sector (one on a whole mesh); a mode's pressure vector is read with its
    sector's.  The pressure jumps across the screens (and an enclosure's walls), so the
    sides get their own copies of the mesh vertices (:class:`AirHalves`); values are taken
    inside each element (no ambiguity at the plane); elsewhere, on the open plane and in a
    vent too, a vertex is written once.  A quadrant mesh is unfolded into the whole air,
    the copies of the mirror planes' vertices merged (:class:`PointMerge`; they agree by
    parity).  Pressures are per unit peak membrane displacement [Pa/m], like the membrane
    files.  The cell data ``cavity`` marks an enclosure's air, which the writer puts into
    its own ParaView block (:func:`copdea_fem.vtu.split_cells`).
    """
    import ngsolve as ngs

    from copdea_fem.fe.symmetry import Symmetry

    by_sector = {coupled.membrane.sector: coupled for coupled in operators}
    first = operators[0]
    space = first.pressure_space
    mesh = space.mesh
    symmetry = Symmetry.of_mesh(mesh)
    corners = ngs.IntegrationRule([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], [0.0] * 4)
    points = mesh.MapToAllElements(corners, ngs.VOL)
    vertices = len(mesh.ngmesh.Coordinates())
    halves = AirHalves(mesh, points, first.mesh_motion, split=jump_vertices(space, vertices),
                       outside_split=jump_vertices(space, vertices, component=2))
    copy, used, count = halves.copy, halves.used, halves.count
    moved = unfold_values(halves.moved[used], symmetry)
    # the copies of the mirror planes' vertices merged (the sides of a screen or wall kept
    # apart); found on the reference mesh (the ALE motion leaves ~1e-8 m normal to the
    # planes there), so the merged point, the mean of the mirror images, lies exactly on
    # the plane
    merge = PointMerge.coincident(unfold_values(halves.reference[used], symmetry),
                                  groups=np.tile(used // count, symmetry.copies))
    cells = merge.labels[unfold_cells(halves.renumber[copy], len(used), symmetry)]
    moved = merge.reduce(moved).astype(np.float32)
    flags = [("pml", halves.in_pml), ("lower_half", halves.lower)]
    if halves.cavity.any():
        flags.append(("cavity", halves.cavity))
    cell_data = {name: [np.tile(flag.astype(np.int8), symmetry.copies)] for name, flag in flags}
    reader = CornerPressure(space, points)      # the corners' DOFs, found once
    for number, (mode, pressure) in enumerate(zip(modes, pressures)):
        vector = np.zeros(space.ndof, dtype=complex)
        vector[by_sector[mode.sector].pressure_free] = pressure
        nodal = np.zeros(AirHalves.SIDES * count, dtype=complex)
        nodal[copy.ravel()] = reader(vector).ravel()
        nodal = merge.reduce(unfold_values(nodal[used], symmetry, mode.sector))
        data = pressure_point_data(nodal)
        yield (f"air_{number:03d}_{safe_name(mode.label)}",
               VtuMesh(moved, [("tetra", cells)], point_data=data, cell_data=cell_data))


class QuadrantOutput:
    """The 3-D engine's result fields for ParaView and the API, behind the engine interface
    (:meth:`copdea_fem.fe.quadrant.engine.QuadrantEngine.output`): the membrane sampled on its
    elements (:class:`MembraneSampler`, built on first use), a quadrant mesh unfolded.

    ``modes``: the structural modes written together (unused here: the sample points do
    not depend on the modes; the axisymmetric counterpart sets its angles from them).
    """

    def __init__(self, state, modes=()):
        self.state = state
        self._sampler = None

    @property
    def symmetry(self) -> str:
        """What modes.json's eigen block calls the symmetry: the mesh's (quarter, ...)."""
        return self.state.symmetry.kind

    @property
    def sampler(self) -> MembraneSampler:
        if self._sampler is None:
            self._sampler = MembraneSampler(self.state.mesh)
        return self._sampler

    def prestress_mesh(self):
        """The :class:`~copdea_fem.vtu.VtuMesh` of prestress.vtu (the prestress
        fields, deformed)."""
        return membrane_mesh(self.sampler, self.state.fields(), self.state.displacement)

    def mode_meshes(self, modes):
        """``(file stem, VtuMesh)`` of each mode's membrane file (:func:`mode_meshes`)."""
        return mode_meshes(self.state, modes, self.sampler)

    def air_meshes(self, operators, modes, pressures):
        """``(file stem, VtuMesh)`` of each mode's air file (:func:`air_meshes`)."""
        return air_meshes(operators, modes, pressures)
