"""ParaView files of a 3-D quadrant result: one point per place, slices on the mirror planes.

The quadrant's fields are unfolded to the whole device (copdea_fem.fe.symmetry); the copies of
the points on the mirror planes x = 0 and y = 0 are merged (copdea_fem.fe.fields.PointMerge),
so a slice exactly on a plane neither counts its faces twice nor leaves holes.  The only
points written twice are the two sides of a screen, where the pressure jumps.
"""

from pathlib import Path

import numpy as np
import pytest
import pyvista as pv
from scipy.spatial import cKDTree

from copdea_fem.cli import main

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def quadrant_result(tmp_path_factory):
    out = tmp_path_factory.mktemp("paraview") / "run"
    code = main(["solve", str(ROOT / "studies/g1_z16_v2_quick.yaml"), "--out", str(out),
                 "--quiet", "--set", "eigen.f_max=500 Hz", "--set", "output.plots=false"])
    assert code == 0
    return out


def _coincident_pairs(points):
    points = np.asarray(points, dtype=float)
    return cKDTree(points).query_pairs(1e-9 * np.ptp(points, axis=0).max(),
                                       output_type="ndarray")


def test_no_coincident_points_but_the_two_sides_of_a_screen(quadrant_result):
    files = sorted(quadrant_result.glob("*.vtu"))
    assert any(f.name.startswith("air_") for f in files)
    assert any(f.name.startswith("mode_") for f in files)
    assert (quadrant_result / "prestress.vtu") in files
    for path in files:
        grid = pv.read(path)
        pairs = _coincident_pairs(grid.points)
        if not path.name.startswith("air_"):
            assert len(pairs) == 0, f"{path.name}: {len(pairs)} coincident point pairs"
            continue
        # air: a point shared by upper and lower cells would be a merged screen point;
        # every coincident pair must be one upper-only and one lower-only point
        cells = grid.cells_dict[pv.CellType.TETRA]
        lower = np.asarray(grid.cell_data["lower_half"], dtype=bool)
        in_lower = np.zeros(grid.n_points, dtype=bool)
        in_upper = np.zeros(grid.n_points, dtype=bool)
        in_lower[cells[lower].ravel()] = True
        in_upper[cells[~lower].ravel()] = True
        assert len(pairs) > 0          # the membrane's two sides
        assert len(np.unique(pairs)) == 2 * len(pairs), f"{path.name}: more than two copies"
        a, b = pairs.T
        one_side = (in_lower[a] ^ in_upper[a]) & (in_lower[b] ^ in_upper[b]) \
            & (in_lower[a] != in_lower[b])
        assert one_side.all(), f"{path.name}: coincident points on one side of the plane"


@pytest.mark.parametrize("normal", [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)])
def test_slice_on_a_mirror_plane_has_the_area_of_a_slice_beside_it(quadrant_result, normal):
    air = pv.read(next(quadrant_result.glob("air_000_*.vtu")))
    normal = np.array(normal)
    on_plane = air.slice(normal=normal, origin=(0.0, 0.0, 0.0)).area
    beside = air.slice(normal=normal, origin=1e-4 * normal).area
    assert beside > 0.01
    assert on_plane == pytest.approx(beside, rel=0.01)
    # the clip at the plane holds half of the air
    assert air.clip(normal=normal, origin=(0.0, 0.0, 0.0)).volume == pytest.approx(
        air.volume / 2, rel=1e-3)


@pytest.mark.parametrize("kind, corners", [("triangle", 3), ("tetra", 4), ("wedge", 6)])
def test_vtu_writer_reads_back_as_meshio_writes(tmp_path, kind, corners):
    """copdea_fem.vtu.write_vtu (raw appended arrays) against meshio's own writer: the
    same grid for VTK (pyvista) and for meshio, wedges in VTK's corner order."""
    import meshio

    from copdea_fem.vtu import write_vtu

    generator = np.random.default_rng(1)
    mesh = meshio.Mesh(generator.random((40, 3)), [(kind, generator.integers(0, 40, (25, corners)))],
                       point_data={"scalar": generator.random(40).astype(np.float32),
                                   "vector": generator.random((40, 3))},
                       cell_data={"flag": [generator.integers(0, 2, 25).astype(np.int8)]})
    write_vtu(tmp_path / "ours.vtu", mesh)
    meshio.write(tmp_path / "meshio.vtu", mesh)
    ours, theirs = pv.read(tmp_path / "ours.vtu"), pv.read(tmp_path / "meshio.vtu")
    np.testing.assert_array_equal(ours.points, theirs.points)
    assert list(ours.cells_dict) == list(theirs.cells_dict)
    for cell_type in theirs.cells_dict:
        np.testing.assert_array_equal(ours.cells_dict[cell_type], theirs.cells_dict[cell_type])
    for name in ("scalar", "vector"):
        np.testing.assert_array_equal(ours.point_data[name], theirs.point_data[name])
    np.testing.assert_array_equal(ours.cell_data["flag"], theirs.cell_data["flag"])
    back = meshio.read(tmp_path / "ours.vtu")
    np.testing.assert_array_equal(back.cells[0].data, mesh.cells[0].data)
    np.testing.assert_array_equal(back.point_data["scalar"], mesh.point_data["scalar"])
