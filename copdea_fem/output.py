"""Result files: modes.csv / modes.json, ParaView .pvd/.vtu, PNG plots.

Every writer takes a target directory: the staging folder of
:func:`copdea_fem.folders.result_directory`, renamed into place only when
everything is written, so a failed run leaves no half-finished results behind.
"""

from __future__ import annotations

import csv
import math
import json
import os
import sys
from pathlib import Path

import numpy as np

from .study import Study, dump_resolved, package_versions

#: VTU files are written binary, uncompressed (:func:`write_vtu`): zlib took half of the
#: output time of a coupled solve (3.2 of 6.7 s, G1 default mesh, 48 modes) for files 2-3x
#: smaller.
VTU_COMPRESSION = None

MODE_COLUMNS = ("label", "m", "n", "kind", "freq_hz", "freq_im_hz", "damping_ratio",
                "membrane_energy_fraction", "modal_mass", "dry_freq_hz", "added_mass_ratio",
                "normal_fraction", "disc_fraction", "residual", "symmetry")


def mode_rows(modes, dry_frequencies: dict | None = None) -> list[dict]:
    """One row per mode with :data:`MODE_COLUMNS` (SI: Hz, kg).

    ``dry_frequencies`` maps a mode's position in ``modes`` to the frequency of
    its dry partner [Hz]; None means the modes are dry themselves.  Modes
    without a partner (air modes) get NaN for ``dry_freq_hz`` and
    ``added_mass_ratio``.
    """
    rows = []
    for index, mode in enumerate(modes):
        dry = mode.freq_hz if dry_frequencies is None else dry_frequencies.get(index, math.nan)
        rows.append({
            "label": mode.label, "m": mode.m, "n": mode.n, "kind": mode.kind,
            "freq_hz": mode.freq_hz, "freq_im_hz": mode.freq_im_hz,
            "damping_ratio": mode.damping_ratio,
            "membrane_energy_fraction": mode.membrane_energy_fraction,
            "modal_mass": mode.modal_mass, "dry_freq_hz": dry,
            "added_mass_ratio": (dry / mode.freq_hz) ** 2 - 1 if mode.freq_hz > 0 else 0.0,
            "normal_fraction": mode.normal_fraction, "disc_fraction": mode.disc_fraction,
            "residual": mode.residual,
            # parity about x = 0 and y = 0 on a quadrant mesh (copdea_fem.symmetry), else ""
            "symmetry": mode.sector.name if mode.sector is not None else ""})
    return rows


def write_modes(directory: Path, rows: list[dict], study: Study, extra: dict) -> None:
    """modes.csv, modes.json and study.resolved.yaml."""
    with open(directory / "modes.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=MODE_COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({key: (f"{value:.10g}" if isinstance(value, float) else value)
                             for key, value in row.items()})
    document = {"study": study.as_dict(), "provenance": package_versions(), **extra,
                "modes": rows}
    (directory / "modes.json").write_text(json.dumps(document, indent=1, default=_json))
    dump_resolved(study, directory / "study.resolved.yaml")


def _json(value):
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    raise TypeError(f"cannot serialise {type(value).__name__}")


def frequency_table(rows: list[dict], kinds=("pumping", "out-of-plane", "in-plane")) -> str:
    """Plain-text table of the modes for the terminal."""
    lines = [f"{'label':>10} {'kind':>13} {'f [Hz]':>10} {'Im f [Hz]':>10} {'residual':>9}"]
    for row in rows:
        if row["kind"] in kinds:
            lines.append(f"{row['label']:>10} {row['kind']:>13} {row['freq_hz']:10.2f} "
                         f"{row['freq_im_hz']:10.3f} {row['residual']:9.1e}")
    return "\n".join(lines)


# -- the result folder of solve and force ------------------------------------------
def prestress_summary(state) -> dict:
    """The prestress block of modes.json (SI)."""
    return {"z_m": state.z, "voltage_v": state.voltage, "disc_force_n": state.disc_force,
            "newton_iterations": state.newton_iterations,
            "load_steps": [{"z_m": z, "voltage_v": v, "newton_iterations": it}
                           for z, v, it in state.load_steps]}


