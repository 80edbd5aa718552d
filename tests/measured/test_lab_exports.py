"""Lab exports as they come: identify a UFF file without a study, roving references,
nodal coordinate systems, unit labels that name no unit, files pyuff writes oddly."""

import logging
import re

import numpy as np
import pytest
import pyuff
from vibrometer_helpers import REALDATA, make_scan, paper_grid, pole

from copdea_fem.cli import main
from copdea_fem.measured import MeasuredDataError, ScanData, read_scan, write_scan
from copdea_fem.measured.uff import read_geometry, read_trace_lines

SAMPLES = REALDATA / "pyuff_format_samples"
BEAM = REALDATA / "pyuff_meas_frf_3pt" / "measurement_e2089be.uff"
needs_realdata = pytest.mark.skipif(not REALDATA.is_dir(),
                                    reason=f"real UFF files not present ({REALDATA})")


def _records(path):
    return pyuff.UFF(str(path)).read_sets()


def _rewrite(path, sets):
    path.unlink(missing_ok=True)
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    return path


def _small_scan(points=4, lines=41):
    positions = paper_grid()[:points]
    rng = np.random.default_rng(1)
    return make_scan(np.arange(lines) * 5.0, [pole(60.0, 0.02)],
                     rng.normal(size=(1, points, 3)), positions)


# --- the real files -----------------------------------------------------------------------

#: The beam's peaks (the file's README: the largest |H| line of each, 1 Hz lines).
BEAM_PEAKS = [52, 142, 279, 460, 687, 959]


@needs_realdata
def test_beam_modes_from_the_file_alone(tmp_path, capsys, caplog):
    """identify FILE on the roving-hammer beam (one response, three references, no
    geometry, unit labels NONE): six modes within 0.5 Hz of the peaks; the reciprocity and
    the unit assumption said in the log; frequencies, damping and shapes by node written,
    no VTU (no geometry)."""
    with caplog.at_level(logging.INFO, logger="copdea_fem"):
        assert main(["identify", str(BEAM), "--out", str(tmp_path / "beam")]) == 0
    modes = np.genfromtxt(tmp_path / "beam" / "modes.csv", delimiter=",", names=True)
    assert modes.size == 6
    assert np.abs(modes["freq_hz"] - BEAM_PEAKS).max() < 0.5
    assert np.all((modes["damping_ratio"] > 0) & (modes["damping_ratio"] < 0.01))
    shapes = (tmp_path / "beam" / "shapes.csv").read_text().splitlines()
    assert len(shapes) == 1 + 6 * 3                      # 6 modes x 3 nodes
    assert {line.split(",")[2] for line in shapes[1:]} == {"1", "2", "3"}
    assert (tmp_path / "beam" / "stabilisation.png").stat().st_size > 1000
    assert not (tmp_path / "beam" / "shapes").exists()
    assert "roving reference (3 references" in caplog.text
    assert "'NONE'" in caplog.text and "names no unit" in caplog.text
    assert "no geometry" in caplog.text and "no VTU" in caplog.text


@needs_realdata
def test_shaker_psd_is_refused_naming_function_type_9(tmp_path, capsys):
    path = SAMPLES / "sample_dataset58_psd_VibControl.uff"
    assert main(["identify", str(path), "--out", str(tmp_path / "psd")]) == 2
    line = capsys.readouterr().err.strip()
    assert "function type 9 (power spectral density)" in line
    assert "allowed: function type 4 (frequency response function) or 12" in line
    assert str(path) in line                              # the whole path
    assert not (tmp_path / "psd").exists()


@needs_realdata
def test_testlab_trace_lines_and_coordinate_systems():
    """The Test.Lab geometry: 36 nodes, its three trace-line sets (pen lifted at node 0)
    and its 36 node systems of dataset 18 (each the global axes turned 180 degrees about
    y: x_point - origin = (-1, 0, 0), xz_point - origin = (-1, 0, -1))."""
    path = SAMPLES / "TestLab_161_164_18_15_82.uff"
    nodes, _ = read_geometry(path)
    assert nodes.size == 36
    traces = read_trace_lines(path)
    assert [name for name, _ in traces] == ["Massif", "Stator", "Dalle"]
    assert np.array_equal(traces[0][1][0], [2, 5, 6, 3, 4, 1, 2, 3])
    assert [len(polylines) for _, polylines in traces] == [1, 8, 2]
    from copdea_fem.measured.coordinates import systems_from_18
    record = _records(path)[2]
    systems = systems_from_18([record], "18", 1.0)
    assert len(systems) == 36
    assert np.allclose(systems[1].axes, np.diag([-1.0, 1.0, -1.0]), atol=1e-7)
    assert np.allclose(systems[1].origin, [-2.4, -0.95, 0.0])


