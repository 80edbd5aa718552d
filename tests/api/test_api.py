"""The Python API (copdea_fem.api): the CLI's results, fields and errors, nothing written
unless asked."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import pyvista as pv

import copdea_fem as cf
from copdea_fem.cli import main

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "studies/g1_z16_v2_quick.yaml"
#: the quick coupled study, band cut to keep the test short (3-D quadrant engine)
SMALL = {"eigen.f_max": "500 Hz", "output.plots": False}


@pytest.fixture(scope="module")
def quadrant(tmp_path_factory):
    """An API solve written by Solution.write, and the CLI's folder for the same study."""
    where = tmp_path_factory.mktemp("api")
    solution = cf.solve(cf.load_study(QUICK, SMALL))
    written = solution.write(where / "api")
    code = main(["solve", str(QUICK), "--out", str(where / "cli"), "--quiet",
                 *[f"--set={key}={value}" for key, value in SMALL.items()]])
    assert code == 0
    return solution, written, where / "cli"


def _assert_frame_equals_csv(frame: pd.DataFrame, path: Path):
    table = pd.read_csv(path, keep_default_na=False)
    assert list(frame.columns) == list(table.columns)
    assert len(frame) == len(table)
    for column in frame.columns:
        left, right = frame[column], table[column]
        numeric = pd.api.types.is_numeric_dtype(right) and right.dtype != object
        if numeric or pd.api.types.is_float_dtype(left):    # a float column with NaN: 'nan'
            np.testing.assert_allclose(left.astype(float), right.astype(float), rtol=1e-8,
                                       atol=1e-12, err_msg=column)
        else:
            assert [str(v) for v in left] == [str(v) for v in right], column


def test_modes_equal_the_cli_modes_csv(quadrant):
    solution, _, cli = quadrant
    modes = solution.modes
    assert isinstance(modes, pd.DataFrame)
    assert modes.loc[0, "label"] == "(0,1)" and modes.loc[0, "kind"] == "out-of-plane"
    _assert_frame_equals_csv(modes, cli / "modes.csv")


def test_write_gives_the_cli_files(quadrant):
    _, written, cli = quadrant
    names = lambda folder: sorted(p.name for p in folder.iterdir())  # noqa: E731
    assert names(written) == names(cli)
    _assert_frame_equals_csv(pd.read_csv(written / "modes.csv", keep_default_na=False),
                             cli / "modes.csv")


def _assert_grid_equals_file(grid, path: Path):
    stored = pv.read(path)
    np.testing.assert_array_equal(np.asarray(grid.points), np.asarray(stored.points))
    assert grid.n_cells == stored.n_cells
    assert set(grid.point_data) == set(stored.point_data) and len(grid.point_data) > 0
    for name in stored.point_data:
        np.testing.assert_array_equal(np.asarray(grid.point_data[name]),
                                      np.asarray(stored.point_data[name]), err_msg=name)


@pytest.mark.parametrize("label", ["(0,1)", "(1,1)b", "(2,1)b"])
def test_membrane_and_air_grids_equal_the_vtu_files(quadrant, label):
    solution, written, _ = quadrant
    number = solution.labels.index(label)
    stem = "".join(ch if ch.isalnum() else "_" for ch in label).strip("_")
    membrane = solution.membrane(label)
    _assert_grid_equals_file(membrane, written / f"mode_{number:03d}_{stem}.vtu")
    assert "normal_velocity_abs" in membrane.point_data
    air = solution.air(label)
    _assert_grid_equals_file(air, written / f"air_{number:03d}_{stem}.vtu")
    assert "pressure_abs" in air.point_data


def test_axisymmetric_grids_equal_the_vtu_files(tmp_path):
    solution = cf.solve(cf.load_study(QUICK, {**SMALL, "geometry.frame": "baffle"}))
    assert solution.axisymmetric
    written = solution.write(tmp_path / "run")
    label = "(2,1)a"
    number = solution.labels.index(label)
    _assert_grid_equals_file(solution.membrane(label), written / f"mode_{number:03d}_2_1_a.vtu")
    _assert_grid_equals_file(solution.air(label), written / f"air_{number:03d}_2_1_a.vtu")


def test_unknown_label_names_the_labels(quadrant):
    with pytest.raises(KeyError, match=r"no mode labelled '\(7,7\)'; labels: \(0,1\)"):
        quadrant[0].membrane("(7,7)")