def write_results(result, out_dir: Path) -> None:
    """Every file of ``solve`` for a :class:`copdea_fem.solve.SolveResult` (either engine),
    staged and moved into place (:func:`copdea_fem.folders.result_directory`)."""
    from .folders import result_directory
    from .modes import IN_PLANE, OUT_OF_PLANE, PUMPING

    study = result.study
    axisymmetric = getattr(result.state, "engine", "3d") == "axisymmetric"
    extra = {"prestress": prestress_summary(result.state),
             "eigen": {"engine": "axisymmetric" if axisymmetric else "3d",
                       "shifts_hz": [float(f) for f in result.eigen.shift_freq_hz],
                       "unknowns": int(result.eigen.unknowns),
                       "factorisations": int(result.eigen.n_factorisations),
                       "symmetry": "orders" if axisymmetric else result.state.symmetry.kind,
                       **_sector_summary(result.eigen)},
             "timings_s": result.timings.seconds}
    with result_directory(out_dir, "solve") as staging:
        write_modes(staging, result.rows, study, extra)
        if study["output"]["paraview"] or study["output"]["plots"]:
            structural = [mode for mode in result.modes
                          if mode.kind in (OUT_OF_PLANE, PUMPING, IN_PLANE)]
            plotted = [k for k, mode in enumerate(structural)
                       if mode.kind in (OUT_OF_PLANE, PUMPING)][:8]
            kept = {k: None for k in plotted}
            files = write_paraview(staging, result.state, structural, kept=kept)
            if result.coupled is not None and study["output"]["paraview"]:
                indices = [k for k, mode in enumerate(result.modes) if mode.kind != "air"]
                write_air = write_revolved_air_vtus if axisymmetric else \
                    write_air_vtus
                air_files = write_air(
                    staging, result.coupled.operators, [result.modes[k] for k in indices],
                    [result.coupled.pressures[k] for k in indices])
                write_pvd(staging / "air.pvd", air_files, list(range(len(air_files))))
            if study["output"]["plots"]:
                plot_modes(staging / "modes.png", [kept[k] or files[k] for k in plotted],
                           [structural[k] for k in plotted])
            if not study["output"]["paraview"]:
                for path in list(staging.glob("*.vtu")) + list(staging.glob("*.pvd")):
                    path.unlink()


def _sector_summary(eigen_result) -> dict:
    """Per-sector unknowns, shifts and eigenpair counts of a coupled solve (modes.json)."""
    if not hasattr(eigen_result, "by_sector"):
        return {}
    return {"sectors": {name: {"unknowns": part.unknowns, "eigenpairs": len(part),
                               "shifts_hz": [float(f) for f in part.shift_freq_hz]}
                        for name, part in eigen_result.by_sector.items()}}


def write_paraview(directory: Path, state, modes, kept: dict | None = None) -> list[Path]:
    """prestress.vtu + modes.pvd with one .vtu per mode (revolved to 3-D when axisymmetric).

    ``kept``: ``{position in modes: None}``; receives the :class:`meshio.Mesh` of those
    modes' files (for the plot, without reading them back).
    """
    if getattr(state, "engine", "3d") == "axisymmetric":
        sampler = RevolvedMembraneSampler(state)
        write_membrane_vtu(directory / "prestress", sampler, sampler.prestress_fields(),
                           displacement=sampler.prestress_displacement())
        files = _write_all(directory, revolved_mode_meshes(state, modes, sampler), kept)
    else:
        sampler = MembraneSampler(state.mesh)
        write_membrane_vtu(directory / "prestress", sampler, state.fields(),
                           displacement=state.displacement)
        files = _write_all(directory, mode_meshes(state, modes, sampler), kept)
    write_pvd(directory / "modes.pvd", files, list(range(len(files))))
    return files


def write_force_results(study: Study, out_dir: Path, z_values, voltages, forces) -> None:
    """force_displacement.csv (+ PNG) and study.resolved.yaml of ``force``."""
    from .folders import result_directory

    with result_directory(out_dir, "force") as staging:
        write_force_csv(staging / "force_displacement.csv", z_values, voltages, forces)
        if study["output"]["plots"]:
            plot_force_displacement(staging / "force_displacement.png", z_values, voltages,
                                    forces)
        dump_resolved(study, staging / "study.resolved.yaml")


# -- ParaView -------------------------------------------------------------------------
class MembraneSampler:
    """Points of a subdivided membrane surface for VTU output (curved, high order).

    Every membrane face element is split into ``subdivision**2`` triangles in
    its reference coordinates; fields are evaluated at the mapped points, so
    curved elements and high-order fields are drawn faithfully.  On a quadrant
    mesh (:mod:`copdea_fem.symmetry`) the four quadrants are written: points,
    vectors and a sector's fields are unfolded by reflection.  Coincident points
    (shared element edges, the copies on the mirror planes) are merged
    (:class:`PointMerge`): a field continuous across them (the displacement) is
    written as it is, one taken inside each element (the prestress stretches, the
    normal) as the mean of the elements' values; on the mirror planes the copies
    agree by parity.
    """

    def __init__(self, mesh, subdivision: int = 3, region: str = "membrane"):
        import ngsolve as ngs

        from .symmetry import Symmetry

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
        reference = _unfold_values(np.asarray(ngs.CF((ngs.x, ngs.y, ngs.z))(self.points)),
                                   self.symmetry)
        self.merge = PointMerge.coincident(reference)
        self.cells = self.merge.labels[_unfold_cells(cells, count * per_element, self.symmetry)]
        self.coordinates = self.merge.reduce(reference)

    def evaluate(self, coefficient, sector=None) -> np.ndarray:
        """Values of a CoefficientFunction at the sample points, (n_points,) or (n_points, d).

        ``sector``: the symmetry class of a mode field on a quadrant mesh (None:
        even about both planes, like the prestress and the coordinates).  A point
        shared by several elements (or quadrant copies) gets the mean of their values.
        """
        values = np.asarray(coefficient(self.points))
        values = values[:, 0] if values.ndim == 2 and values.shape[1] == 1 else values
        return self.merge.reduce(_unfold_values(values, self.symmetry, sector))


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
    from .symmetry import QUADRANTS
    return QUADRANTS if symmetry.quarter else QUADRANTS[:1]