@needs_realdata
def test_artemis_geometry_reads_74_nodes():
    nodes, coordinates = read_geometry(SAMPLES / "Artemis_geometry_RPBC_setup_05.uff")
    assert nodes.size == 74 and np.all(np.isfinite(coordinates))


# --- references and directions ------------------------------------------------------------

def _roving_files(tmp_path):
    """The same FRFs (closed form, one mode, nodes 1..4 along x) as a roving response file
    (reference node 9) and as a roving reference file (response node 9, by reciprocity
    H_ij = H_ji)."""
    scan = _small_scan()
    response = write_scan(tmp_path / "response.uff", scan, binary=False)
    sets = _records(response)
    swapped = []
    for record in sets:
        if record["type"] == 58:
            record = dict(record, ref_node=record["rsp_node"], ref_dir=record["rsp_dir"],
                          rsp_node=9, rsp_dir=1)
        swapped.append(record)
    return response, _rewrite(tmp_path / "reference.uff", swapped), scan


def test_roving_reference_is_read_by_reciprocity(tmp_path, caplog):
    response, reference, scan = _roving_files(tmp_path)
    with caplog.at_level(logging.INFO, logger="copdea_fem"):
        swapped = read_scan(reference)
    straight = read_scan(response)
    assert np.array_equal(swapped.channel_point, straight.channel_point)
    assert np.array_equal(swapped.channel_direction, straight.channel_direction)
    assert np.allclose(swapped.values, scan.values, rtol=0, atol=1e-11 * np.abs(scan.values).max())
    assert "roving reference (12 references, one response at node 9 dir 1)" in caplog.text


def test_several_references_and_responses_are_refused_by_name(tmp_path):
    _, reference, _ = _roving_files(tmp_path)
    sets = _records(reference)
    for record in sets:
        if record["type"] == 58 and record["ref_node"] == 2:
            record["rsp_node"] = 3
    path = _rewrite(tmp_path / "poly.uff", sets)
    with pytest.raises(MeasuredDataError, match=r"poly\.uff.*12 references \(node 1 dir 1, "
                                                r"node 1 dir 2, .*with 2 responses"):
        read_scan(path)


def test_negative_directions_are_read_signed(tmp_path):
    """rsp_dir -3 is the -z axis: read as (0, 0, -1), compared signed (the values as
    written: the sign lies in the direction, not the data)."""
    scan = _small_scan()
    flipped = ScanData(path=scan.path, nodes=scan.nodes, positions=scan.positions,
                       channel_point=scan.channel_point,
                       channel_direction=np.tile(np.diag([1.0, 1.0, -1.0]), (scan.n_points, 1)),
                       frequencies=scan.frequencies, values=scan.values)
    path = write_scan(tmp_path / "minus_z.uff", flipped, binary=False)
    assert {r["rsp_dir"] for r in _records(path) if r["type"] == 58} == {1, 2, -3}
    back = read_scan(path)
    assert np.array_equal(back.channel_direction[2::3], np.tile([0.0, 0.0, -1.0],
                                                                (scan.n_points, 1)))
    assert np.array_equal(back.channel_direction[0::3], np.tile([1.0, 0.0, 0.0],
                                                                (scan.n_points, 1)))


