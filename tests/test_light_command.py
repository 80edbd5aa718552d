"""The baffled G1 command imports only what it needs.

pint, meshio, pyvista and pandas would add their imports to every command beside the solve;
the command writes its files without them.  matplotlib draws the PNGs on its Agg canvas
(never pyplot), and a solve without plots does not import it.  Speed itself is measured by
``python -m benchmarks.command command``."""

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from copdea_fem.vtu import VtuMesh, write_vtu

ROOT = Path(__file__).resolve().parent.parent


def test_solve_with_its_files_imports_no_pint_meshio_pyplot_or_pyvista(tmp_path):
    code = (
        "import sys\n"
        "from copdea_fem.cli import main\n"
        f"code = main(['solve', {str(ROOT / 'studies' / 'g1_z16_v2_quick.yaml')!r}, "
        f"'--set', 'geometry.frame=baffle', '--out', {str(tmp_path / 'out')!r}])\n"
        "print(code, sorted(m for m in ('pint', 'meshio', 'matplotlib.pyplot', 'pyvista', 'pandas') "
        "if m in sys.modules))\n")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               cwd=ROOT)
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.strip().splitlines()[-1] == "0 []"
    written = {path.name for path in (tmp_path / "out").iterdir()}
    assert {"modes.csv", "modes.pvd", "air.pvd", "prestress.vtu", "modes.png"} <= written


def test_vtumesh_writes_the_bytes_of_the_meshio_mesh(tmp_path):
    import meshio
    import pyvista as pv

    generator = np.random.default_rng(3)
    points = generator.random((30, 3))
    cells = generator.integers(0, 30, (12, 6))
    point_data = {"p": generator.random(30).astype(np.float32)}
    cell_data = {"pml": [generator.integers(0, 2, 12).astype(np.int8)]}
    ours = VtuMesh(points, [("wedge", cells)], point_data=point_data, cell_data=cell_data)
    write_vtu(tmp_path / "a.vtu", ours)
    write_vtu(tmp_path / "b.vtu", meshio.Mesh(points, [("wedge", cells)],
                                              point_data=point_data, cell_data=cell_data))
    assert (tmp_path / "a.vtu").read_bytes() == (tmp_path / "b.vtu").read_bytes()
    grid, read = ours.to_pyvista(), pv.read(tmp_path / "a.vtu")    # the grid the file holds
    np.testing.assert_array_equal(grid.cells, read.cells)
    np.testing.assert_array_equal(grid.points, read.points)
    np.testing.assert_array_equal(grid.point_data["p"], read.point_data["p"])
    np.testing.assert_array_equal(grid.cell_data["pml"], read.cell_data["pml"])


def test_first_shift_is_computed_once_per_region(monkeypatch):
    """BandRegion.first_shift is kept per region (the 33 band solves of the G1 command ask
    it of two regions): the same number as the search, and the search runs once."""
    from copdea_fem.fe.eigen import region as region_module

    monkeypatch.setattr(region_module, "_FIRST_SHIFTS", {})
    calls = []
    search = region_module.BandRegion._first_shift
    monkeypatch.setattr(region_module.BandRegion, "_first_shift",
                        lambda self: calls.append(1) or search(self))
    first = region_module.BandRegion(0.0, 1000.0, 50.0, 10.0, hermitian=False)
    again = region_module.BandRegion(0.0, 1000.0, 50.0, 10.0, hermitian=False)
    other = region_module.BandRegion(0.0, 1500.0, 0.0, 10.0, hermitian=True)
    assert first.first_shift() == again.first_shift() == search(first)
    assert other.first_shift() == search(other) != first.first_shift()
    assert len(calls) == 2


def test_package_versions_are_a_new_dict_each_call():
    from copdea_fem.folders import package_versions

    versions = package_versions()
    versions["numpy"] = "changed"
    assert package_versions()["numpy"] == np.__version__


def test_bare_solve_imports_neither_the_plots_nor_the_3d_engine(tmp_path):
    """Without plots the axisymmetric solve imports neither the plots (nor matplotlib or
    Pillow) nor the 3-D engine (``copdea_fem.output`` resolves its names on first use), and
    still writes its tables."""
    heavy = ("copdea_fem.output.plots", "copdea_fem.fe.quadrant.engine", "copdea_fem.fe.quadrant.fields",
             "matplotlib", "PIL")
    code = (
        "import sys\n"
        "from copdea_fem.cli import main\n"
        f"code = main(['solve', {str(ROOT / 'studies' / 'g1_z16_v2_quick.yaml')!r}, "
        "'--set', 'geometry.frame=baffle', '--set', 'output.paraview=false', "
        f"'--set', 'output.plots=false', '--out', {str(tmp_path / 'out')!r}])\n"
        f"print(code, sorted(m for m in {heavy!r} if m in sys.modules))\n")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               cwd=ROOT)
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.strip().splitlines()[-1] == "0 []"
    assert {"modes.csv", "modes.json"} <= {path.name for path in (tmp_path / "out").iterdir()}