def _unfold_cells(cells: np.ndarray, n_points: int, symmetry) -> np.ndarray:
    """Cells of every quadrant copy; a copy reflected once has its orientation reversed."""
    copies = []
    for number, (qx, qy) in enumerate(_quadrants(symmetry)):
        copy = cells + number * n_points
        copies.append(copy if qx * qy > 0 else copy[:, [0, 2, 1, *range(3, cells.shape[1])]])
    return np.concatenate(copies)


def _unfold_values(values: np.ndarray, symmetry, sector=None) -> np.ndarray:
    """Quadrant values -> all quadrants: f(q x) = s(q) R_q f(x) (vectors: x, y flipped)."""
    parts = []
    for qx, qy in _quadrants(symmetry):
        sign = 1.0 if sector is None else float(sector.sign(qx, qy))
        if values.ndim == 2 and values.shape[1] == 3:
            parts.append(values * (sign * np.array([qx, qy, 1.0])))
        else:
            parts.append(values * sign)
    return np.concatenate(parts)


def write_membrane_vtu(path: Path, sampler: MembraneSampler, fields: dict,
                       displacement=None) -> Path:
    """VTU of the membrane with point data (meshio): :func:`membrane_mesh` written.

    ``fields`` maps names to CoefficientFunctions or to arrays already sampled;
    ``displacement`` (the prestress u) moves the points to the deformed shape.
    """
    path = path.with_suffix(".vtu")
    write_vtu(path, membrane_mesh(sampler, fields, displacement))
    return path


def write_vtu(path: Path, mesh) -> None:
    """A :class:`meshio.Mesh` (points, one cell block, point and cell data) as a VTU file
    with its arrays appended as raw binary: the XML header, then every array's bytes as
    they lie in memory.  ParaView, VTK (pyvista) and meshio read it; meshio's own writer
    took ~20 ms a file (base64 and per-array XML), this one ~7 ms, mostly the disk
    (97 files of the baffled G1 command: 1.9 s and 0.64 s on a loaded machine)."""
    blocks, header = [], []
    offset = 0

    def array(values, name=None, components=None) -> str:
        nonlocal offset
        values = np.ascontiguousarray(values)
        values = values.astype(values.dtype.newbyteorder("<"), copy=False)
        kind = _VTK_TYPES[values.dtype.str.lstrip("<=|")]
        data = values.tobytes()
        blocks.append(np.uint64(len(data)).tobytes())
        blocks.append(data)
        named = f' Name="{name}"' if name is not None else ""
        count = components if components is not None else (
            values.shape[1] if values.ndim == 2 else None)
        counted = f' NumberOfComponents="{count}"' if count is not None else ""
        tag = (f'<DataArray type="{kind}"{named}{counted} format="appended" '
               f'offset="{offset}"/>')
        offset += 8 + len(data)
        return tag

    (kind, cells), = [(block.type, block.data) for block in mesh.cells]
    cells = np.asarray(cells)
    if kind in _VTK_ORDER:          # meshio's node order -> VTK's (as meshio.write does)
        cells = cells[:, _VTK_ORDER[kind]]
    # 32-bit connectivity where it fits: the air's wedges are most of a file's bytes
    cells = cells.astype(np.int32 if cells.size < 2**31 - 1 and len(mesh.points) < 2**31 - 1
                         else np.int64, copy=False)
    points = np.asarray(mesh.points)
    n_points, (n_cells, corners) = len(points), cells.shape
    header.append(f'<Points>{array(points, components=3)}</Points>')
    header.append('<Cells>'
                  + array(cells.ravel(), "connectivity")
                  + array(np.arange(1, n_cells + 1, dtype=cells.dtype) * corners, "offsets")
                  + array(np.full(n_cells, _VTK_CELLS[kind], dtype=np.uint8), "types")
                  + '</Cells>')
    header.append("<PointData>" + "".join(array(values, name)
                                           for name, values in mesh.point_data.items())
                  + "</PointData>")
    header.append("<CellData>" + "".join(array(values[0], name)
                                          for name, values in mesh.cell_data.items())
                  + "</CellData>")
    text = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
            'byte_order="LittleEndian" header_type="UInt64">\n<UnstructuredGrid>\n'
            f'<Piece NumberOfPoints="{n_points}" NumberOfCells="{n_cells}">\n'
            + "\n".join(header) + '\n</Piece>\n</UnstructuredGrid>\n'
            '<AppendedData encoding="raw">\n_')
    with open(path, "wb") as handle:
        handle.write(text.encode())
        for block in blocks:
            handle.write(block)
        handle.write(b"\n</AppendedData>\n</VTKFile>\n")


