"""The VTU writer (raw appended binary arrays), ParaView collections (.pvd), file names.

We own this writer rather than write through meshio: the files are raw appended binary
arrays, shared arrays of a series encoded once (:class:`VtuWriter`), and meshio's import
and base64 encoding would slow every command that writes files (docs/benchmarks.md).
The tests read every kind of file back with meshio and pyvista, which we did not write.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

#: VTU files are written binary, uncompressed (:func:`write_vtu`): zlib took about half of
#: the output time of a coupled solve (G1 default mesh, 48 modes) for files 2-3x smaller.
VTU_COMPRESSION = None


class CellBlock(NamedTuple):
    """One block of cells of one type (``type``: a meshio cell type name, ``data``)."""

    type: str
    data: np.ndarray


class VtuMesh:
    """What one VTU file holds: points (n, 3), one block of cells, point and cell data,
    laid out as a meshio mesh (``points``, ``cells[0].type``/``.data``, ``point_data``,
    ``cell_data`` as lists per block); :meth:`to_pyvista` gives the grid the file holds."""

    def __init__(self, points, cells, point_data=None, cell_data=None, field_data=None):
        self.points = np.asarray(points)
        self.cells = [CellBlock(kind, np.asarray(data)) for kind, data in cells]
        self.point_data = dict(point_data or {})
        self.cell_data = dict(cell_data or {})
        #: numbers of the whole mesh (VTK FieldData: ParaView's "Field Data"), name -> 1-D
        self.field_data = {name: np.atleast_1d(np.asarray(values, float))
                           for name, values in (field_data or {}).items()}

    def to_pyvista(self):
        """The same mesh as a :class:`pyvista.UnstructuredGrid` (cells in VTK's node order)."""
        import pyvista as pv

        grid = pv.UnstructuredGrid({_VTK_CELLS[block.type]: _vtk_order(block)
                                    for block in self.cells}, np.asarray(self.points, float))
        for name, values in self.point_data.items():
            grid.point_data[name] = np.asarray(values)
        for name, blocks in self.cell_data.items():
            grid.cell_data[name] = np.concatenate([np.asarray(block) for block in blocks])
        for name, values in self.field_data.items():
            grid.field_data[name] = values
        return grid


def _vtk_order(block: CellBlock) -> np.ndarray:
    """A block's connectivity in VTK's node order (meshio's order -> VTK's)."""
    cells = np.asarray(block.data)
    return cells[:, _VTK_ORDER[block.type]] if block.type in _VTK_ORDER else cells


def write_membrane_vtu(path: Path, sampler, fields: dict,
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
    takes about three times as long a file (base64 and per-array XML), while this one's
    time is mostly the disk.  (:class:`VtuWriter` for many files that share their
    geometry.)"""
    VtuWriter().write(path, mesh)


class VtuWriter:
    """:func:`write_vtu` for a series of files: an array that the next mesh holds again
    (the same ndarray object: the points, cells and cell data of every mode of one domain,
    which the field samplers build once per series) is converted to its written bytes
    once, and the files stay byte for byte those of :func:`write_vtu`.

    Only the arrays of the last mesh written are remembered (each with a reference, so
    that an identity match is that array): the arrays must not change in place until
    their file is written.  The per-mode arrays go to the file as they lie in memory,
    without a copy.

    Used as a context manager (``with VtuWriter() as writer``), the files are written by
    one background thread while the caller builds the next mesh (the system call copying
    the bytes releases the GIL): every file is complete when the block ends, and the first
    error of a write is raised there.  That saves wall time, not CPU time.
    """

    def __init__(self):
        self._encoded: dict = {}        # id(array) -> (array, (VTK type, components), data)
        self._pool = None
        self._pending: list = []

    def __enter__(self) -> "VtuWriter":
        from concurrent.futures import ThreadPoolExecutor

        self._pool = ThreadPoolExecutor(1, thread_name_prefix="vtu-writer")
        return self

    def __exit__(self, kind, error, traceback) -> None:
        pool, pending, self._pool, self._pending = self._pool, self._pending, None, []
        pool.shutdown(wait=True)
        if kind is None:                # else the caller's own error goes on
            for job in pending:
                job.result()            # the first write that failed raises here

    def _encode(self, values, remembered: dict):
        """``(VTK type, components, data)`` of an array, little endian and C-contiguous
        (``data``: the array itself or a converted copy, written through the buffer
        protocol); remembered for the next file."""
        hit = self._encoded.get(id(values))
        if hit is not None and hit[0] is values:
            remembered[id(values)] = hit
            return hit[1]
        data = np.ascontiguousarray(values)
        data = data.astype(data.dtype.newbyteorder("<"), copy=False)
        count = data.shape[1] if data.ndim == 2 else None
        encoded = (_VTK_TYPES[data.dtype.str.lstrip("<=|")], count,
                   data.reshape(-1).view(np.uint8))
        remembered[id(values)] = (values, encoded)
        return encoded

    def _cells(self, block, n_points: int, remembered: dict):
        """``(number of cells, encoded connectivity, offsets, types)`` of one cell block:
        VTK's node order, 32-bit numbers where they fit (the air's wedges are most of a
        file's bytes)."""
        key = ("cells", id(block.data), n_points)
        hit = self._encoded.get(key)
        if hit is not None and hit[0] is block.data:
            remembered[key] = hit
            return hit[1]
        kind, cells = block.type, np.asarray(block.data)
        if kind in _VTK_ORDER:      # meshio's node order -> VTK's (as meshio.write does)
            cells = cells[:, _VTK_ORDER[kind]]
        cells = cells.astype(np.int32 if cells.size < 2**31 - 1 and n_points < 2**31 - 1
                             else np.int64, copy=False)
        n_cells, corners = cells.shape
        arrays = (cells.ravel(), np.arange(1, n_cells + 1, dtype=cells.dtype) * corners,
                  np.full(n_cells, _VTK_CELLS[kind], dtype=np.uint8))
        encoded = (n_cells, [self._encode(values, {}) for values in arrays])
        remembered[key] = (block.data, encoded)
        return encoded

    def write(self, path: Path, mesh) -> None:
        """``mesh`` (:class:`VtuMesh` or :class:`meshio.Mesh`: points, one cell block,
        point and cell data) as the VTU file ``path``, as :func:`write_vtu` writes it."""
        remembered: dict = {}
        header, blocks = [], []
        offset = 0

        def array(encoded, name=None, components=None) -> str:
            nonlocal offset
            kind, count, data = encoded
            count = components if components is not None else count
            blocks.append(np.uint64(data.nbytes).tobytes())
            blocks.append(data)
            named = f' Name="{name}"' if name is not None else ""
            counted = f' NumberOfComponents="{count}"' if count is not None else ""
            tag = (f'<DataArray type="{kind}"{named}{counted} format="appended" '
                   f'offset="{offset}"/>')
            offset += 8 + data.nbytes
            return tag

        block, = mesh.cells
        n_points = len(mesh.points)
        n_cells, (connectivity, offsets, types) = self._cells(block, n_points, remembered)
        header.append(f'<Points>{array(self._encode(mesh.points, remembered), components=3)}'
                      '</Points>')
        header.append('<Cells>' + array(connectivity, "connectivity")
                      + array(offsets, "offsets") + array(types, "types") + '</Cells>')
        header.append("<PointData>" + "".join(array(self._encode(values, remembered), name)
                                               for name, values in mesh.point_data.items())
                      + "</PointData>")
        header.append("<CellData>" + "".join(array(self._encode(values[0], remembered), name)
                                              for name, values in mesh.cell_data.items())
                      + "</CellData>")
        field = ""
        if getattr(mesh, "field_data", None):
            tags = []
            for name, values in mesh.field_data.items():
                values = np.atleast_1d(np.asarray(values, float)).ravel()
                tags.append(array(self._encode(values, remembered), name).replace(
                    "<DataArray ", f'<DataArray NumberOfTuples="{values.size}" ', 1))
            field = "<FieldData>" + "".join(tags) + "</FieldData>\n"
        self._encoded = remembered
        text = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
                'byte_order="LittleEndian" header_type="UInt64">\n<UnstructuredGrid>\n'
                + field + f'<Piece NumberOfPoints="{n_points}" NumberOfCells="{n_cells}">\n'
                + "\n".join(header) + '\n</Piece>\n</UnstructuredGrid>\n'
                '<AppendedData encoding="raw">\n_')
        buffers = [text.encode(), *blocks, b"\n</AppendedData>\n</VTKFile>\n"]
        if self._pool is None:
            _write_buffers(path, buffers)
        else:
            self._pending.append(self._pool.submit(_write_buffers, path, buffers))


def _write_buffers(path: Path, buffers: list) -> None:
    """The file ``path`` holding ``buffers`` (bytes-like) one after another, written by one
    gathering system call where the system has one (``os.writev``; the rest, if it wrote
    less, by plain writes): a VTU file's ~20 arrays cost one call, not ~20."""
    with open(path, "wb", buffering=0) as handle:
        if not hasattr(os, "writev"):
            for data in buffers:
                handle.write(data)
            return
        views = [memoryview(data).cast("B") for data in buffers]
        written = os.writev(handle.fileno(), views)
        for view in views:
            if written >= view.nbytes:
                written -= view.nbytes
                continue
            rest = view[written:]
            while rest.nbytes:
                rest = rest[handle.write(rest):]
            written = 0


#: numpy dtype (without byte order) -> VTK's DataArray type; VTK cell type numbers.
_VTK_TYPES = {"f8": "Float64", "f4": "Float32", "i8": "Int64", "i4": "Int32", "i2": "Int16",
              "i1": "Int8", "u8": "UInt64", "u4": "UInt32", "u2": "UInt16", "u1": "UInt8"}
_VTK_CELLS = {"vertex": 1, "line": 3, "triangle": 5, "tetra": 10, "wedge": 13}
#: meshio orders a wedge's corners as gmsh does, VTK with the first face turned over
_VTK_ORDER = {"wedge": [0, 2, 1, 3, 5, 4]}


def membrane_mesh(sampler, fields: dict, displacement=None):
    """The :class:`VtuMesh` of :func:`write_membrane_vtu` (triangles, point data)."""
    coordinates = sampler.coordinates
    if isinstance(displacement, np.ndarray):
        coordinates = coordinates + displacement
    elif displacement is not None:
        coordinates = coordinates + sampler.evaluate(displacement)
    data = {name: value if isinstance(value, np.ndarray) else sampler.evaluate(value)
            for name, value in fields.items()}
    return VtuMesh(coordinates, [("triangle", sampler.cells)], point_data=data)


def split_cells(mesh: VtuMesh, flag: str) -> tuple[VtuMesh, VtuMesh]:
    """``mesh`` as two meshes: the cells whose cell data ``flag`` is 0, and those where it is
    not (one cell block; points renumbered to those each part uses; ``flag`` dropped).  An
    enclosure's air as its own ParaView block (:func:`write_pvd`'s ``parts``)."""
    (block,) = mesh.cells
    chosen = np.asarray(mesh.cell_data[flag][0]) != 0
    parts = []
    for take in (~chosen, chosen):
        cells = block.data[take]
        used, renumbered = np.unique(cells, return_inverse=True)
        parts.append(VtuMesh(mesh.points[used], [(block.type, renumbered.reshape(cells.shape))],
                             point_data={name: np.asarray(values)[used]
                                         for name, values in mesh.point_data.items()},
                             cell_data={name: [np.asarray(values[0])[take]]
                                        for name, values in mesh.cell_data.items()
                                        if name != flag}))
    return parts[0], parts[1]


def write_pvd(path: Path, files: list[Path], times: list[float],
              parts: list[int] | None = None) -> None:
    """A ParaView collection; 'time' is the mode index so ParaView steps through modes;
    ``parts``: the block of each file (default 0: one block), which ParaView shows as a
    multiblock data set (e.g. the outside air and an enclosure's air)."""
    parts = [0] * len(files) if parts is None else parts
    entries = "\n".join(f'    <DataSet timestep="{t:g}" group="" part="{part:d}" '
                        f'file="{f.name}"/>' for f, t, part in zip(files, times, parts))
    path.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                    f"  <Collection>\n{entries}\n  </Collection>\n</VTKFile>\n")


def write_all(directory: Path, meshes, kept: dict | None = None) -> list[Path]:
    """``(name, VtuMesh)`` pairs as ``directory/name.vtu``; the paths in order
    (``kept``: ``{position: None}``, receives the meshes at those positions)."""
    files = []
    with VtuWriter() as writer:             # written in the background, complete on return
        for number, (name, mesh) in enumerate(meshes):
            path = directory / f"{name}.vtu"
            writer.write(path, mesh)
            files.append(path)
            if kept is not None and number in kept:
                kept[number] = mesh
    return files


def safe_name(label: str) -> str:
    """A mode label as a file name part: ``(1,1)a`` -> ``1_1_a``."""
    return "".join(ch if ch.isalnum() else "_" for ch in label).strip("_")


def pressure_point_data(field) -> dict:
    """The air files' point arrays of a complex pressure field [Pa]: real, imaginary part
    and modulus (float32), named as ParaView users know them."""
    return {"pressure_real": field.real.astype(np.float32),
            "pressure_imag": field.imag.astype(np.float32),
            "pressure_abs": np.abs(field).astype(np.float32)}