def test_the_command_process_collects_rarely_and_freezes_what_is_left():
    """``copdea-fem`` (``console_main``): the collector's gen-0 threshold is raised for the
    command and the objects alive at its end are frozen (no final walk over them)."""
    code = ("import gc, sys\n"
            "from copdea_fem import cli\n"
            "sys.argv = ['copdea-fem', 'schema']\n"
            "code = cli.console_main()\n"
            "print(code, gc.get_threshold()[0], gc.get_freeze_count() > 1000)\n")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               cwd=ROOT)
    assert completed.returncode == 0, completed.stderr[-2000:]
    from copdea_fem.cli import COMMAND_GC_THRESHOLD
    assert completed.stdout.strip().splitlines()[-1] == f"0 {COMMAND_GC_THRESHOLD} True"


def test_bare_peer_case_runs_on_one_blas_thread_without_scipy_optimize(tmp_path):
    """The FreeFEM peer's case without files (``benchmarks/command.py`` ``command-peer``,
    bare) as the ``copdea-fem`` command runs it (``console_main``): each coupled mode's dry
    partner is evident, so scipy.optimize is never imported
    (:func:`copdea_fem.fe.modes.largest_mac_assignment`), and the OpenBLAS
    libraries loaded with one thread (:data:`copdea_fem.cli.COMMAND_BLAS_THREADS`)."""
    code = (
        "import sys\n"
        "from copdea_fem import cli\n"
        f"sys.argv = ['copdea-fem', 'solve', {str(ROOT / 'studies' / 'g1_z00_v2.yaml')!r}, "
        "'--set', 'geometry.frame=baffle', '--set', 'load.voltage=0 V', "
        "'--set', 'eigen.f_max=400 Hz', '--set', 'output.paraview=false', "
        f"'--set', 'output.plots=false', '--out', {str(tmp_path / 'out')!r}]\n"
        "code = cli.console_main()\n"
        "from threadpoolctl import threadpool_info\n"
        "threads = sorted({pool['num_threads'] for pool in threadpool_info() "
        "if pool['internal_api'] == 'openblas'})\n"
        "print(code, 'scipy.optimize' in sys.modules, threads)\n")
    environment = {name: value for name, value in os.environ.items()
                   if name != "OPENBLAS_NUM_THREADS"}
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               cwd=ROOT, env=environment)
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.strip().splitlines()[-1] == "0 False [1]"
    with open(tmp_path / "out" / "modes.csv", newline="") as table:
        labels = [row["label"] for row in csv.DictReader(table)]
    assert labels == ["(0,1)", "(1,1)a", "(1,1)b"]


def test_identify_file_imports_no_pint(tmp_path):
    """``copdea-fem identify FILE`` on a binary export (unit labels Hz, m/s, V) reads its
    labels without pint (its import and unit registry ~0.6 s of a 2 s budget, issue 42)."""
    code = (
        "import sys\n"
        "import numpy as np\n"
        "from copdea_fem.cli import main\n"
        "from copdea_fem.measured import ScanData, write_scan\n"
        "f = np.arange(1, 201) * 2.5\n"
        "s = complex(-0.02 * 2 * np.pi * 150, 2 * np.pi * 150)\n"
        "iw = 2j * np.pi * f\n"
        "h = iw * (1 / (iw - s) + 1 / (iw - s.conjugate()))\n"
        "shape = np.array([1.0, 0.5, -0.3, 0.8, 0.2, -0.6])\n"
        "scan = ScanData(path=None, nodes=np.array([1, 2]), positions=np.eye(3)[:2],\n"
        "                channel_point=np.repeat([0, 1], 3),\n"
        "                channel_direction=np.tile(np.eye(3), (2, 1)),\n"
        "                frequencies=f, values=np.outer(shape, h))\n"
        f"path = write_scan({str(tmp_path / 'two.uff')!r}, scan, binary=True)\n"
        f"code = main(['identify', str(path), '--out', {str(tmp_path / 'out')!r}, '--quiet'])\n"
        "print(code, 'pint' in sys.modules)\n")
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               cwd=ROOT)
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.strip().splitlines()[-1] == "0 False", completed.stdout
    modes = (tmp_path / "out" / "modes.csv").read_text().splitlines()
    assert len(modes) == 2 and abs(float(modes[1].split(",")[1]) - 150) < 0.5