#: numpy dtype (without byte order) -> VTK's DataArray type; VTK cell type numbers.
_VTK_TYPES = {"f8": "Float64", "f4": "Float32", "i8": "Int64", "i4": "Int32", "i2": "Int16",
              "i1": "Int8", "u8": "UInt64", "u4": "UInt32", "u2": "UInt16", "u1": "UInt8"}
_VTK_CELLS = {"triangle": 5, "tetra": 10, "wedge": 13}
#: meshio orders a wedge's corners as gmsh does, VTK with the first face turned over
_VTK_ORDER = {"wedge": [0, 2, 1, 3, 5, 4]}


def membrane_mesh(sampler, fields: dict, displacement=None):
    """The :class:`meshio.Mesh` of :func:`write_membrane_vtu` (triangles, point data)."""
    import meshio

    coordinates = sampler.coordinates
    if isinstance(displacement, np.ndarray):
        coordinates = coordinates + displacement
    elif displacement is not None:
        coordinates = coordinates + sampler.evaluate(displacement)
    data = {name: value if isinstance(value, np.ndarray) else sampler.evaluate(value)
            for name, value in fields.items()}
    return meshio.Mesh(coordinates, [("triangle", sampler.cells)], point_data=data)


def write_pvd(path: Path, files: list[Path], times: list[float]) -> None:
    """A ParaView collection; 'time' is the mode index so ParaView steps through modes."""
    entries = "\n".join(f'    <DataSet timestep="{t:g}" group="" part="0" file="{f.name}"/>'
                        for f, t in zip(files, times))
    path.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                    f"  <Collection>\n{entries}\n  </Collection>\n</VTKFile>\n")


def write_mode_vtus(directory: Path, state, modes, sampler: MembraneSampler) -> list[Path]:
    """One .vtu per mode on the prestressed shape: displacement re/im/abs, normal velocity.

    Mode shapes are normalised to peak |u| = 1 (dimensionless); the normal
    velocity amplitude is omega |u.n| for that normalisation [1/s].
    """
    return _write_all(directory, mode_meshes(state, modes, sampler))


def _write_all(directory: Path, meshes, kept: dict | None = None) -> list[Path]:
    """``(name, meshio.Mesh)`` pairs as ``directory/name.vtu``; the paths in order
    (``kept``: ``{position: None}``, receives the meshes at those positions)."""
    files = []
    for number, (name, mesh) in enumerate(meshes):
        path = directory / f"{name}.vtu"
        write_vtu(path, mesh)
        files.append(path)
        if kept is not None and number in kept:
            kept[number] = mesh
    return files


def mode_meshes(state, modes, sampler: MembraneSampler):
    """``(file stem, meshio.Mesh)`` of each mode of :func:`write_mode_vtus`, one at a time."""
    import ngsolve as ngs

    from .membrane import deformed_normal

    mode_field = ngs.GridFunction(state.space)
    normal = sampler.evaluate(deformed_normal(state.displacement))
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
        yield (f"mode_{number:03d}_{_safe(mode.label)}",
               membrane_mesh(sampler, fields, displacement=state.displacement))


class _AirHalves:
    """The air's element corners with the lower half on its own copy of the mesh vertices
    (the pressure jumps across the screens; values are taken inside each element), on the
    mesh moved by ``mesh_motion``; 3-D tetrahedra or meridian triangles (the dimension of
    ``mesh``).  ``copy[e, k]``: the (doubled) vertex of corner k of element e; ``moved``:
    the moved coordinates of every doubled vertex; ``used``/``renumber``: the vertices a
    cell uses and their new numbers.  ``split``: per mesh vertex, whether its lower copy is
    its own point (where the pressure jumps: :func:`_jump_vertices`); None: every lower
    vertex (the open plane then carries two coincident copies of one pressure)."""

    def __init__(self, mesh, points, mesh_motion, split=None):
        import ngsolve as ngs

        from .acoustics import LOWER, PML_REGIONS
        dim = mesh.dim
        elements = list(mesh.Elements(ngs.VOL))
        self.lower = np.array([mesh.Materials(LOWER).Mask()[el.index] for el in elements])
        self.in_pml = np.array([mesh.Materials(PML_REGIONS).Mask()[el.index]
                                for el in elements])
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
        second = self.lower[:, None] if split is None else \
            self.lower[:, None] & np.asarray(split, dtype=bool)[corner_vertex]
        self.copy = np.where(second, count, 0) + corner_vertex      # lower: 2nd copy
        motion = np.asarray(mesh_motion(points)).reshape(len(elements), corners, dim)
        self.moved = np.zeros((2 * count, dim))
        self.moved[self.copy.ravel()] = (reference + motion).reshape(-1, dim)
        self.reference = np.zeros((2 * count, dim))
        self.reference[self.copy.ravel()] = reference.reshape(-1, dim)
        self.used = np.unique(self.copy)
        self.renumber = -np.ones(2 * count, dtype=int)
        self.renumber[self.used] = np.arange(len(self.used))