def test_displacement_coordinate_systems_turn_directions_and_points(tmp_path):
    """Nodes whose coordinates and directions refer to dataset 18's system 5: its origin
    (1, 2, 3) m, x axis along global y, z along global z (a quarter turn about z).  A node
    at local (1, 0, 0) lies at global (1, 3, 3); its rsp_dir 1 measures along global +y,
    rsp_dir 2 along global -x (p = o + R^T p_local, d = R^T d_local)."""
    scan = _small_scan(points=3)
    path = write_scan(tmp_path / "systems.uff", scan, binary=False)
    sets = _records(path)
    geometry = next(s for s in sets if s["type"] == 2411)
    geometry["def_cs"] = np.array([5, 0, 0])
    geometry["disp_cs"] = np.array([5, 5, 0])
    geometry["x"], geometry["y"], geometry["z"] = (np.array([1.0, 0.0, 0.0]),
                                                   np.array([0.0, 1.0, 0.0]),
                                                   np.array([0.0, 0.0, 1.0]))
    system = pyuff.prepare_18(cs_num=[5], cs_type=[0], ref_cs_num=[0], color=[8],
                              cs_name=["turned"], ref_o=[[1.0, 2.0, 3.0]],
                              x_point=[[1.0, 3.0, 3.0]], xz_point=[[1.0, 2.0, 4.0]])
    path = _rewrite(tmp_path / "systems.uff", [sets[0], system, *sets[1:]])
    back = read_scan(path)
    assert np.allclose(back.positions, [[1.0, 3.0, 3.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    first = back.channel_direction[back.channel_point == 0]
    assert np.allclose(first, [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    third = back.channel_direction[back.channel_point == 2]
    assert np.allclose(third, np.eye(3))


def test_dataset_2420_systems_are_applied(tmp_path):
    """The same quarter turn as dataset 2420 (rows 1-3: the local axes in global axes,
    row 4: the origin): local x = global y, local y = global -x."""
    scan = _small_scan(points=3)
    sets = _records(write_scan(tmp_path / "a.uff", scan, binary=False))
    geometry = next(s for s in sets if s["type"] == 2411)
    geometry["def_cs"] = np.array([5, 0, 0])
    geometry["disp_cs"] = np.array([5, 0, 0])
    geometry["x"], geometry["y"], geometry["z"] = (np.array([1.0, 0.0, 0.0]),
                                                   np.array([0.0, 1.0, 0.0]),
                                                   np.array([0.0, 0.0, 1.0]))
    system = pyuff.prepare_2420(Part_UID=1, Part_Name="part", CS_sys_labels=[5],
                                CS_types=[0], CS_colors=[8], CS_names=["turned"],
                                CS_matrices=[np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0],
                                                       [0.0, 0.0, 1.0], [1.0, 2.0, 3.0]])])
    path = _rewrite(tmp_path / "2420.uff", [sets[0], system, *sets[1:]])
    back = read_scan(path)
    assert np.allclose(back.positions[0], [1.0, 3.0, 3.0])
    assert np.allclose(back.channel_direction[back.channel_point == 0],
                       [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def test_a_cylindrical_system_is_refused_by_name(tmp_path):
    scan = _small_scan(points=3)
    sets = _records(write_scan(tmp_path / "c.uff", scan, binary=False))
    next(s for s in sets if s["type"] == 2411)["disp_cs"] = np.array([7, 0, 0])
    system = pyuff.prepare_18(cs_num=[7], cs_type=[1], ref_cs_num=[0], color=[8],
                              cs_name=["cyl"], ref_o=[[0.0, 0.0, 0.0]],
                              x_point=[[1.0, 0.0, 0.0]], xz_point=[[1.0, 0.0, 1.0]])
    path = _rewrite(tmp_path / "cyl.uff", [sets[0], system, *sets[1:]])
    with pytest.raises(MeasuredDataError, match=r"cyl\.uff.*coordinate system 7 is "
                                                r"cylindrical.*allowed: Cartesian"):
        read_scan(path)


# --- units --------------------------------------------------------------------------------

def test_unlabelled_ordinate_takes_dataset_164_factor_the_right_way(tmp_path, caplog):
    """An FRF whose labels name no unit: dataset 164 says the file's length unit is the
    millimetre (length factor 1000: SI = value / 1000) and records 9-10 give the ordinate
    length exponent 1: the values in SI are the file's / 1000, and the log says so."""
    scan = _small_scan()
    sets = _records(write_scan(tmp_path / "si.uff", scan, binary=False))
    sets[0]["length"] = 1000.0
    for record in sets:
        if record["type"] == 58:
            record.update(ordinate_axis_units_lab="NONE", orddenom_axis_units_lab="NONE",
                          ordinate_len_unit_exp=1, data=record["data"] * 1000.0)
    path = _rewrite(tmp_path / "mm.uff", sets)
    with caplog.at_level(logging.WARNING, logger="copdea_fem"):
        back = read_scan(path, geometry=True)
    assert np.allclose(back.values, scan.values, rtol=1e-10, atol=0)
    assert "names no unit ('NONE' in 58 #3)" in caplog.text


def test_fortran_d_exponents_are_read(tmp_path):
    scan = _small_scan()
    path = write_scan(tmp_path / "e.uff", scan, binary=False)
    fortran = tmp_path / "d.uff"
    fortran.write_text(re.sub(r"(\d)e([+-]\d\d)", r"\1D\2", path.read_text()))
    assert "D+" in fortran.read_text() or "D-" in fortran.read_text()
    back = read_scan(fortran)
    assert np.allclose(back.values, read_scan(path).values, rtol=0, atol=0)


def test_pyuffs_infinity_is_refused_by_name(tmp_path):
    """pyuff writes an infinite value as the largest double, 1.79769313486e+308: refused
    naming the dataset, node and abscissa, not identified into 0 modes."""
    sets = _records(write_scan(tmp_path / "a.uff", _small_scan(), binary=False))
    sets[4]["data"] = sets[4]["data"].copy()
    sets[4]["data"][7] = np.inf
    path = _rewrite(tmp_path / "inf.uff", sets)
    assert "1.79769313486e+308" in path.read_text()
    with pytest.raises(MeasuredDataError, match=r"inf\.uff' dataset 58 #5 \(response node "
                                                r"1\): 1 values of magnitude above 1e\+307 "
                                                r"\(first 1\.798e\+308 at abscissa 35"):
        read_scan(path)


def test_2411_with_a_conflicting_15_warns_which_is_used(tmp_path, caplog):
    scan = _small_scan()
    sets = _records(write_scan(tmp_path / "a.uff", scan, binary=False))
    old = pyuff.prepare_15(node_nums=[1, 2, 3, 4], def_cs=[0] * 4, disp_cs=[0] * 4,
                           color=[8] * 4, x=[0.0, 1.0, 2.0, 3.0], y=[0.0] * 4, z=[0.0] * 4)
    path = _rewrite(tmp_path / "both.uff", [*sets[:2], old, *sets[2:]])
    with caplog.at_level(logging.WARNING, logger="copdea_fem"):
        back = read_scan(path)
    assert np.allclose(back.positions, scan.positions)
    assert "dataset 2411 #2 (4 nodes) and dataset 15 #3 (4 nodes) give different nodes " \
           "or coordinates: 2411 #2 used, 15 #3 ignored" in caplog.text
    caplog.clear()
    same = pyuff.prepare_15(node_nums=[4, 3, 2, 1], def_cs=[0] * 4, disp_cs=[0] * 4,
                            color=[8] * 4, x=scan.positions[::-1, 0],
                            y=scan.positions[::-1, 1], z=scan.positions[::-1, 2])
    path = _rewrite(tmp_path / "same.uff", [*sets[:2], same, *sets[2:]])
    with caplog.at_level(logging.WARNING, logger="copdea_fem"):
        read_scan(path)
    assert "ignored" not in caplog.text


# --- identify FILE ------------------------------------------------------------------------

def test_identify_file_writes_vtu_on_trace_lines(tmp_path, capsys):
    """A file with geometry and a dataset 82: two modes found (closed form, 50 and 130 Hz),
    the shape VTUs hold the trace segments as VTK lines on the file's points."""
    import meshio

    positions = paper_grid()[:6]
    rng = np.random.default_rng(4)
    scan = make_scan(np.arange(161) * 1.25, [pole(50.0, 0.02), pole(130.0, 0.01)],
                     rng.normal(size=(2, 6, 3)), positions)
    sets = _records(write_scan(tmp_path / "s.uff", scan))
    trace = pyuff.prepare_82(trace_num=1, n_nodes=7, color=8, id="edge",
                             nodes=np.array([1, 2, 3, 0, 4, 5, 6]))
    path = _rewrite(tmp_path / "traced.uff", [*sets[:2], trace, *sets[2:]])
    assert main(["identify", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    modes = np.genfromtxt(tmp_path / "out" / "modes.csv", delimiter=",", names=True)
    assert np.allclose(modes["freq_hz"], [50.0, 130.0], atol=0.05)
    files = sorted((tmp_path / "out" / "shapes").glob("*.vtu"))
    assert len(files) == 2
    mesh = meshio.read(files[0])
    assert mesh.cells[0].type == "line"
    assert mesh.cells[0].data.tolist() == [[0, 1], [1, 2], [3, 4], [4, 5]]
    assert np.allclose(mesh.points, positions)


def test_identify_file_band_and_options_refused_by_name(tmp_path, capsys):
    path = write_scan(tmp_path / "s.uff", _small_scan())
    assert main(["identify", str(path), "--band", "300", "400", "--out",
                 str(tmp_path / "o")]) == 2
    assert "--band = [300, 400] Hz is not allowed (outside the file's lines); allowed: a " \
           "band within 5..200 Hz" in capsys.readouterr().err
    assert main(["identify", str(path), "--band", "9", "x", "--out", str(tmp_path / "o")]) == 2
    assert "--band = 'x' is not allowed" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_collinear_scan_points_give_vertices_not_empty_vtus():
    """Points on one line have no Delaunay surface: the shapes are written on the points
    (VTK vertices), not as files of 0 cells."""
    from copdea_fem.vibrometer.identified import IdentifiedMode, shape_meshes

    positions = np.column_stack([np.linspace(0.018, 0.034, 5), np.zeros(5), np.zeros(5)])
    scan = make_scan(np.arange(41) * 5.0, [pole(60.0, 0.02)], np.ones((1, 5, 3)), positions)
    mode = IdentifiedMode(1, 60.0, 0.02, np.ones(scan.n_channels, complex), 1.0)
    ((_, mesh),) = shape_meshes(scan, (mode,))
    assert mesh.cells[0].type == "vertex" and mesh.cells[0].data.shape == (5, 1)
