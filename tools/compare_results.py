"""Two result folders of ``copdea-fem solve`` compared as a user's tools read them.

A tool, not a CI gate (pytest does not collect this file: its name does not start with
``test_``).  For a change of the writers that must not change what is written (issue 25:
the result files of a small solve made cheap to write): every ``.vtu`` read with meshio
and with pyvista (VTK, what ParaView uses) -- points, cells, every point and cell array,
the same names, shapes, types and values; the ``.pvd`` collections, ``modes.csv`` and
``study.resolved.yaml`` byte for byte; ``modes.json`` but its timings, the folder's
manifest but its time stamp; the PNG pictures pixel for pixel (Pillow).  Values must be
equal to the bit, or within ``--rtol`` of the array's largest modulus where asked (a
vectorised computation that reorders a sum).

Run from the repository root::

    python tools/compare_results.py OLD_FOLDER NEW_FOLDER [--rtol 1e-12]

Prints one line per difference and a summary; exit status 0 when the folders agree, 1
when they do not.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from copdea_fem.folders import MANIFEST


def _arrays_differ(name: str, old, new, rtol: float) -> str | None:
    """A line saying how two arrays differ, or None when they agree (see module doc)."""
    old, new = np.asarray(old), np.asarray(new)
    if old.shape != new.shape or old.dtype != new.dtype:
        return f"{name}: shape/type {old.shape} {old.dtype} -> {new.shape} {new.dtype}"
    if np.array_equal(old, new, equal_nan=old.dtype.kind in "fc"):
        return None
    if old.dtype.kind not in "fc" or rtol == 0:
        return f"{name}: values differ ({int(np.sum(old != new))} entries)"
    scale = float(np.max(np.abs(old))) or 1.0
    worst = float(np.max(np.abs(old.astype(complex) - new.astype(complex)))) / scale
    return None if worst <= rtol else f"{name}: relative difference {worst:.3g} > {rtol:g}"


def compare_vtu(old: Path, new: Path, rtol: float) -> list[str]:
    """Differences of two VTU files as meshio and pyvista read them."""
    import meshio
    import pyvista

    problems = []
    a, b = meshio.read(old), meshio.read(new)
    problems.append(_arrays_differ("meshio points", a.points, b.points, rtol))
    if [block.type for block in a.cells] != [block.type for block in b.cells]:
        problems.append("meshio cell types differ")
    for k, (x, y) in enumerate(zip(a.cells, b.cells)):
        problems.append(_arrays_differ(f"meshio cells[{k}]", x.data, y.data, 0.0))
    for kind, first, second in (("point", a.point_data, b.point_data),
                                ("cell", a.cell_data, b.cell_data)):
        if list(first) != list(second):
            problems.append(f"meshio {kind} data names {list(first)} -> {list(second)}")
        for name in first.keys() & second.keys():
            left, right = first[name], second[name]
            if kind == "cell":
                left, right = np.concatenate(left), np.concatenate(right)
            problems.append(_arrays_differ(f"meshio {kind} {name}", left, right, rtol))
    a, b = pyvista.read(old), pyvista.read(new)
    problems.append(_arrays_differ("vtk points", a.points, b.points, rtol))
    problems.append(_arrays_differ("vtk cell connectivity", a.cell_connectivity,
                                   b.cell_connectivity, 0.0))
    problems.append(_arrays_differ("vtk offsets", a.cell_offsets, b.cell_offsets, 0.0))
    problems.append(_arrays_differ("vtk cell types", a.celltypes, b.celltypes, 0.0))
    for kind, first, second in (("point", a.point_data, b.point_data),
                                ("cell", a.cell_data, b.cell_data)):
        if list(first.keys()) != list(second.keys()):
            problems.append(f"vtk {kind} data names differ")
        for name in set(first.keys()) & set(second.keys()):
            problems.append(_arrays_differ(f"vtk {kind} {name}", first[name], second[name],
                                           rtol))
    return [f"{new.name}: {line}" for line in problems if line]


def compare_png(old: Path, new: Path) -> list[str]:
    """A line when the two pictures' RGB pixels differ."""
    from PIL import Image

    a = np.asarray(Image.open(old).convert("RGB"))
    b = np.asarray(Image.open(new).convert("RGB"))
    if a.shape != b.shape:
        return [f"{new.name}: size {a.shape} -> {b.shape}"]
    differ = int(np.any(a != b, axis=2).sum())
    return [f"{new.name}: {differ} pixels differ"] if differ else []


def compare_json(old: Path, new: Path, left_out: str) -> list[str]:
    """A JSON file without its key ``left_out`` (timings, a time stamp: they differ between
    any two runs)."""
    a, b = (json.loads(path.read_text()) for path in (old, new))
    for data in (a, b):
        data.pop(left_out, None)
    return [] if a == b else [f"{new.name}: differs ({left_out} left out)"]


def compare_folders(old: Path, new: Path, rtol: float = 0.0) -> tuple[list[str], int]:
    """Every difference between two result folders (module doc), and the files compared."""
    names = sorted(path.name for path in old.iterdir() if path.is_file())
    missing = sorted({path.name for path in new.iterdir() if path.is_file()} ^ set(names))
    problems = [f"only in one folder: {name}" for name in missing]
    for name in names:
        a, b = old / name, new / name
        if not b.exists():
            continue
        if name.endswith(".vtu"):
            problems += compare_vtu(a, b, rtol)
        elif name.endswith(".png"):
            problems += compare_png(a, b)
        elif name == "modes.json":
            problems += compare_json(a, b, "timings_s")
        elif name == MANIFEST:
            problems += compare_json(a, b, "written_utc")
        elif a.read_bytes() != b.read_bytes():
            problems.append(f"{name}: bytes differ")
    return problems, len(names)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path)
    parser.add_argument("new", type=Path)
    parser.add_argument("--rtol", type=float, default=0.0,
                        help="allowed difference of float arrays, relative to the array's "
                             "largest modulus (default 0: equal to the bit)")
    args = parser.parse_args(argv)
    problems, count = compare_folders(args.old, args.new, args.rtol)
    for line in problems:
        print(line)
    print(f"{count} files compared, {len(problems)} differences")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