def _jump_vertices(pressure_space, vertices: int):
    """Per mesh vertex: whether the pressure jump ``q`` of :func:`acoustics.pressure_space`
    has a free DOF there (a screen vertex; the lower half needs its own copy); None when
    the space has no jump component (every lower vertex is then split)."""
    try:
        active = pressure_space.components[1].GetActiveDofs()
    except (AttributeError, IndexError):
        return None
    # H1 numbers the vertex DOFs first, one per mesh vertex
    return np.array([active[k] for k in range(vertices)], dtype=bool)


def write_air_vtus(directory: Path, operators, modes, pressures) -> list[Path]:
    """One .vtu per mode of the air (:func:`air_meshes`), ``air_NNN_<label>.vtu``."""
    return _write_all(directory, air_meshes(operators, modes, pressures))


def air_meshes(operators, modes, pressures):
    """``(file stem, meshio.Mesh)`` per mode of the air on the deformed mesh: pressure
    re/im/abs, PML flag.

    ``operators``: the :class:`copdea_fem.coupled.CoupledOperators` of each
    sector (one on a whole mesh); a mode's pressure vector is read with its
    sector's.  The pressure jumps across the screens, so the upper and lower
    halves get their own copies of the mesh vertices; values are taken inside
    each element (no ambiguity at the plane); elsewhere, on the open plane too, a vertex
    is written once.  A quadrant mesh is unfolded into the whole air, the copies of the
    mirror planes' vertices merged (:class:`PointMerge`; they agree by parity).  Pressures are per unit peak membrane displacement
    [Pa/m], like the membrane files.
    """
    import meshio
    import ngsolve as ngs

    from .acoustics import pressure_field
    from .symmetry import Symmetry

    by_sector = {coupled.membrane.sector: coupled for coupled in operators}
    first = operators[0]
    space = first.pressure_space
    mesh = space.mesh
    symmetry = Symmetry.of_mesh(mesh)
    gf = ngs.GridFunction(space)
    field = pressure_field(gf.components[0], gf.components[1], mesh)
    corners = ngs.IntegrationRule([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], [0.0] * 4)
    points = mesh.MapToAllElements(corners, ngs.VOL)
    halves = _AirHalves(mesh, points, first.mesh_motion,
                        split=_jump_vertices(space, len(mesh.ngmesh.Coordinates())))
    lower, in_pml, copy, used, count = (halves.lower, halves.in_pml, halves.copy, halves.used,
                                        halves.count)
    moved = _unfold_values(halves.moved[used], symmetry)
    # the copies of the mirror planes' vertices merged (the two sides of a screen kept apart);
    # found on the reference mesh (the ALE motion leaves ~1e-8 m normal to the planes there),
    # so the merged point, the mean of the mirror images, lies exactly on the plane
    merge = PointMerge.coincident(_unfold_values(halves.reference[used], symmetry),
                                  groups=np.tile(used >= count, symmetry.copies))
    cells = merge.labels[_unfold_cells(halves.renumber[copy], len(used), symmetry)]
    moved = merge.reduce(moved).astype(np.float32)
    cell_data = {"pml": [np.tile(in_pml.astype(np.int8), symmetry.copies)],
                 "lower_half": [np.tile(lower.astype(np.int8), symmetry.copies)]}
    for number, (mode, pressure) in enumerate(zip(modes, pressures)):
        gf.vec.FV().NumPy()[:] = 0
        gf.vec.FV().NumPy()[by_sector[mode.sector].pressure_free] = pressure
        values = np.asarray(field(points))
        nodal = np.zeros(2 * count, dtype=complex)
        nodal[copy.ravel()] = values.ravel()
        nodal = merge.reduce(_unfold_values(nodal[used], symmetry, mode.sector))
        data = {"pressure_real": nodal.real.astype(np.float32),
                "pressure_imag": nodal.imag.astype(np.float32),
                "pressure_abs": np.abs(nodal).astype(np.float32)}
        yield (f"air_{number:03d}_{_safe(mode.label)}",
               meshio.Mesh(moved, [("tetra", cells)], point_data=data, cell_data=cell_data))