def test_nothing_written_and_no_progress_unless_asked(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    messages = []
    study = cf.load_study(QUICK, {**SMALL, "geometry.frame": "baffle"})
    cf.solve(study)
    assert list(tmp_path.iterdir()) == []
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    cf.solve(study, progress=messages.append)
    assert any("prestress" in message for message in messages)


def _cli_error(capsys, argv) -> tuple[int, str]:
    code = main(argv)
    line = capsys.readouterr().err.strip()
    assert line.startswith("error: ")
    return code, line[len("error: "):]


def test_errors_are_the_cli_exceptions_and_messages(tmp_path, capsys):
    # bad input (exit 2)
    code, message = _cli_error(capsys, ["check", str(QUICK), "--set", "load.voltage=3 m"])
    assert code == 2
    with pytest.raises(cf.api.StudyError) as caught:
        cf.load_study(QUICK, {"load.voltage": "3 m"})
    assert str(caught.value) == message
    with pytest.raises(cf.api.StudyError) as caught:
        cf.load_study(QUICK, ["load.voltage=3 m"])
    assert str(caught.value) == message
    # a failed solve (exit 3)
    overrides = {"geometry.frame": "baffle", "eigen.max_modes": "2"}
    code, message = _cli_error(capsys, ["solve", str(QUICK), "--out", str(tmp_path / "a"),
                                        "--quiet",
                                        *[f"--set={k}={v}" for k, v in overrides.items()]])
    assert code == 3
    with pytest.raises(cf.SolveFailed) as caught:
        cf.solve(cf.load_study(QUICK, overrides))
    assert str(caught.value) == message
    # an output folder that may not be written (exit 2), checked before anything is written
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "mine.txt").write_text("keep")
    code, message = _cli_error(capsys, ["force", str(QUICK), "--out", str(folder), "--quiet",
                                        "--points", "2"])
    assert code == 2
    curve = cf.force(cf.load_study(QUICK), voltages="2 kV", points=2)
    with pytest.raises(cf.api.OutputFolderError) as caught:
        curve.write(folder)
    assert str(caught.value) == message
    assert sorted(p.name for p in folder.iterdir()) == ["mine.txt"]
    # force's own input checks
    code, message = _cli_error(capsys, ["force", str(QUICK), "--points", "1"])
    with pytest.raises(cf.api.StudyError, match="--points = 1 is not allowed"):
        cf.force(QUICK, points=1)


def test_force_table_is_the_csv(tmp_path):
    curve = cf.force(cf.load_study(QUICK), voltages=["0 kV", "2 kV"], z_max="10 mm", points=2)
    assert list(curve.table.columns) == ["voltage_v", "z_m", "force_n"]
    assert (curve.table["force_n"] > 0).all()
    _assert_frame_equals_csv(curve.table,
                             curve.write(tmp_path / "force") / "force_displacement.csv")


def test_the_api_names_are_the_api_functions_and_no_module_is_named_like_one():
    """``copdea_fem.solve`` and its siblings are the functions of :mod:`copdea_fem.api`; no
    submodule takes an API name, and the package is a plain module (no module class)."""
    import importlib.util
    import types

    from copdea_fem import api
    package = Path(cf.__file__).parent
    modules = {path.stem for path in package.rglob("*.py")} | {
        path.name for path in package.rglob("*") if path.is_dir()}
    for name in cf.__all__:
        assert getattr(cf, name) is getattr(api, name)
        assert importlib.util.find_spec(f"copdea_fem.{name}") is None, name
        assert name not in modules, f"a module or folder of copdea_fem is named {name!r}"
    assert isinstance(cf.solve, types.FunctionType)
    assert type(cf) is types.ModuleType


def test_import_stays_light():
    code = ("import sys, copdea_fem as cf; cf.load_study; "
            "print(sorted(m for m in ('ngsolve', 'pyvista', 'pandas', 'matplotlib', 'scipy') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.strip()
    assert out == "[]"


@pytest.mark.parametrize("option, value, allowed", [
    ("alpha", "0.05", "a number in (0, 1)"), ("alpha", True, "a number in (0, 1)"),
    ("alpha", float("nan"), "a number in (0, 1)"), ("alpha", 1, "a number in (0, 1)"),
    ("fe_workers", 0, "an integer >= 1"), ("fe_workers", "two", "an integer >= 1"),
    ("fe_workers", 2.5, "an integer >= 1"), ("fe_workers", True, "an integer >= 1")])
def test_diagnose_refuses_bad_options_naming_them(option, value, allowed):
    measured = ROOT / "studies" / "measured_fe_example" / "measured.yaml"
    with pytest.raises(cf.StudyError) as error:
        cf.diagnose(measured, model="reduced", **{option: value})
    message = str(error.value)
    assert message.startswith(f"--{option.replace('_', '-')} = ") and allowed in message
