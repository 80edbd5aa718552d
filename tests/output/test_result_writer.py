"""The result files of a solve written cheaply (issue 25): what is built once per write
and reused for every mode -- the air's geometry, the encoded geometry bytes, the DOFs each
element corner reads, the membrane's amplitude and prestress profiles, the picture's
raster -- gives every mode's file the values a direct evaluation gives.

The writers' speed lives in ``python -m benchmarks.command command`` (docs/benchmarks.md);
``tools/compare_results.py`` compares whole result folders of two checkouts."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial import cKDTree

import copdea_fem as cf
from copdea_fem.fe.modes import IN_PLANE, OUT_OF_PLANE, PUMPING
from copdea_fem.vtu import VtuMesh, VtuWriter, write_vtu

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "studies/g1_z16_v2_quick.yaml"
#: the quick study in a baffle (axisymmetric engine): orders 0, 1, 2 below 500 Hz; quadratic
#: pressure, so that the corners' values also need H1's edge functions to vanish there
AXISYMMETRIC = {"eigen.f_max": "500 Hz", "geometry.frame": "baffle",
                "mesh.pressure_order": 2}


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """An axisymmetric coupled solve and its written folder."""
    solution = cf.solve(cf.load_study(QUICK, AXISYMMETRIC))
    folder = solution.write(tmp_path_factory.mktemp("writer") / "run")
    return solution, folder


def _air_file(folder: Path, number: int) -> Path:
    """The air file of mode ``number`` (``air_NNN_<label>.vtu``)."""
    path, = folder.glob(f"air_{number:03d}_*.vtu")
    return path


def _structural(result) -> list:
    """The modes with a membrane file (not the air's own), in the files' order."""
    return [mode for mode in result.modes if mode.kind in (OUT_OF_PLANE, PUMPING, IN_PLANE)]


def _corner_pressures(result, number):
    """Direct evaluation: mode ``number``'s pressure CoefficientFunction [Pa] evaluated by
    NGSolve at every element corner of the meridian, and the corners' moved (r, z) [m]."""
    import ngsolve as ngs

    from copdea_fem.fe.acoustics import pressure_field

    mode, pressure = result.modes[number], result.coupled.pressures[number]
    operators = next(item for item in result.coupled.operators if item.m == mode.m)
    mesh = operators.pressure_space.mesh
    points = mesh.MapToAllElements(ngs.IntegrationRule([(1, 0), (0, 1), (0, 0)], [0.0] * 3),
                                   ngs.VOL)
    gf = ngs.GridFunction(operators.pressure_space)
    gf.vec.FV().NumPy()[operators.pressure_free] = pressure
    values = np.asarray(pressure_field(gf.components[0], gf.components[1], mesh)(points))
    moved = np.asarray(ngs.CF((ngs.x, ngs.y))(points)) + np.asarray(operators.mesh_motion(points))
    return values.ravel(), moved


def test_air_files_share_one_geometry_and_hold_each_modes_own_pressure(written):
    """Two modes of different order written together: the same points, wedges and cell
    data, and at every written point the pressure of that mode: p(r, z) cos m theta (sin
    for the sin family) with p evaluated by NGSolve at each element corner there.  Left
    out: the axis (one merged point) and the screens' two sides (two points at one place,
    each with its half's pressure: not told apart by position)."""
    import meshio

    solution, folder = written
    result = solution.result
    orders = {mode.m: number for number, mode in reversed(list(enumerate(result.modes)))}
    assert {0, 2} <= set(orders)
    files = {}
    for number in (orders[0], orders[2]):
        files[number] = meshio.read(_air_file(folder, number))
    first, second = files.values()
    np.testing.assert_array_equal(first.points, second.points)
    np.testing.assert_array_equal(first.cells[0].data, second.cells[0].data)
    for name in ("pml", "lower_half"):
        np.testing.assert_array_equal(first.cell_data[name][0], second.cell_data[name][0])
    assert not np.allclose(first.point_data["pressure_abs"], second.point_data["pressure_abs"])
    for number, grid in files.items():
        mode = result.modes[number]
        values, moved = _corner_pressures(result, number)
        points = grid.points.astype(float)
        r, z = np.hypot(points[:, 0], points[:, 1]), points[:, 2]
        single = r > 1e-6 * r.max()
        single[cKDTree(points).query_pairs(1e-7, output_type="ndarray").ravel()] = False
        theta = np.arctan2(points[:, 1], points[:, 0])
        harmonic = np.cos(mode.m * theta) if mode.family == "cos" else np.sin(mode.m * theta)
        stored = grid.point_data["pressure_real"] + 1j * grid.point_data["pressure_imag"]
        # every element corner at a written point (points are float32: 1e-6 m apart is
        # one point, the mesh's vertices are millimetres apart)
        nearby = cKDTree(moved).query_ball_point(np.column_stack([r, z])[single], 1e-6)
        assert all(nearby)
        point = np.repeat(np.flatnonzero(single), [len(group) for group in nearby])
        corner = np.concatenate(nearby)
        expected = values[corner] * harmonic[point]
        # float32 values and coordinates (the angle): 1e-6 of the largest pressure
        scale = np.abs(values).max()
        np.testing.assert_allclose(stored[point], expected, rtol=0, atol=1e-6 * scale)
        np.testing.assert_allclose(grid.point_data["pressure_abs"][point], np.abs(expected),
                                   rtol=0, atol=1e-6 * scale)


def test_an_air_file_written_with_others_equals_the_mode_alone(written):
    """The air of a mode built alone (its own geometry, its own corner reader) equals its
    file written in the series, array for array."""
    import meshio

    solution, folder = written
    result = solution.result
    assert _structural(result) == result.modes             # every air file is a mode's
    output = solution.engine.output(result.state, result.modes)
    for number in (len(result.modes) - 1, 0):
        mode = result.modes[number]
        with solution.engine.threads():
            (_, alone), = output.air_meshes(result.coupled.operators, [mode],
                                            [result.coupled.pressures[number]])
        stored = meshio.read(_air_file(folder, number))
        np.testing.assert_array_equal(stored.points, alone.points)
        for name, values in alone.point_data.items():
            np.testing.assert_array_equal(stored.point_data[name], values)


def test_corner_pressure_reads_what_the_field_evaluates(written):
    """CornerPressure finds the corners' DOFs (it gathers) and gives what NGSolve evaluates
    at the corners for any vector, to the bit."""
    import ngsolve as ngs

    from copdea_fem.fe.acoustics import pressure_field
    from copdea_fem.fe.fields import CornerPressure

    solution, _ = written
    space = solution.result.coupled.operators[0].pressure_space
    mesh = space.mesh
    points = mesh.MapToAllElements(ngs.IntegrationRule([(1, 0), (0, 1), (0, 0)], [0.0] * 3),
                                   ngs.VOL)
    reader = CornerPressure(space, points)
    assert reader.gathered
    gf = ngs.GridFunction(space)
    field = pressure_field(gf.components[0], gf.components[1], mesh)
    generator = np.random.default_rng(7)
    for _ in range(2):
        vector = generator.standard_normal(space.ndof) + 1j * generator.standard_normal(space.ndof)
        gf.vec.FV().NumPy()[:] = vector
        np.testing.assert_array_equal(reader(vector), np.asarray(field(points)).ravel())


def test_membrane_profiles_equal_one_evaluation_per_function(written):
    """The amplitudes of all modes of an order (one tuple CoefficientFunction) and the
    compiled prestress fields equal each function sampled on its own, to the bit."""
    import ngsolve as ngs

    from copdea_fem.fe.axisymmetric.fields import amplitude_profiles

    solution, _ = written
    result = solution.result
    modes = _structural(result)
    assert len({mode.m for mode in modes}) >= 3
    sampler = solution.engine.output(result.state, modes).sampler
    # two different vectors of one order and family (the quick study's pairs (m,1)a/b are
    # one vector with two families): the last mode again, with a random vector
    generator = np.random.default_rng(11)
    size = len(modes[-1].vector)
    modes = modes + [SimpleNamespace(
        operators=modes[-1].operators, m=modes[-1].m, family=modes[-1].family,
        vector=generator.standard_normal(size) + 1j * generator.standard_normal(size))]
    for mode, profile in zip(modes, amplitude_profiles(sampler, modes)):
        gf = ngs.GridFunction(mode.operators.space)
        parts = []
        for part in (np.real(mode.vector), np.imag(mode.vector)):
            gf.vec.FV().NumPy()[:] = part
            parts.append(np.stack([sampler.profile(function)
                                   for function in mode.operators.amplitudes(gf)], 1))
        np.testing.assert_array_equal(profile, parts[0] + 1j * parts[1])
    profiles = sampler.prestress_profiles()
    fields = result.state.fields()
    assert list(profiles) == list(fields)
    for name, function in fields.items():
        np.testing.assert_array_equal(profiles[name], sampler.profile(function))


def test_a_series_writer_writes_each_file_as_write_vtu_alone(tmp_path):
    """VtuWriter: meshes that share their geometry arrays, then one with the same shapes
    but other values -- every file byte for byte what write_vtu writes for it alone."""
    generator = np.random.default_rng(5)
    points = generator.random((30, 3)).astype(np.float32)
    cells = generator.integers(0, 30, (12, 6))
    flags = {"pml": [generator.integers(0, 2, 12).astype(np.int8)]}
    meshes = [VtuMesh(points, [("wedge", cells)], cell_data=flags,
                      point_data={"p": generator.random(30).astype(np.float32)})
              for _ in range(3)]
    other = VtuMesh(generator.random((30, 3)).astype(np.float32),
                    [("wedge", generator.integers(0, 30, (12, 6)))],
                    point_data={"p": generator.random(30).astype(np.float32)},
                    cell_data={"pml": [generator.integers(0, 2, 12).astype(np.int8)]})
    series = [*meshes, other, meshes[0]]
    writer = VtuWriter()
    for number, mesh in enumerate(series):
        writer.write(tmp_path / f"series_{number}.vtu", mesh)
        write_vtu(tmp_path / f"alone_{number}.vtu", mesh)
        assert (tmp_path / f"series_{number}.vtu").read_bytes() == \
            (tmp_path / f"alone_{number}.vtu").read_bytes()
    with VtuWriter() as writer:                 # written by a background thread
        for number, mesh in enumerate(series):
            writer.write(tmp_path / f"background_{number}.vtu", mesh)
    for number in range(len(series)):
        assert (tmp_path / f"background_{number}.vtu").read_bytes() == \
            (tmp_path / f"alone_{number}.vtu").read_bytes()


def test_a_background_write_that_fails_raises_when_the_series_ends(tmp_path):
    mesh = VtuMesh(np.zeros((3, 3)), [("triangle", np.array([[0, 1, 2]]))])
    with pytest.raises(FileNotFoundError):
        with VtuWriter() as writer:
            writer.write(tmp_path / "fine.vtu", mesh)
            writer.write(tmp_path / "no such folder" / "lost.vtu", mesh)
            writer.write(tmp_path / "after.vtu", mesh)
    assert (tmp_path / "fine.vtu").exists() and (tmp_path / "after.vtu").exists()


def test_a_short_gathering_write_is_completed(tmp_path, monkeypatch):
    """Where os.writev writes less than asked (it may), the rest is written: the file is
    whole, byte for byte write_vtu's."""
    import os

    from copdea_fem import vtu

    generator = np.random.default_rng(4)
    mesh = VtuMesh(generator.random((20, 3)), [("triangle", generator.integers(0, 20, (9, 3)))],
                   point_data={"p": generator.random(20)})
    write_vtu(tmp_path / "whole.vtu", mesh)
    for short in (0, 5, 300):                  # in the header, in an array, past the first
        monkeypatch.setattr(vtu.os, "writev", lambda fd, views, short=short: os.write(
            fd, b"".join(bytes(view) for view in views)[:short]))
        write_vtu(tmp_path / f"short_{short}.vtu", mesh)
        assert (tmp_path / f"short_{short}.vtu").read_bytes() == \
            (tmp_path / "whole.vtu").read_bytes()