# -- ParaView, axisymmetric engine: meridian fields revolved to 3-D --------------------
def revolution_angles(max_order: int, minimum: int = 72, per_wave: int = 8) -> np.ndarray:
    """Polar angles [rad] of a revolved output: ``minimum``, or ``per_wave`` per wavelength of
    the highest order."""
    count = max(minimum, per_wave * int(max_order))
    return 2 * np.pi * np.arange(count) / count


def _harmonics(m: int, family: str, angles):
    """(radial/axial factor, hoop factor) of an order-m field: cos/sin family (axisymmetric.modes)."""
    if family == "cos":
        return np.cos(m * angles), np.sin(m * angles)
    return np.sin(m * angles), -np.cos(m * angles)


class RevolvedMembraneSampler:
    """The membrane surface of an axisymmetric result, revolved: points, triangles, fields.

    Radii are the exact sample points of :class:`copdea_fem.axisymmetric.meridian.LineSampler`
    (shared element ends merged); a field of order m is ``f(r) cos m theta`` (or the
    sin family's turned copy) on every ring of points.
    """

    def __init__(self, state, max_order: int = 0):
        self.state = state
        self.line = state.line()
        radii = self.line.radii.ravel()
        self.radii, self._unique = np.unique(np.round(radii, 12), return_index=True)
        self.angles = revolution_angles(max_order)
        rr, tt = np.meshgrid(self.radii, self.angles, indexing="ij")
        self._cos, self._sin = np.cos(tt).ravel(), np.sin(tt).ravel()
        self._rings = rr.ravel()
        self.coordinates = np.column_stack([rr.ravel() * self._cos, rr.ravel() * self._sin,
                                            np.zeros(rr.size)])
        n_r, n_t = len(self.radii), len(self.angles)
        index = np.arange(n_r * n_t).reshape(n_r, n_t)
        nxt = np.roll(index, -1, axis=1)
        lower, upper = index[:-1], index[1:]
        lower_next, upper_next = nxt[:-1], nxt[1:]
        cells = np.concatenate([
            np.stack([lower, upper, upper_next], axis=-1).reshape(-1, 3),
            np.stack([lower, upper_next, lower_next], axis=-1).reshape(-1, 3)])
        # a ring at r = 0 (a membrane without a disc) is one point
        component = index.copy()
        component[self.radii <= 1e-12 * max(self.radii.max(), 1e-300)] = index[0, 0]
        self.merge = PointMerge.from_components(component.ravel())
        keep = self.merge.labels[cells]
        self.cells = keep[(keep[:, 0] != keep[:, 1]) & (keep[:, 1] != keep[:, 2])
                          & (keep[:, 0] != keep[:, 2])]
        self.coordinates = self.merge.reduce(self.coordinates)

    def profile(self, coefficient) -> np.ndarray:
        """Values of a CoefficientFunction at the sample radii: (n_r,) or (n_r, d)."""
        values = self.line.values(coefficient)
        values = values.reshape(-1, *values.shape[2:])
        return values[self._unique]

    def ring(self, values, factor) -> np.ndarray:
        """Radial values (n_r[, d]) times an angular factor (n_t,) -> the written points."""
        return self.merge.reduce(self._ring(values, factor))

    def _ring(self, values, factor) -> np.ndarray:
        """Radial values (n_r[, d]) times an angular factor (n_t,) -> (n_r n_t[, d])."""
        values = np.asarray(values)
        out = values[:, None] * factor[None, :] if values.ndim == 1 else \
            values[:, None, :] * factor[None, :, None]
        return out.reshape(-1, *values.shape[1:])

    def vector(self, radial, hoop, axial, m=0, family="cos") -> np.ndarray:
        """Cartesian vectors (n, 3) of (u_r, u_theta, u_z) amplitudes of an order-m field."""
        main, cross = _harmonics(m, family, self.angles)
        u_r, u_t, u_z = (self._ring(radial, main), self._ring(hoop, cross),
                         self._ring(axial, main))
        return self.merge.reduce(np.column_stack([u_r * self._cos - u_t * self._sin,
                                                  u_r * self._sin + u_t * self._cos, u_z]))

    def prestress_displacement(self) -> np.ndarray:
        u = self.profile(self.state.displacement)
        return self.vector(u[:, 0], np.zeros(len(u)), u[:, 1])

    def prestress_fields(self) -> dict:
        fields = self.state.fields()
        data = {}
        for name, value in fields.items():
            values = self.profile(value)
            if name in ("displacement", "normal"):
                data[name] = self.vector(values[:, 0], np.zeros(len(values)), values[:, 1])
            else:
                data[name] = self.ring(values, np.ones(len(self.angles)))
        return data


def write_revolved_mode_vtus(directory: Path, state, modes, sampler=None) -> list[Path]:
    """One .vtu per mode of the axisymmetric engine, revolved; fields as write_mode_vtus."""
    return _write_all(directory, revolved_mode_meshes(state, modes, sampler))


def revolved_sampler(state, modes, sampler=None) -> RevolvedMembraneSampler:
    """``sampler`` if its angles resolve the highest order of ``modes``, else a finer one."""
    highest = max([mode.m for mode in modes], default=0)
    if sampler is None or len(sampler.angles) < len(revolution_angles(highest)):
        sampler = RevolvedMembraneSampler(state, highest)
    return sampler


def revolved_mode_meshes(state, modes, sampler=None):
    """``(file stem, meshio.Mesh)`` of each mode of :func:`write_revolved_mode_vtus`;
    ``sampler`` as the writer would choose it for ``modes`` (:func:`revolved_sampler`)."""
    import ngsolve as ngs

    sampler = revolved_sampler(state, modes, sampler)
    displacement = sampler.prestress_displacement()
    normal_profile = sampler.profile(state.fields()["normal"])
    for number, mode in enumerate(modes):
        operators = mode.operators
        gf = ngs.GridFunction(operators.space)
        parts = []
        for part in (np.real(mode.vector), np.imag(mode.vector)):
            gf.vec.FV().NumPy()[:] = part
            parts.append(np.stack([sampler.profile(cf) for cf in operators.amplitudes(gf)], 1))
        amplitude = parts[0] + 1j * parts[1]                         # (n_r, 3): a, b, c
        shape = [sampler.vector(amplitude[:, 0].real, amplitude[:, 1].real,
                                amplitude[:, 2].real, mode.m, mode.family),
                 sampler.vector(amplitude[:, 0].imag, amplitude[:, 1].imag,
                                amplitude[:, 2].imag, mode.m, mode.family)]
        normal = amplitude[:, 0] * normal_profile[:, 0] + amplitude[:, 2] * normal_profile[:, 1]
        main, _ = _harmonics(mode.m, mode.family, sampler.angles)
        normal_shape = sampler.ring(normal, main)
        omega = 2 * np.pi * abs(complex(mode.freq_hz, mode.freq_im_hz))
        fields = {"displacement_real": shape[0], "displacement_imag": shape[1],
                  "displacement_abs": np.linalg.norm(np.abs(shape[0] + 1j * shape[1]), axis=1),
                  "normal_displacement_real": normal_shape.real,
                  "normal_displacement_imag": normal_shape.imag,
                  "normal_velocity_abs": omega * np.abs(normal_shape)}
        yield (f"mode_{number:03d}_{_safe(mode.label)}",
               membrane_mesh(sampler, fields, displacement=displacement))


def write_revolved_air_vtus(directory: Path, operators, modes, pressures) -> list[Path]:
    """One .vtu per mode of the revolved air (:func:`revolved_air_meshes`)."""
    return _write_all(directory, revolved_air_meshes(operators, modes, pressures))


def revolved_air_meshes(operators, modes, pressures, max_order: int | None = None):
    """``(file stem, meshio.Mesh)`` of each mode of the air of the axisymmetric engine,
    revolved (wedge cells); ``max_order``: the highest order of the modes written together
    (sets the angles; default: that of ``modes``).

    The meridian's vertices are revolved on the deformed meridian; as in
    :func:`write_air_vtus` the lower half gets its own copy of the vertices (the
    pressure jumps across the screens) and values are taken inside each element.
    Fields and cell data as there; a field of order m is ``p(r, z) cos m theta``
    (or the sin family's turned copy).
    """
    import meshio
    import ngsolve as ngs

    from .acoustics import pressure_field

    by_order = {coupled.m: coupled for coupled in operators}
    mesh = operators[0].pressure_space.mesh
    corners = ngs.IntegrationRule([(1, 0), (0, 1), (0, 0)], [0.0] * 3)
    points = mesh.MapToAllElements(corners, ngs.VOL)
    halves = _AirHalves(mesh, points, operators[0].mesh_motion,
                        split=_jump_vertices(operators[0].pressure_space,
                                             len(mesh.ngmesh.Coordinates())))
    lower, in_pml, copy, used, count = (halves.lower, halves.in_pml, halves.copy, halves.used,
                                        halves.count)
    moved = halves.moved
    triangles = halves.renumber[copy]
    # the air of every mode is a large file: 36 angles, or 4 per wavelength
    if max_order is None:
        max_order = max([mode.m for mode in modes], default=0)
    angles = revolution_angles(max_order, 36, 4)
    n_t = len(angles)
    r, z = moved[used, 0], moved[used, 1]
    # a vertex on the axis (reference r = 0) is one point, not one per angle
    component = np.arange(len(used) * n_t).reshape(len(used), n_t)
    reference_r = np.abs(halves.reference[used, 0])
    on_axis = reference_r <= 1e-9 * reference_r.max()
    component[on_axis] = component[on_axis, :1]
    merge = PointMerge.from_components(component.ravel())
    xyz = merge.reduce(np.column_stack([(r[:, None] * np.cos(angles)).ravel(),
                                        (r[:, None] * np.sin(angles)).ravel(),
                                        np.repeat(z, n_t)])).astype(np.float32)
    step = np.arange(n_t)
    ring = triangles[:, :, None] * n_t                              # (el, 3, 1)
    cells = np.concatenate([ring + step, ring + (step + 1) % n_t], axis=1)   # (el, 6, n_t)
    # a wedge with a corner on the axis keeps its two (now equal) corner numbers: ParaView
    # reads it as the collapsed wedge it is
    cells = merge.labels[np.moveaxis(cells, 2, 1).reshape(-1, 6)]
    cell_data = {"pml": [np.repeat(in_pml.astype(np.int8), n_t)],
                 "lower_half": [np.repeat(lower.astype(np.int8), n_t)]}
    for number, (mode, pressure) in enumerate(zip(modes, pressures)):
        coupled = by_order[mode.m]
        gf = ngs.GridFunction(coupled.pressure_space)
        gf.vec.FV().NumPy()[coupled.pressure_free] = pressure
        values = np.asarray(pressure_field(gf.components[0], gf.components[1], mesh)(points))
        nodal = np.zeros(2 * count, dtype=complex)
        nodal[copy.ravel()] = values.ravel()
        main, _ = _harmonics(mode.m, mode.family, angles)
        field = merge.reduce((nodal[used][:, None] * main[None, :]).ravel())
        data = {"pressure_real": field.real.astype(np.float32),
                "pressure_imag": field.imag.astype(np.float32),
                "pressure_abs": np.abs(field).astype(np.float32)}
        yield (f"air_{number:03d}_{_safe(mode.label)}",
               meshio.Mesh(xyz, [("wedge", cells)], point_data=data, cell_data=cell_data))


def _safe(label: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in label).strip("_")


# -- plots --------------------------------------------------------------------------
def plot_modes(path: Path, vtu_files: list, modes, columns: int = 4) -> None:
    """PNG of the lowest structural modes seen from above, coloured by the normal
    displacement (red up, blue down, each mode on its own symmetric scale; matplotlib).

    ``vtu_files``: the modes' VTU files, or their :class:`meshio.Mesh` objects (as written,
    not read back).  Nodal diameters and circles show as the pale lines.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.tri import Triangulation

    count = len(vtu_files)
    if count == 0:
        return
    width, rows = min(columns, count), (count + columns - 1) // columns
    figure = Figure(figsize=(3.0 * width, 3.0 * rows), dpi=100)
    FigureCanvasAgg(figure)
    for k, (item, mode) in enumerate(zip(vtu_files, modes)):
        mesh = item if hasattr(item, "points") else _read_vtu(item)
        points, triangles = np.asarray(mesh.points), np.asarray(mesh.cells[0].data)
        values = np.asarray(mesh.point_data["normal_displacement_real"], dtype=float)
        limit = float(np.abs(values).max()) or 1.0
        axis = figure.add_subplot(rows, width, k + 1)
        axis.tripcolor(Triangulation(points[:, 0], points[:, 1], triangles), values,
                       cmap="coolwarm", vmin=-limit, vmax=limit, shading="gouraud")
        axis.set_aspect("equal")
        axis.set_axis_off()
        axis.set_title(f"{mode.label}  {mode.freq_hz:.1f} Hz", fontsize=10)
    figure.subplots_adjust(left=0.01, right=0.99, bottom=0.01, top=1 - 0.3 / (3.0 * rows),
                           wspace=0.02, hspace=0.12)
    figure.savefig(path)


def _read_vtu(path):
    import meshio
    return meshio.read(path)


def _headless_vtk() -> None:
    """Without a display (Linux, no DISPLAY/WAYLAND_DISPLAY) render through EGL.

    VTK's default X window would first fail with a "bad X server connection"
    warning and then fall back to EGL anyway; asking for EGL directly skips
    the warning.  A VTK_DEFAULT_OPENGL_WINDOW set by the user is kept.
    """
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def plot_force_displacement(path: Path, z_values, voltages, forces) -> None:
    """PNG of F(z) at each voltage (Fig. 4b style)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(5, 4))
    for voltage, force in zip(voltages, forces):
        axis.plot(np.asarray(z_values) * 1e3, force, marker="o", ms=3,
                  label=f"V = {voltage / 1e3:g} kV")
    axis.set_xlabel("disc displacement z [mm]")
    axis.set_ylabel("axial force F [N]")
    axis.grid(alpha=0.3)
    axis.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def write_force_csv(path: Path, z_values, voltages, forces) -> None:
    """Long table voltage_v, z_m, force_n."""
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["voltage_v", "z_m", "force_n"])
        for voltage, row in zip(voltages, forces):
            for z, force in zip(z_values, row):
                writer.writerow([f"{voltage:.10g}", f"{z:.10g}", f"{force:.10g}"])


def write_json(path: Path, document: dict) -> None:
    path.write_text(json.dumps(document, indent=1, default=_json))
