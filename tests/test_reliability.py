"""Reliability: results never destroy data, every bad input and every fault ends cleanly.

Each case checks the exit code, the first line of the message, that a refusal
comes before any meshing or solving (the expensive entry points are replaced by
ones that fail the test if called; no clock) and the file system afterwards
(nothing the test made beforehand changed, no staging folder, old copy or lock
file left).  Interruptions and concurrent runs use real processes.
"""

import math
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from scan_subsets import example_copy

from copdea_fem import folders
from copdea_fem.api import SolveFailed
from copdea_fem.cli import main
from copdea_fem.fe import engines
from copdea_fem.fe.quadrant import geometry
from copdea_fem.folders import OutputFolderError
from copdea_fem.study import StudyError

ROOT = Path(__file__).resolve().parent.parent
REDUCED_STUDY = ROOT / "tests" / "reduced" / "data" / "g1_z16_2kV.yaml"   # ring model: ms
DRY_STUDY = ROOT / "studies" / "g1_z16_pumping.yaml"
EXAMPLE = ROOT / "studies" / "measured_example"
LEFTOVER_MARKS = (".staging-", ".old-", ".copdea-fem-lock")


@pytest.fixture
def work(tmp_path, monkeypatch):
    """A working folder with a user's file in it; meshing, solving and fitting fail the test."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "notes.txt").write_text("my notes\n")

    def forbidden(*args, **kwargs):
        raise AssertionError("the run did work before refusing")

    monkeypatch.setattr("copdea_fem.fe.pipeline.prepare_mesh", forbidden)
    monkeypatch.setattr("copdea_fem.fe.quadrant.geometry.generate_mesh", forbidden)
    monkeypatch.setattr("copdea_fem.fe.axisymmetric.engine.meridian_mesh", forbidden)
    monkeypatch.setattr("copdea_fem.fe.bands.BandSolver.solve", forbidden)
    monkeypatch.setattr("copdea_fem.reduced.io.build_reduced", forbidden)
    monkeypatch.setattr("copdea_fem.diagnosis.select.Diagnoser.run", forbidden)
    monkeypatch.setattr("copdea_fem.sweeps.executors.solve_point", forbidden)
    return tmp_path


def snapshot(folder: Path) -> dict:
    return {path.relative_to(folder): path.read_bytes() for path in folder.rglob("*")
            if path.is_file()}


def leftovers(folder: Path) -> list:
    return [path for path in folder.rglob("*") if any(m in path.name for m in LEFTOVER_MARKS)]


def refused(argv, folder, capsys, code=2):
    """Run the CLI expecting a refusal before any expensive stage (the ``work`` fixture
    makes them fail; no clock: the machines are loaded); return its first line."""
    before = snapshot(folder)
    assert main([str(item) for item in argv]) == code
    after = snapshot(folder)
    assert after == before, "files were written, changed or deleted"
    assert not leftovers(folder)
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


def study_file(folder: Path, text: str, name="study.yaml") -> Path:
    path = folder / name
    path.write_text(text)
    return path


# ==================================================================== the table of bad input
#
# Every new study key, command, option, API function and input format joins this table
# (docs/reliability.md): one row per case a careless, hurried or unlucky user would try,
# in the categories of the audit (CATEGORIES).  A row is run by test_the_table: CLI rows
# through main() in a working folder where meshing, solving and fitting fail the test,
# API rows by calling them; the outcome is the expected exit code (2: refused before any
# work, nothing written, one line) or exception type, and the message holds `fragment`.

#: The audit's categories of bad input and faults (every one has rows or scenario tests).
CATEGORIES = {1: "numbers as people write them", 2: "structure", 3: "physics at the edge",
              4: "files", 5: "output folders", 6: "faults", 7: "load"}
QUICK = ROOT / "studies" / "g1_z16_v2_quick.yaml"
ENCLOSURE_CYLINDER = ROOT / "studies" / "g1_enclosure_cylinder.yaml"


@dataclass(frozen=True)
class Case:
    """One row: what a user does and what must come of it.

    ``argv``: command-line words (``{work}`` and ``{root}`` filled in), or ``api``: a call
    ``api(work)``.  ``expect``: the exit code, or the exception type the call raises (a
    documented one), or ``None``: the call returns normally and ``fragment`` is in its
    returned text.  ``files``: written into the working folder first (name -> text or
    bytes); ``setup(work)`` and ``patch(monkeypatch)`` prepare anything else (a fault).
    """

    id: str
    category: int
    fragment: str
    argv: tuple = ()
    api: Callable | None = None
    expect: int | type | None = 2
    files: dict = field(default_factory=dict)
    setup: Callable | None = None
    patch: Callable | None = None


def _edited(section, key, value, path=QUICK, overrides=None):
    """A study loaded through the API and then changed: a typed copy
    (:func:`dataclasses.replace` of one section), checked as a file is."""
    import dataclasses

    import copdea_fem as cf
    study = cf.load_study(path, overrides or {"geometry.frame": "baffle"})
    changed = dataclasses.replace(getattr(study, section), **{key: value})
    return dataclasses.replace(study, **{section: changed})


def _assigned(how):
    """The error of a hand edit of a loaded study: frozen, so Python refuses it."""
    import dataclasses
    import warnings

    import copdea_fem as cf
    study = cf.load_study(QUICK)
    try:
        if how == "item":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DeprecationWarning)
                study["load"]["voltage"] = 5.0
        else:
            study.load.voltage = 5.0
    except (TypeError, dataclasses.FrozenInstanceError) as error:
        return f"{type(error).__name__}: {error}"
    return "changed"


def _solve(study):
    import copdea_fem as cf
    return cf.solve(study)


def _load(overrides):
    import copdea_fem as cf
    return lambda work: cf.load_study(QUICK, overrides)


def _loaded(overrides, dotted):
    """The SI value of ``dotted`` in the quick study with ``overrides``, as text."""
    import copdea_fem as cf
    return lambda work: f"{dotted} = {cf.load_study(QUICK, overrides).get(dotted)!r}"


def _netgen_fails(monkeypatch):
    from netgen.libngpy._meshing import NgException

    def meshing(*args, **kwargs):
        raise NgException("meshing failed")
    monkeypatch.setattr("copdea_fem.fe.axisymmetric.engine.meridian_mesh", meshing)


def _fails_with(error):
    def patch(monkeypatch):
        def run_solve(*args, **kwargs):
            raise error()
        monkeypatch.setattr("copdea_fem.fe.pipeline.run_solve", run_solve)
    return patch


def _ale_error():
    from copdea_fem.fe.ale import MeshMotionError
    return MeshMotionError("the air mesh following the membrane is inverted")


def _residual_error():
    from copdea_fem.fe.eigen import EigenResidualError
    return EigenResidualError("2 eigenpair(s) above residual_tol=1e-06")


def _modes_error():
    from copdea_fem.fe.eigen import TooManyModesError
    return TooManyModesError("the band holds 300 eigenpairs, more than max_modes=200")


def _api():
    import copdea_fem
    return copdea_fem


def _copy_example(work):
    shutil.copytree(EXAMPLE, work / "data")


def _append(name, text):
    def setup(work):
        _copy_example(work)
        path = work / "data" / name
        path.write_bytes(path.read_bytes() + text.encode())
    return setup


def _workers(value):
    from copdea_fem.parallel import check_workers
    return lambda work: f"workers = {check_workers(value, '--fe-workers')}"


def _resonances(work):
    from copdea_fem.measured import read_resonances
    path = work / "peaks.csv"
    path.write_text("freq_hz,quality_factor\n340,20\n512,30\n340,20\n")
    return f"{len(read_resonances(path))} peaks"


CALIBRATE = ("calibrate-damping", QUICK, "--set", "geometry.frame=baffle", "--set",
             "air.enabled=false", "--fit", "rayleigh", "--quality-factors", "{work}/q.csv",
             "--out", "{work}/cal")
QUALITY = "--quality-factors '{work}/q.csv' line 2: "


def _quality(text):
    return {"q.csv": text}


def _lab_file(edit=None, text_edit=None):
    """A setup writing work/lab.uff: a 4-point, 3-direction scan of one mode (60 Hz, 2 %,
    closed form), its pyuff records changed by ``edit(records)`` or its text by
    ``text_edit``."""
    def setup(work):
        import pyuff

        from copdea_fem.measured import ScanData, write_scan
        frequencies = np.arange(41) * 5.0
        omega, s = 2 * math.pi * frequencies, complex(-0.02 * 2 * math.pi * 60, 2 * math.pi * 60)
        shapes = np.random.default_rng(2).normal(size=12)
        residue = -1j * shapes / (2 * s.imag)
        values = (np.outer(residue, 1 / (1j * omega - s)) + np.outer(
            residue.conj(), 1 / (1j * omega - s.conjugate()))) * 1j * omega
        positions = np.column_stack([np.linspace(0.02, 0.03, 4), np.linspace(0, 0.01, 4) ** 2,
                                     np.zeros(4)])
        scan = ScanData(path=Path("lab.uff"), nodes=np.arange(1, 5), positions=positions,
                        channel_point=np.repeat(np.arange(4), 3),
                        channel_direction=np.tile(np.eye(3), (4, 1)),
                        frequencies=frequencies, values=values)
        path = write_scan(work / "lab.uff", scan, binary=False)
        if edit is not None:
            records = pyuff.UFF(str(path)).read_sets()
            edit(records)
            path.unlink()
            pyuff.UFF(str(path)).write_sets(records, mode="overwrite")
        if text_edit is not None:
            path.write_text(text_edit(path.read_text()))
    return setup


def _lab_records(change):
    def edit(records):
        for record in records:
            if record["type"] == 58:
                change(record)
    return edit


def _infinity(records):
    records[5]["data"] = records[5]["data"].copy()
    records[5]["data"][3] = np.inf


def _conflicting_15(records):
    """A dataset 15 after the 2411 with the same nodes elsewhere (x = 0, 1, 2, 3 m)."""
    import pyuff
    records.insert(2, pyuff.prepare_15(node_nums=[1, 2, 3, 4], def_cs=[0] * 4, disp_cs=[0] * 4,
                                       color=[8] * 4, x=[0.0, 1.0, 2.0, 3.0], y=[0.0] * 4,
                                       z=[0.0] * 4))


def _scan_tolerance(value):
    def setup(work):
        shutil.copytree(ROOT / "studies" / "measured_scan_example", work / "data")
        path = work / "data" / "measured.yaml"
        path.write_text(path.read_text().replace("  scan: z16_v2.uff\n", "  scan: z16_v2.uff\n"
                                                 f"  scan_tolerance: {value}\n"))
    return setup


#: G1 in a baffle over a sealed cylinder (geometry.enclosure)
ENCLOSED = ("--set", "geometry.frame=baffle", "--set", "geometry.enclosure=cylinder")
BAD_STUDY_TEXT = "is not valid YAML"
CASES = [
    # 1. numbers as people write them
    *[Case(f"number {text}", 1, f"{key} = {value!r}", api=_loaded({key: text}, key),
           expect=None)
      for key, text, value in [("membrane.rayleigh_beta", "3e-6", 3e-6),
                               ("membrane.rayleigh_alpha", "5E5", 5e5),
                               ("load.voltage", "2e3", 2000.0),
                               ("load.voltage", "2e3 V", 2000.0),
                               ("load.voltage", ".5", 0.5),
                               ("load.voltage", "1_000", 1000.0),
                               ("load.voltage", "-0", 0.0),  # not -0.0
                               ("load.voltage", 1000, 1000.0)]],
    Case("number 3e-6 in a file (YAML 1.1 text)", 1, "valid study",
         argv=("check", "{work}/s.yaml"), expect=0,
         files={"s.yaml": "membrane: {rayleigh_beta: 3e-6, rayleigh_alpha: 5E5}\n"}),
    Case("number --set 3e-6", 1, "valid study",
         argv=("check", QUICK, "--set", "membrane.rayleigh_beta=3e-6"), expect=0),
    *[Case(f"numpy {kind.__name__}", 1, f"mesh.order = {value!r}",
           api=_loaded({"mesh.order": kind(2)}, "mesh.order"), expect=None)
      for kind, value in [(np.int64, 2), (np.int32, 2), (np.float32, 2)]],
    Case("numpy float32 voltage", 1, "load.voltage = 1000.0",
         api=_loaded({"load.voltage": np.float32(1000)}, "load.voltage"), expect=None),
    *[Case(f"not finite {text}", 1, "is not allowed (not a finite number)",
           argv=("check", QUICK, "--set", f"load.voltage={text}"))
      for text in ("nan", "inf", "-Infinity", ".nan", ".inf")],
    Case("numpy nan", 1, "is not allowed (not a finite number)", expect=StudyError,
         api=_load({"eigen.f_max": np.float64("nan")})),
    Case("open bound after unit conversion", 1, "geometry.frame_radius = 0.035500000000000004 "
         "is not allowed; allowed: (0.0355,",
         argv=("check", QUICK, "--set", "geometry.frame=circle", "--set",
               "geometry.frame_radius=35.5 mm")),
    Case("open bound as a bare number", 1, "geometry.frame_radius = 0.0355 is not allowed",
         argv=("check", QUICK, "--set", "geometry.frame=circle", "--set",
               "geometry.frame_radius=0.0355")),
    Case("open minimum within round-off", 1, "membrane.prestretch = 1.0000000000000002 is not "
         "allowed", api=_load({"membrane.prestretch": 1.0000000000000002}), expect=StudyError),
    Case("a bound just past", 1, "load.voltage = 100001 is not allowed; allowed: [0, 100000] V",
         argv=("check", QUICK, "--set", "load.voltage=100001")),
    Case("absurdly large", 1, "is not allowed (not a finite number)",
         argv=("check", QUICK, "--set", "load.voltage=" + "9" * 400)),
    Case("unit of the wrong dimension", 1, "(wrong unit, expected a quantity in V)",
         argv=("check", QUICK, "--set", "load.voltage=2 kg")),
    Case("an integer key given 2.5", 1, "mesh.order = 2.5 is not allowed; allowed: an integer",
         argv=("check", QUICK, "--set", "mesh.order=2.5")),
    Case("long value cut in the message", 1, "(100004 characters) is not allowed (longer than "
         "100 characters", argv=("check", "{work}/s.yaml"),
         files={"s.yaml": "load: {voltage: '" + "9" * 100_000 + " V'}\n"}),
    # 2. structure
    Case("overrides as one text", 2, "overrides = 'load.voltage=1 kV' is not allowed; allowed: "
         "a mapping", api=_load("load.voltage=1 kV"), expect=StudyError),
    Case("an override key that is no text", 2, "overrides key 42 = '1 kV' is not allowed",
         api=_load({42: "1 kV"}), expect=StudyError),
    Case("a list of overrides holding a number", 2, "overrides = 42 is not allowed",
         api=_load([42]), expect=StudyError),
    Case("hand edit: a misspelled key", 2, "load.voltag = 5000.0 is not allowed (unknown key)",
         api=lambda work: _solve(_edited("load", "z", 0.016).replace({"load.voltag": 5000.0})),
         expect=StudyError),
    Case("hand edit: text with a unit", 2, "load.voltage = 2000.0",
         api=lambda work: "load.voltage = "
         f"{_edited('load', 'voltage', '2 kV').load.voltage!r}", expect=None),
    Case("hand edit: a negative thickness", 2, "membrane.thickness = -1e-06 is not allowed",
         api=lambda work: _solve(_edited("membrane", "thickness", -1e-6)), expect=StudyError),
    Case("hand edit: order 2.5", 2, "mesh.order = 2.5 is not allowed",
         api=lambda work: _solve(_edited("mesh", "order", 2.5)), expect=StudyError),
    Case("hand edit: f_max NaN", 2, "eigen.f_max = nan is not allowed (not a finite number)",
         api=lambda work: _solve(_edited("eigen", "f_max", math.nan)), expect=StudyError),
    Case("hand edit: a key assigned", 2, "FrozenInstanceError: cannot assign to field "
         "'voltage'", api=lambda work: _assigned("attribute"), expect=None),
    Case("hand edit: an item assigned", 2, "TypeError: 'mappingproxy' object does not support "
         "item assignment", api=lambda work: _assigned("item"), expect=None),
    Case("hand edit: a section replaced", 2, "load = 5 is not allowed; allowed: a mapping",
         api=lambda work: _solve(_section_replaced()), expect=StudyError),
    Case("a study that is a dict", 2, "study = dict is not allowed",
         api=lambda work: _solve({"load": {}}), expect=StudyError),
    Case("alias in a --set value", 2, "load.z = '&a [*a]' is not allowed",
         argv=("check", REDUCED_STUDY, "--set", "load.z=&a [*a]")),
    Case("list where a scalar is expected", 2, "load.voltage = [1, 2] is not allowed",
         argv=("check", QUICK, "--set", "load.voltage=[1, 2]")),
    Case("duplicate key", 2, f"{BAD_STUDY_TEXT} (line 3, column 3): key 'voltage' is given "
         "twice, on lines 2 and 3; keep one", argv=("solve", "{work}/study.yaml"),
         files={"study.yaml": "load:\n  voltage: 2 kV\n  voltage: 3 kV\n"}),
    Case("duplicate section", 2, f"{BAD_STUDY_TEXT} (line 3, column 1): key 'load' is given "
         "twice, on lines 1 and 3; keep one", argv=("solve", "{work}/study.yaml"),
         files={"study.yaml": "load: {z: 1 mm}\nmesh: {order: 2}\nload: {voltage: 2 kV}\n"}),
    Case("alias bomb", 2, f"{BAD_STUDY_TEXT} (line 1, column 4): anchors and aliases (&a, *a) "
         "are not allowed; write the value out", argv=("solve", "{work}/study.yaml"),
         files={"study.yaml": "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, "
                "*a, *a, *a, *a]\n" + "".join(f"{c}: &{c} [{', '.join([f'*{p}'] * 9)}]\n"
                                           for p, c in zip("bcdefgh", "cdefghi"))}),
    Case("a list as the study", 2, "must hold a mapping of keys, got list",
         argv=("solve", "{work}/study.yaml"), files={"study.yaml": "- 1\n- 2\n"}),
    Case("5000-digit integer", 2, f"{BAD_STUDY_TEXT}: Exceeds the limit (4300 digits) for "
         "integer string conversion", argv=("solve", "{work}/study.yaml"),
         files={"study.yaml": "load: {voltage: " + "9" * 5000 + "}\n"}),
    Case("sweep file with an alias", 2, "anchors and aliases", argv=("sweep", "{work}/sw.yaml",
         "--out", "{work}/s"), files={"sw.yaml": f"study: {DRY_STUDY}\nmodel: dry\n"
                                      "axes: &x {load.z: [1 mm]}\n"}),
    Case("measured.yaml with a key twice", 2, "key 'base_study' is given twice",
         argv=("diagnose", "{work}/data/measured.yaml", "--out", "{work}/report"),
         setup=_append("measured.yaml", "\nbase_study: other.yaml\n")),
    # 3. physics at the edge
    Case("a membrane mesh Netgen cannot mesh (axisymmetric)", 3, "mesh.membrane_size = 1e-05 is "
         "not allowed (more than 200 elements across the membrane: Netgen cannot mesh it)",
         argv=("solve", QUICK, "--set", "geometry.frame=baffle", "--set",
               "mesh.membrane_size=0.01 mm", "--out", "{work}/r")),
    Case("a membrane mesh Netgen cannot mesh, API", 3,
         "(more than 200 elements across the membrane",
         api=_load({"geometry.frame": "baffle", "mesh.membrane_size": "0.01 mm"}),
         expect=StudyError),
    Case("a frame ring within round-off of r_o, solve", 3, "geometry.frame_radius = "
         "0.035500000000000004 is not allowed", argv=("solve", QUICK, "--set",
                                                     "geometry.frame=circle", "--set",
                                                     "geometry.frame_radius=35.5 mm", "--out",
                                                     "{work}/r")),
    Case("the same size on the 3-D engine", 3, "mesh.membrane_size = 1e-05 is not allowed "
         "(more than 200 elements across", argv=("check", QUICK, "--set",
                                                  "mesh.membrane_size=0.01 mm")),
    Case("1 nm even with --allow-large", 3, "(more than 200 elements across the membrane",
         argv=("check", DRY_STUDY, "--set", "mesh.membrane_size=1 nm", "--allow-large")),
    Case("a frame ring narrower than a mesh can hold", 3,
         "(a frame ring this narrow cannot be meshed)",
         argv=("check", QUICK, "--set", "geometry.frame=circle", "--set",
               "geometry.frame_radius=35.5000001 mm")),
    Case("--allow-large lifts the guard", 3, "valid study", expect=0,
         argv=("check", DRY_STUDY, "--set", "mesh.engine=3d", "--set",
               "mesh.membrane_size=0.1 mm", "--allow-large")),
    Case("a mesh far too fine (3-D guard)", 3, "unknowns, more than the limit of "
         f"{engines.MAX_UNKNOWNS:.3g}; allowed: a larger mesh.membrane_size",
         argv=("solve", QUICK, "--set", "mesh.membrane_size=0.1 mm", "--out", "{work}/r")),
    Case("a mesh far too fine, force", 3, "unknowns, more than the limit of",
         argv=("force", DRY_STUDY, "--set", "mesh.engine=3d", "--set",
               "mesh.membrane_size=0.1 mm", "--out", "{work}/r")),
    Case("a sweep point Netgen cannot mesh", 3, "(mesh.membrane_size = 1e-06): "
         "mesh.membrane_size = 1e-06 is not allowed (more than 200 elements across",
         argv=("sweep", "{work}/sw.yaml", "--out", "{work}/s"),
         files={"sw.yaml": f"study: {DRY_STUDY}\nmodel: dry\n"
                "axes: {mesh.membrane_size: [6 mm, 1 um]}\n"}),
    Case("touching radii", 3, "geometry.inner_radius = 0.035500000000000004 is not allowed; "
         "allowed: [0, 0.0355) m",
         argv=("check", QUICK, "--set", "geometry.inner_radius=35.5 mm")),
    # an enclosure under the membrane (docs/enclosures.md)
    Case("an enclosure rim touching the membrane's", 3, "geometry.enclosure_radius = "
         "0.035500000100000005 is not allowed (the lines meeting there cannot be meshed); "
         "allowed: equal to geometry.outer_radius",
         argv=("check", QUICK, *ENCLOSED, "--set", "geometry.enclosure_radius=35.5000001 mm")),
    Case("a hairline enclosure", 3, "geometry.enclosure_depth = 1e-07 is not allowed",
         argv=("solve", QUICK, *ENCLOSED, "--set", "geometry.enclosure_depth=0.1 um", "--out",
               "{work}/r")),
    Case("a hairline vent", 3, "geometry.enclosure_vent_radius = 1e-09 is not allowed",
         argv=("check", QUICK, *ENCLOSED, "--set", "geometry.frame=none", "--set",
               "geometry.enclosure_vent_radius=1 nm")),
    Case("a vent in a baffle", 3, "(with a baffle the enclosure replaces the lower",
         argv=("check", QUICK, *ENCLOSED, "--set", "geometry.enclosure_vent_radius=5 mm")),
    Case("a box without the square frame", 3, "geometry.enclosure = 'box' is not allowed",
         argv=("check", QUICK, *ENCLOSED, "--set", "geometry.enclosure=box")),
    Case("an enclosure past the air sphere, solve", 3, "the enclosure's farthest point "
         "(0.203126 m from the centre) must lie within 0.8", argv=("solve", QUICK, *ENCLOSED, "--set", "geometry.frame=none", "--set",
                          "geometry.enclosure_depth=0.2 m", "--out", "{work}/r")),
    Case("only the cavity's air without a cavity", 3, "air.outside = False is not allowed",
         argv=("check", QUICK, "--set", "air.outside=false")),
    Case("a modal response over a sealed box", 3, "response.method = modal is not allowed "
         "with a sealed enclosure", argv=("response", QUICK, *ENCLOSED, "--set",
                                          "response.method=modal", "--out", "{work}/r")),
    Case("a response without the outside air", 3, "air.outside = false is not allowed for "
         "`response`", argv=("response", QUICK, *ENCLOSED, "--set", "geometry.frame=none",
                             "--set", "air.outside=false", "--out", "{work}/r")),
    # 4. files
    Case("empty study file", 4, "is not allowed (empty file); allowed: a UTF-8 text file of "
         "at most 1048576 bytes", argv=("solve", "{work}/study.yaml"), files={"study.yaml": ""}),
    Case("only comments", 4, "is not allowed (only comments); allowed: a mapping of keys",
         argv=("solve", "{work}/study.yaml"), files={"study.yaml": "# only a comment\n"}),
    Case("binary study", 4, "is not allowed (a binary file)", argv=("solve", "{work}/study.yaml"),
         files={"study.yaml": b"load: {z: 1 mm}\n\0\0\0"}),
    Case("study not UTF-8", 4, "is not allowed (not UTF-8 text: byte 0xe9 at offset 21)",
         argv=("solve", "{work}/study.yaml"), files={"study.yaml": b"load: {z: 1 mm}\n# caf\xe9\n"}),
    Case("oversized study", 4, "bytes, above the limit)", argv=("solve", "{work}/study.yaml"),
         files={"study.yaml": "load: {z: 1 mm}\n" + "#" * (1 << 20)}),
    Case("a folder as the study", 4, "is not allowed (a folder, not a file)",
         argv=("check", "{work}/study.yaml"), setup=lambda work: (work / "study.yaml").mkdir()),
    Case("a missing study", 4, "is not allowed (does not exist)",
         argv=("check", "{work}/study.yaml")),
    Case("a device as the study", 4, "error: study file = '/dev/zero' is not allowed (not a "
         "regular file)", argv=("check", "/dev/zero")),
    Case("binary force CSV", 4, "is not allowed (a binary file); allowed: a UTF-8 text file of "
         "at most 67108864 bytes", argv=("fit-material", REDUCED_STUDY, "{work}/force.csv",
                                         "--out", "{work}/fit"),
         files={"force.csv": b"z_m,force_n\n\x00\x01\x02\xff"}),
    Case("empty spectrum CSV", 4, "is not allowed (empty file)",
         argv=("calibrate-damping", REDUCED_STUDY, "{work}/spectrum.csv", "--out", "{work}/cal"),
         files={"spectrum.csv": ""}),
    Case("binary measured CSV", 4, "is not allowed (a binary file)",
         argv=("diagnose", "{work}/data/measured.yaml", "--out", "{work}/report"),
         setup=lambda work: (_copy_example(work), (work / "data" / "z16_v2_spectrum.csv")
                             .write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00"))),
    Case("a duplicated peak row counts once", 4, "2 peaks", api=_resonances, expect=None),
    Case("a duplicated peak row, the warning", 4, "peaks.csv line 4 repeats line 2 (a "
         "duplicated peak): counted once", api=_resonances, expect=None),
    Case("overdamped damping ratios", 4, QUALITY + "damping_ratio = 2 is not allowed "
         "(overdamped: no oscillation, no resonance to fit); allowed: (0, 1)", argv=CALIBRATE,
         files=_quality('label,damping_ratio\n"(0,1)",2\n"(1,1)a",3\n')),
    Case("overdamped quality factor", 4, QUALITY + "quality_factor = 0.3 is not allowed "
         "(overdamped", argv=CALIBRATE, files=_quality('label,quality_factor\n"(0,1)",0.3\n')),
    Case("NaN damping ratio", 4, QUALITY + "damping_ratio = nan is not allowed",
         argv=CALIBRATE, files=_quality('label,damping_ratio\n"(0,1)",nan\n')),
    Case("negative quality factor", 4, QUALITY + "quality_factor = -20 is not allowed",
         argv=CALIBRATE, files=_quality('label,quality_factor\n"(0,1)",-20\n')),
    Case("negative freq_hz", 4, QUALITY + "freq_hz = '-5' is not allowed", argv=CALIBRATE,
         files=_quality('label,damping_ratio,freq_hz\n"(0,1)",0.01,-5\n')),
    Case("NaN freq_hz", 4, QUALITY + "freq_hz = 'nan' is not allowed", argv=CALIBRATE,
         files=_quality('label,damping_ratio,freq_hz\n"(0,1)",0.01,nan\n')),
    Case("empty label", 4, QUALITY + "label = '' is not allowed (empty)", argv=CALIBRATE,
         files=_quality('label,damping_ratio\n"",0.01\n"(0,1)",0.02\n')),
    Case("a label that is no mode label", 4, QUALITY + "label = 'first' is not allowed; "
         "allowed: a mode label", argv=CALIBRATE, files=_quality('label,damping_ratio\nfirst,0.01\n')),
    Case("damping_ratio and quality_factor disagreeing", 4, QUALITY + "damping_ratio = 0.01 "
         "and quality_factor = 10 disagree", argv=CALIBRATE,
         files=_quality('label,damping_ratio,quality_factor\n"(0,1)",0.01,10\n')),
    Case("a column twice", 4, "(damping_ratio twice)", argv=CALIBRATE,
         files=_quality('label,damping_ratio,damping_ratio\n"(0,1)",0.01,0.01\n')),
    Case("agreeing columns, a label the FE lacks", 4, "allowed: labels of the FE modes",
         argv=(*CALIBRATE, "--quiet"),
         files=_quality('label,damping_ratio,quality_factor\n"(9,9)",0.025,20\n'),
         patch=lambda monkeypatch: monkeypatch.setattr(
             "copdea_fem.damping_fit.fe_modes", lambda study: {"(0,1)": (340.0, 0.0)})),
    # 5. output folders (more in the scenario tests below)
    Case("the working folder from a study", 5, "is the working folder or a parent of it; "
         "choose a new subfolder, e.g. --out results/NAME", argv=("solve", "{work}/s.yaml"),
         files={"s.yaml": "output: {directory: '.'}\n"}),
    Case("the working folder from a study, empty", 5, "is the working folder or a parent of "
         "it", argv=("solve", "{work}/s.yaml"), files={"s.yaml": "output: {directory: ''}\n"}),
    *[Case(f"a directory outside from a study: {directory}", 5, "is outside the working folder",
           argv=("solve", "{work}/s.yaml"), files={"s.yaml": f"output: {{directory: '{directory}'}}\n"})
      for directory in ("..", "../elsewhere", "/tmp/copdea-outside")],
    Case("a parent of the working folder", 5, "is the working folder or a parent of it",
         argv=("spectrum", REDUCED_STUDY, "--out", "{work}/..")),
    Case("an existing file", 5, "notes.txt is an existing file, not a folder; choose another "
         "path", argv=("spectrum", REDUCED_STUDY, "--out", "{work}/notes.txt")),
    Case("below a file", 5, "notes.txt is a file; choose another path",
         argv=("spectrum", REDUCED_STUDY, "--out", "{work}/notes.txt/run")),
    Case("in /proc", 5, "error: output folder /proc/copdea-fem-run cannot be written",
         argv=("spectrum", REDUCED_STUDY, "--out", "/proc/copdea-fem-run")),
    Case("a folder with a user's files", 5, "is not empty and not a copdea-fem result (it holds "
         "sample_3.txt); nothing was written: choose a new or empty folder",
         argv=("spectrum", REDUCED_STUDY, "--out", "{work}/lab"),
         files={"lab/sample_3.txt": "measured on Monday"}),
    # 6. faults
    Case("Netgen fails while meshing", 6, "error: Netgen failed (meshing failed); change "
         "mesh.membrane_size, mesh.air_size or mesh.grading", expect=3,
         argv=("solve", QUICK, "--set", "geometry.frame=baffle", "--out", "{work}/r"),
         patch=_netgen_fails),
    Case("Netgen fails, API", 6, "Netgen failed (meshing failed)", expect=SolveFailed,
         api=lambda work: _solve(_edited("load", "z", 0.016)), patch=_netgen_fails),
    Case("air mesh inversion", 6, "error: the air mesh motion failed at load.z = 16 mm, "
         "load.voltage = 2000 V: the air mesh following the membrane is inverted; change "
         "air.domain_radius, mesh.membrane_size or load.z", expect=3,
         argv=("solve", QUICK, "--out", "{work}/r"), patch=_fails_with(_ale_error)),
    Case("eigen residual tolerance", 6, "eigenpair(s) above residual_tol=1e-06; change "
         "eigen.residual_tol (now 1e-06) or eigen.backend", expect=3,
         argv=("solve", QUICK, "--out", "{work}/r"), patch=_fails_with(_residual_error)),
    Case("too many modes", 6, "change eigen.max_modes (now 200) or the band "
         "eigen.f_min..eigen.f_max", expect=3, argv=("solve", QUICK, "--out", "{work}/r"),
         patch=_fails_with(_modes_error)),
    # 7. load
    Case("--fe-workers far above the cores", 7, f"workers = {os.cpu_count()}",
         api=_workers(100_000), expect=None),
    Case("--fe-workers far above the cores, the warning", 7, "--fe-workers = 100000 is more "
         f"than the {os.cpu_count()} cores of this machine: {os.cpu_count()} worker(s) used",
         api=_workers(100_000), expect=None),
    Case("--fe-workers 0", 7, "--fe-workers = '0' is not allowed; allowed: an integer >= 1",
         argv=("diagnose", "{work}/data/measured.yaml", "--fe-workers", "0", "--out",
               "{work}/report"), setup=_copy_example),
    # the execution layer's options and the API functions of fit-material, calibrate-damping,
    # synth and the measured sets
    Case("sweep --workers with --executor inline", 2, "--workers = 2 is not allowed with "
         "--executor inline (it runs in this process alone); allowed: --workers with --executor "
         "processes or dask", argv=("sweep", "{root}/studies/sweeps/coarse_reduced_grid.yaml",
                                    "--executor", "inline", "--workers", "2", "--out", "{work}/s")),
    Case("diagnose --workers with --executor inline", 2, "--workers = '2' is not allowed with "
         "--executor inline", argv=("diagnose", "{work}/data/measured.yaml", "--executor",
                                    "inline", "--workers", "2", "--out", "{work}/report"),
         setup=_copy_example),
    Case("diagnose --executor threads", 2, "--executor = 'threads' is not allowed; allowed: "
         "one of inline, processes, dask", argv=("diagnose", "{work}/data/measured.yaml",
                                                "--executor", "threads", "--out", "{work}/r"),
         setup=_copy_example),
    Case("diagnose --workers 1.5", 1, "--workers = '1.5' is not allowed; allowed: an integer "
         ">= 1", argv=("diagnose", "{work}/data/measured.yaml", "--workers", "1.5", "--out",
                       "{work}/r"), setup=_copy_example),
    Case("diagnose --fe-workers beside --workers", 2, "--fe-workers = '2' is not allowed with "
         "--workers; allowed: --workers alone", argv=("diagnose", "{work}/data/measured.yaml",
                                                      "--fe-workers", "2", "--workers", "3",
                                                      "--out", "{work}/r"),
         setup=_copy_example),
    Case("synth --seed -1", 1, "--seed = -1 is not allowed; allowed: an integer in [0, ",
         argv=("synth", QUICK, "--seed", "-1", "--out", "{work}/y")),
    Case("synth --format uff --seed -1", 1, "seed = -1 is not allowed; allowed: an integer in "
         "[0, ", argv=("synth", QUICK, "--format", "uff", "--seed", "-1", "--out", "{work}/y")),
    Case("synthesise(seed=-1), API", 1, "--seed = -1 is not allowed",
         api=lambda work: _api().synthesise(QUICK, seed=-1), expect=StudyError),
    Case("fit_material with a number for the data file, API", 2, "data file = 5 is not "
         "allowed; allowed: a file's path", api=lambda work: _api().fit_material(QUICK, 5),
         expect=StudyError),
    Case("calibrate_damping fit='bogus', API", 2, "--fit = 'bogus' is not allowed; allowed: "
         "one of modal, rayleigh, prony",
         api=lambda work: _api().calibrate_damping(QUICK, None, fit="bogus"), expect=StudyError),
    Case("load_measured of a number, API", 2, "measured file = 3 is not allowed; allowed: a "
         "file's path", api=lambda work: _api().load_measured(3), expect=StudyError),
    Case("load_measured of a folder, API", 4, "measured file = ", api=lambda work:
         _api().load_measured(work), expect=StudyError),
    # the options and keys of the vibrometer, the Dask executor and the reduced modal path
    Case("identify --max-order 0", 3, "identify max_order = 0 is not allowed; allowed: an "
         "integer in [4, 400]", argv=("identify", "{root}/studies/measured_scan_example/"
                                      "measured.yaml", "--max-order", "0", "--out", "{work}/i")),
    Case("--scheduler without dask", 2, "--scheduler = 'tcp://127.0.0.1:1' is not allowed "
         "with --executor pool", argv=("sweep", "{root}/studies/sweeps/coarse_reduced_grid.yaml",
                                       "--executor", "pool", "--scheduler", "tcp://127.0.0.1:1",
                                       "--out", "{work}/s")),
    Case("--scheduler not an address", 1, "--scheduler = 'notanaddress' is not allowed",
         argv=("sweep", "{root}/studies/sweeps/coarse_reduced_grid.yaml", "--executor", "dask",
               "--scheduler", "notanaddress", "--out", "{work}/s")),
    Case("reduced_modal with a membrane loss", 3, "response.method = 'reduced_modal' is not "
         "allowed", argv=("check", QUICK, "--set", "response.method=reduced_modal", "--set",
                          "membrane.loss_factor=0.01")),
    # lab exports read by identify FILE (no study)
    Case("identify FILE: pyuff's infinity in a 58", 4, "dataset 58 #6 (response node 2): 1 "
         "values of magnitude above 1e+307 (first 1.798e+308 at abscissa 15: how pyuff writes "
         "infinity", argv=("identify", "{work}/lab.uff", "--out", "{work}/i"),
         setup=_lab_file(_infinity)),
    Case("identify FILE: Fortran D exponents in 58 data lines", 4, "lab.uff: 1 modes",
         argv=("identify", "{work}/lab.uff", "--out", "{work}/i"), expect=0,
         setup=_lab_file(text_edit=lambda text: text.replace("e-0", "D-0"))),
    Case("identify FILE: a time history", 4, "the file holds function type 1 (time response) "
         "in 12 dataset(s) 58", argv=("identify", "{work}/lab.uff", "--out", "{work}/i"),
         setup=_lab_file(_lab_records(lambda r: r.update(func_type=1)))),
    Case("identify FILE: two references and twelve responses", 4, "(a poly-reference test) "
         "is not allowed; allowed: one reference (roving response) or one response (roving "
         "reference", argv=("identify", "{work}/lab.uff", "--out", "{work}/i"),
         setup=_lab_file(_lab_records(lambda r: r.update(ref_node=r["rsp_node"] % 2 + 1,
                                                         ref_dir=3)))),
    Case("identify FILE: --band outside the lines", 1, "--band = [300, 400] Hz is not allowed "
         "(outside the file's lines); allowed: a band within 5..200 Hz",
         argv=("identify", "{work}/lab.uff", "--band", "300", "400", "--out", "{work}/i"),
         setup=_lab_file()),
    Case("identify FILE: unit labels NONE", 4, "names no unit ('NONE' in 58 #3): their unit "
         "taken as dataset 164's units", argv=("identify", "{work}/lab.uff", "--out",
                                               "{work}/i"), expect=0,
         setup=_lab_file(_lab_records(lambda r: r.update(ordinate_axis_units_lab="NONE")))),
    Case("identify FILE: a 2411 and a conflicting 15", 4, "dataset 2411 #2 (4 nodes) and "
         "dataset 15 #3 (4 nodes) give different nodes or coordinates: 2411 #2 used, 15 #3 "
         "ignored", argv=("identify", "{work}/lab.uff", "--out", "{work}/i"), expect=0,
         setup=_lab_file(_conflicting_15)),
    Case("identify measured.yaml --band", 2, "--band = 100 200 is not allowed with a "
         "measured.yaml", argv=("identify", "{root}/studies/measured_scan_example/"
                                "measured.yaml", "--band", "100", "200", "--out", "{work}/i")),
    *[Case(f"scan_tolerance {value}", 1, f"conditions[0].scan_tolerance = {shown} is not "
           "allowed; allowed: > 0 m", api=lambda work: _api().load_measured(
               work / "data" / "measured.yaml"), expect=StudyError,
           setup=_scan_tolerance(value))
      for value, shown in (("0 mm", "'0 mm = 0 m'"), ("-3 mm", "'-3 mm = -0.003 m'"),
                           ("0", "0"))],
    # scans as labs export them: few channels, few lines, a band past the lines
    Case("identify a 1-D scan of 34 records", 4, "modes found: at least 10",
         api=lambda work: _modes_found(example_copy(work, z_only=True)), expect=None),
    Case("identify a 15-line scan", 4, "15 lines up to 237.5 Hz are not allowed for "
         "identification", argv=("identify", "{work}/scan/measured.yaml", "--out", "{work}/i"),
         setup=lambda work: example_copy(work, lines=15)),
    Case("identify a band past the scan's top", 1, "band: [150 Hz, 900 Hz] reaches past the "
         "scan's lines 150..850 Hz", api=lambda work: _modes_found(
             example_copy(work, band=(150, 900))), expect=None),
    Case("identify a band off the scan's lines", 1, "condition 'z16_v2' band = '[900 Hz, "
         "1000 Hz]' is not allowed", argv=("identify", "{work}/scan/measured.yaml", "--out",
                                           "{work}/i"),
         setup=lambda work: example_copy(work, band=(900, 1000))),
    # a condition's mode set (modes: FILE, dataset 55) in measured.yaml
    Case("modes beside scan in one condition", 2, "conditions[0].modes = 'z16_v2.uff' is not "
         "allowed; allowed: scan: or modes:, not both",
         argv=("correlate", "{work}/data/measured.yaml", "--out", "{work}/pairs"),
         setup=lambda work: _scan_condition(work, "  scan: z16_v2.uff",
                                            "  scan: z16_v2.uff\n  modes: z16_v2.uff")),
    Case("modes naming a file of FRFs", 4, "dataset 55: no mode shape (no dataset 55) is not "
         "allowed", argv=("diagnose", "{work}/data/measured.yaml", "--out", "{work}/d"),
         setup=lambda work: _scan_condition(work, "  scan: z16_v2.uff", "  modes: z16_v2.uff")),
    Case("modes naming a missing file", 4, "the file does not exist",
         argv=("correlate", "{work}/data/measured.yaml", "--out", "{work}/pairs"),
         setup=lambda work: _scan_condition(work, "  scan: z16_v2.uff", "  modes: gone.unv")),
    Case("modes with scan_directions", 2, "conditions[0].scan_directions = [0, 0, 1] is not "
         "allowed; allowed: only beside scan: FILE (a mode set's shapes lie along the file's "
         "axes)", argv=("correlate", "{work}/data/measured.yaml", "--out", "{work}/pairs"),
         setup=lambda work: _scan_condition(work, "  scan: z16_v2.uff", "  modes: modes.unv\n"
                                            "  scan_directions: [0, 0, 1]")),
    # enclosures, sealed cavities, microphones inside the air and the synthetic exports
    Case("a microphone on the enclosure's bottom", 3, "error: response.microphones: "
         "microphone 'bottom' at [0.0, 0.0, -0.02] m is not allowed (it lies on the "
         "enclosure's rigid wall)", argv=("response", ENCLOSURE_CYLINDER, "--set",
                                         "geometry.frame=none", "--set", "response.microphones"
                                         "=bottom = 0 m, 0 m, -20 mm", "--out", "{work}/r")),
    Case("a microphone on the enclosure's side wall", 3, "(it lies on the enclosure's rigid "
         "wall)", argv=("response", ENCLOSURE_CYLINDER, "--set", "geometry.frame=none", "--set",
                        "response.microphones=side = 35.5 mm, 0 m, -10 mm", "--out",
                        "{work}/r")),
    Case("a microphone on the membrane", 3, "microphone 'skin' at [0.01, 0.0, 0.0] m is not "
         "allowed (it lies on the plane z = 0 of the membrane, disc or frame)",
         argv=("response", QUICK, "--set", "geometry.frame=none", "--set",
               "response.microphones=skin = 10 mm, 0 m, 0 m", "--out", "{work}/r")),
    Case("the default microphone on the membrane", 3, "response.microphone_distance: "
         "microphone 'axis' at [0.0, 0.0, 1e-12] m is not allowed (it lies on the plane z = 0",
         argv=(
             "response", ROOT / "studies" / "g1_enclosure_box.yaml", "--set", "load.z=5 mm",
             "--set", "response.microphone_distance=1e-12 m", "--out", "{work}/r")),
    Case("response of the flat membrane", 3, "error: load.z = 0 is not allowed for `response`; "
         "allowed: > 0 m (on the flat membrane the voltage does not drive this state",
         argv=("response", ROOT / "studies" / "g1_enclosure_box.yaml", "--out", "{work}/r")),
    *[Case(f"synth --format {fmt} of the flat membrane", 3, "error: --conditions #1: load.z = "
           "0 is not allowed for `synth`; allowed: > 0 m (on the flat membrane the voltage does "
           "not drive this state", argv=("synth", ROOT / "studies" / "g1_enclosure_box.yaml",
                                         "--format", fmt, "--conditions", "load.voltage=2 kV",
                                         "--out", "{work}/y"))
      for fmt in ("csv", "uff")],
    *[Case(f"synth --format uff {option} {value}", 2, f"error: {option} = {shown} is not "
           "allowed with --format uff; allowed: its default",
           argv=("synth", QUICK, "--format", "uff", option, value, "--out", "{work}/y"))
      for option, value, shown in (("--missing", "2", "2.0"),
                                   ("--amplitude-noise", "1e9", "1000000000.0"),
                                   ("--label-fraction", "0.2", "0.2"),
                                   ("--quality-noise", "0.3", "0.3"),
                                   ("--spurious", "3", "3"))],
    Case("synth --format uff --no-spectra", 2, "--no-spectra = True is not allowed with "
         "--format uff", argv=("synth", QUICK, "--format", "uff", "--no-spectra", "--out",
                               "{work}/y")),
    Case("synthesise(file_format='uff', missing=0.5), API", 2, "--missing = 0.5 is not allowed "
         "with --format uff", api=lambda work: _api().synthesise(QUICK, file_format="uff",
                                                                missing=0.5),
         expect=StudyError),
    Case("an enclosure depth without an enclosure", 2, "geometry.enclosure_depth is ignored: "
         "geometry.enclosure = none", api=_load({"geometry.enclosure_depth": "20 mm"}),
         expect=None),
    Case("an enclosure radius on a box", 2, "geometry.enclosure_radius is ignored with "
         "geometry.enclosure = box", expect=None, api=_load({
             "geometry.frame": "square", "geometry.enclosure": "box", "load.z": "5 mm",
             "geometry.enclosure_radius": "30 mm"})),
    Case("an enclosure without air", 3, "geometry.enclosure = cylinder changes nothing with "
         "air.enabled = false", expect=None, api=_load({
             "geometry.frame": "baffle", "geometry.enclosure": "cylinder",
             "air.enabled": False})),
    # excite and statespace
    Case("excite without --target", 2, "--target is required for `excite`",
         argv=("excite", QUICK, "--out", "{work}/e")),
    Case("excite --max-ac 0", 1, "--max-ac = 0.0 is not allowed; allowed: a peak AC amplitude "
         "> 0 V", argv=("excite", QUICK, "--target", "(0,1)", "--max-ac", "0", "--out",
                        "{work}/e")),
    Case("excite --max-ac nan", 1, "--max-ac = nan is not allowed",
         argv=("excite", QUICK, "--target", "(0,1)", "--max-ac", "nan", "--out", "{work}/e")),
    Case("statespace with a membrane loss factor", 3, "membrane.loss_factor = 0.01, "
         "rayleigh_alpha = 0, rayleigh_beta = 0, prony = () are not allowed for `statespace`",
         argv=("statespace", QUICK, "--set", "membrane.loss_factor=0.01", "--out",
               "{work}/s")),
    Case("statespace without a bias", 3, "load.voltage = 0 is not allowed for `statespace`",
         argv=("statespace", QUICK, "--set", "load.voltage=0 V", "--out", "{work}/s")),
]


def _modes_found(measured) -> str:
    """``identify`` on a measured.yaml: whether at least 10 modes were found."""
    count = len(_api().identify(measured).sets[0].modes)
    return f"modes found: {'at least 10' if count >= 10 else count}"


def _scan_condition(work, old, new):
    """The bundled scan example in ``work/data`` with its condition's line ``old`` made
    ``new``."""
    data = work / "data"
    shutil.copytree(ROOT / "studies" / "measured_scan_example", data)
    manifest = data / "measured.yaml"
    text = manifest.read_text()
    assert text.count(old) == 1
    manifest.write_text(text.replace(old, new))


def _section_replaced():
    import dataclasses
    return dataclasses.replace(_edited("load", "z", 0.016), load=5)


#: Scenario tests (real processes, threads, signals, permissions) that the table cannot
#: hold, by category: test_scenarios_are_in_this_file checks they exist.
SCENARIOS = {
    5: ["test_a_read_only_output_folder_is_refused", "test_two_threads_writing_one_folder",
        "test_two_threads_claiming_one_folder_the_second_is_refused",
        "test_a_held_folder_is_refused_naming_the_holder",
        "test_a_leftover_that_cannot_be_removed_is_named_truthfully"],
    6: ["test_interrupt_in_the_write_phase_keeps_old_or_nothing",
        "test_a_fault_at_each_step_of_the_swap", "test_pool_workers_die_with_a_killed_sweep"],
    7: ["test_two_concurrent_runs_into_one_folder",
        "test_two_diagnoses_sharing_an_fe_cache_solve_an_entry_once"],
}


def test_every_category_has_cases():
    covered = {case.category for case in CASES}
    assert covered == set(CATEGORIES), set(CATEGORIES) - covered
    assert len({case.id for case in CASES}) == len(CASES), "two rows share an id"


def test_scenarios_are_in_this_file():
    assert set(SCENARIOS) <= set(CATEGORIES)
    missing = [name for names in SCENARIOS.values() for name in names if name not in globals()]
    assert not missing, missing


#: The errors the API documents (module doc of copdea_fem.api).
DOCUMENTED = (StudyError, SolveFailed, OutputFolderError)


@pytest.mark.parametrize("case", CASES, ids=[case.id for case in CASES])
def test_the_table(case, work, capsys, monkeypatch, caplog):
    for name, content in case.files.items():
        path = work / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
    if case.setup is not None:
        case.setup(work)
    if case.patch is not None:
        case.patch(monkeypatch)
    if case.api is not None:
        if case.expect is None:
            with caplog.at_level("WARNING", logger="copdea_fem"):
                text = f"{case.api(work)} | warnings: {caplog.text}"
        else:
            with pytest.raises(case.expect) as raised:
                case.api(work)
            assert isinstance(raised.value, DOCUMENTED), type(raised.value)
            text = str(raised.value)
            assert "\n" not in text
    else:
        argv = [str(item).format(work=work, root=ROOT) for item in case.argv]
        if case.expect == 0:
            assert main(argv) == 0
            captured = capsys.readouterr()
            text = captured.out + captured.err
        else:
            text = refused(argv, work, capsys, code=case.expect)
    assert case.fragment.replace("{work}", str(work)) in text, text


# ------------------------------------------------------------------ output folders

def test_diagnose_into_the_measurement_folder_is_refused(work, capsys):
    data = work / "mydata"
    shutil.copytree(EXAMPLE, data)
    line = refused(["diagnose", data / "measured.yaml", "--out", data], work, capsys)
    assert line.startswith(f"error: output folder {data} holds the input file")


def test_out_home_folder_is_refused(work, capsys, monkeypatch):
    home = work / "home"
    home.mkdir()
    monkeypatch.setenv("HOME", str(home))
    line = refused(["spectrum", REDUCED_STUDY, "--out", home], work, capsys)
    assert line == f"error: output folder {home} is the home folder; choose a new subfolder"


def test_out_the_folder_of_the_study_is_refused(work, capsys):
    folder = work / "studies"
    folder.mkdir()
    study = shutil.copy(REDUCED_STUDY, folder / "s.yaml")
    line = refused(["spectrum", study, "--out", folder], work, capsys)
    assert line == (f"error: output folder {folder} holds the input file {study}; choose another "
                    "folder for the results")


def test_out_a_folder_above_the_input_file_is_refused(work, capsys):
    deep = work / "campaign" / "day1"
    deep.mkdir(parents=True)
    data = deep / "force.csv"
    data.write_text("z_m,force_n\n0.001,0.1\n0.002,0.2\n")
    line = refused(["fit-material", REDUCED_STUDY, data, "--out", work / "campaign"], work,
                   capsys)
    assert line.startswith(f"error: output folder {work / 'campaign'} holds the input file")


def test_result_of_another_command_is_not_replaced(work, capsys):
    folder = work / "run"
    folder.mkdir()
    (folder / "force_displacement.csv").write_text("voltage_v,z_m,force_n\n")
    folders.write_manifest(folder, "force")
    line = refused(["spectrum", REDUCED_STUDY, "--out", folder], work, capsys)
    assert line == (f"error: output folder {folder} holds a force result, which a spectrum run "
                    "would replace; nothing was written: choose another folder (--out)")


def test_result_with_a_file_added_by_hand_is_not_replaced(work, capsys):
    folder = work / "run"
    folder.mkdir()
    (folder / "spectrum_average.csv").write_text("freq_hz,v_axial,v_radial\n")
    folders.write_manifest(folder, "spectrum")
    (folder / "my_analysis.ipynb").write_text("{}")
    line = refused(["spectrum", REDUCED_STUDY, "--out", folder], work, capsys)
    assert line.endswith("holds files its copdea-fem result did not write (my_analysis.ipynb); "
                         "nothing was written: move them out or choose another folder")


def test_sweep_output_directory_outside_the_working_folder_is_refused(work, capsys):
    sweep = study_file(work, f"study: {DRY_STUDY}\nmodel: dry\naxes: {{load.z: [1 mm, 2 mm]}}\n"
                       "output: {directory: /tmp/copdea-outside-sweep}\n", "sweep.yaml")
    line = refused(["sweep", sweep], work, capsys)
    assert "is outside the working folder" in line


def test_a_held_folder_is_refused_naming_the_holder(work, capsys):
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\nfrom copdea_fem.folders import claim\n"
         "with claim(sys.argv[1], 'spectrum'):\n    print('held', flush=True)\n"
         "    time.sleep(60)\n", str(work / "run")],
        cwd=work, env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        before = snapshot(work)
        assert main(["spectrum", str(REDUCED_STUDY), "--out", str(work / "run")]) == 2
        line = capsys.readouterr().err.strip()
        assert line == (f"error: output folder {work / 'run'} is being written by another "
                        f"copdea-fem run (process {holder.pid}); wait for it to finish or choose "
                        "another folder")
        assert snapshot(work) == before
    finally:
        holder.kill()
        holder.wait()


# ------------------------------------------------------------- writing, interruptions

def _default_sigint():
    """Ctrl-C acts in the child even when the tests run as a background job (a shell starts
    those with SIGINT ignored, and an ignored signal stays ignored across exec)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def cli_process(argv, cwd, delay=None, gate=None):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if delay is not None:
        env[folders.WRITE_DELAY_VARIABLE] = str(delay)
    if gate is not None:
        env[folders.WRITE_GATE_VARIABLE] = str(gate)
    return subprocess.Popen([sys.executable, "-m", "copdea_fem.cli", *map(str, argv)], cwd=cwd,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_sigint)


def wait_for_staging(folder: Path, process, timeout=60.0) -> Path:
    start = time.perf_counter()
    while time.perf_counter() - start < timeout:
        staged = [p for p in folder.glob(".*.staging-*") if (p / folders.MANIFEST).is_file()]
        if staged:
            return staged[0]
        assert process.poll() is None, process.communicate()
        time.sleep(0.05)
    raise AssertionError("no staging folder appeared")


@pytest.mark.parametrize("sign, code, previous", [
    (signal.SIGTERM, 143, False), (signal.SIGINT, 130, False), (signal.SIGTERM, 143, True)])
def test_interrupt_in_the_write_phase_keeps_old_or_nothing(tmp_path, sign, code, previous):
    out = tmp_path / "run"
    if previous:
        assert main(["spectrum", str(REDUCED_STUDY), "--out", str(out)]) == 0
    before = snapshot(tmp_path)
    process = cli_process(["spectrum", REDUCED_STUDY, "--out", out], tmp_path, delay=60)
    wait_for_staging(tmp_path, process)
    process.send_signal(sign)
    _, err = process.communicate(timeout=30)
    assert process.returncode == code
    assert err.strip().splitlines() == [f"interrupted; previous result kept in {out}"
                                        if previous else "interrupted; no result written"]
    assert snapshot(tmp_path) == before and not leftovers(tmp_path)


def interrupt_when(arguments, folder, marker: str, sign) -> tuple[int, str]:
    """Run ``copdea-fem ARGUMENTS`` in its own process group; once a stderr line holds
    ``marker`` (and half a second of work), send ``sign`` to the whole group, as a
    terminal's Ctrl-C does: ``(exit code, the rest of stderr)``."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    process = subprocess.Popen(
        [sys.executable, "-m", "copdea_fem.cli", *map(str, arguments)], cwd=folder, env=env,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        preexec_fn=_default_sigint)
    try:
        for line in process.stderr:
            if marker in line:
                break
        else:
            raise AssertionError(f"the command ended before {marker!r}: {process.wait()}")
        time.sleep(0.5)                        # the work is running
        os.killpg(process.pid, sign)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    return process.returncode, err


@pytest.mark.parametrize("sign, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)],
                         ids=["ctrl-c", "sigterm"])
def test_an_interrupted_dask_sweep_ends_in_one_line(tmp_path, sign, code):
    """A sweep on a local Dask cluster, interrupted once its tasks run: the signal goes to the
    whole process group, as a terminal's Ctrl-C does (the workers get it too).  The exit code
    is the CLI's and the one line the docs promise (docs/reliability.md) is all that follows
    on stderr: no worker's traceback, no Dask log of the closing cluster or of its cancelled
    tasks (copdea_fem.parallel.dask_client)."""
    pytest.importorskip("distributed")
    out = tmp_path / "sweep"
    code_, err = interrupt_when(
        ["sweep", ROOT / "studies" / "sweeps" / "coarse_fig11b.yaml", "--executor", "dask",
         "--workers", "1", "--out", out], tmp_path, "chains on", sign)
    assert code_ == code
    assert err.strip().splitlines() == [f"interrupted; the points finished so far are kept in "
                                        f"{out}; run the sweep again to resume"]


@pytest.mark.parametrize("sign, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)],
                         ids=["ctrl-c", "sigterm"])
def test_an_interrupted_dask_diagnosis_ends_in_one_line(tmp_path, sign, code):
    """A diagnosis whose FE solves run on a local Dask cluster (the bundled FE example, an
    empty FE cache), interrupted once the cluster is up and a solve runs, the signal to the
    whole process group (as a terminal's Ctrl-C): the CLI's exit code and its one line on
    stderr (docs/reliability.md), no "closing the cluster" progress, no worker traceback,
    no Dask log (the diagnosis hands the interrupt to the cluster's context,
    copdea_fem.parallel.dask_client), and no report written."""
    pytest.importorskip("distributed")
    out, cache = tmp_path / "report", tmp_path / "fe_cache"
    cache.mkdir()
    code_, err = interrupt_when(
        ["diagnose", ROOT / "studies" / "measured_fe_example" / "measured.yaml", "--executor",
         "dask", "--workers", "1", "--fe-cache", cache, "--out", out], tmp_path,
        "dask: local cluster at", sign)
    assert code_ == code
    assert err.strip().splitlines() == ["interrupted; no result written"]
    assert not out.exists()


def test_a_run_killed_while_writing_is_cleaned_up_by_the_next(tmp_path, capsys):
    out = tmp_path / "run"
    process = cli_process(["spectrum", REDUCED_STUDY, "--out", out], tmp_path, delay=60)
    staging = wait_for_staging(tmp_path, process)
    process.kill()
    process.communicate()
    assert staging.is_dir() and not out.exists()
    assert main(["spectrum", str(REDUCED_STUDY), "--out", str(out)]) == 0
    assert f"removed {staging.name}, an unfinished result an interrupted run left" in \
        capsys.readouterr().err
    assert (out / "spectrum_average.csv").is_file() and not leftovers(tmp_path)


def test_a_swap_cut_between_its_renames_is_restored(tmp_path):
    out = tmp_path / "run"
    assert main(["spectrum", str(REDUCED_STUDY), "--out", str(out)]) == 0
    previous = snapshot(out)
    out.rename(tmp_path / ".run.old-12345678")           # as if killed between the renames
    with folders.claim(out, "spectrum"):
        assert snapshot(out) == previous
    assert not leftovers(tmp_path)


def test_two_concurrent_runs_into_one_folder(tmp_path):
    out = tmp_path / "run"
    gate = tmp_path / "gate"        # the first run holds its write phase until the second is done
    first = cli_process(["spectrum", REDUCED_STUDY, "--out", out], tmp_path, delay=120,
                        gate=gate)
    wait_for_staging(tmp_path, first)
    second = cli_process(["spectrum", REDUCED_STUDY, "--out", out], tmp_path)
    _, err = second.communicate(timeout=60)
    gate.touch()
    assert second.returncode == 2
    assert err.strip() == (f"error: output folder {out} is being written by another copdea-fem "
                           f"run (process {first.pid}); wait for it to finish or choose another "
                           "folder")
    assert first.wait(timeout=60) == 0
    assert (out / "spectrum_average.csv").is_file() and not leftovers(tmp_path)
    manifest = folders.read_manifest(out)
    assert manifest["command"] == "spectrum" and "spectrum_average.csv" in manifest["files"]


def test_a_previous_result_is_replaced_only_by_its_own_files(tmp_path):
    out = tmp_path / "run"
    assert main(["spectrum", str(REDUCED_STUDY), "--out", str(out)]) == 0
    assert main(["spectrum", str(REDUCED_STUDY), "--out", str(out),
                 "--set", "output.plots=true"]) == 0
    assert (out / "spectrum_average.png").is_file()
    assert set(folders.read_manifest(out)["files"]) == {
        p.name for p in out.iterdir() if p.name != folders.MANIFEST}
    assert not leftovers(tmp_path)


def test_a_sweep_folder_is_marked_resumed_in_place_and_kept_from_other_commands(tmp_path,
                                                                                capsys):
    out = tmp_path / "sweep"
    argv = ["sweep", str(ROOT / "studies" / "sweeps" / "coarse_reduced_grid.yaml"), "--quiet",
            "--out", str(out)]
    assert main(argv) == 0
    assert folders.read_manifest(out)["command"] == "sweep"
    points = sorted((out / "points").iterdir())
    assert len(points) == 12
    assert all(folders.read_manifest(point)["command"] == "sweep point" for point in points)
    before = snapshot(out / "points")
    assert main(argv) == 0                                  # resumed: nothing recomputed
    assert snapshot(out / "points") == before
    capsys.readouterr()
    line = refused(["spectrum", REDUCED_STUDY, "--out", out], tmp_path, capsys)
    assert line == (f"error: output folder {out} holds a sweep result, which a spectrum run "
                    "would replace; nothing was written: choose another folder (--out)")


# ------------------------------------------------------------------- mesh cache

FORCE = ["force", str(DRY_STUDY), "--points", "2", "--voltages", "0 kV", "--z-max", "2 mm",
         *(f"--set={item}" for item in ("mesh.membrane_size=9 mm", "mesh.order=1",
                                        "mesh.curve_order=1", "geometry.frame=none",
                                        "mesh.engine=3d",   # the 3-D mesh is the cached one
                                        "prestress.z_steps=1", "output.plots=false"))]


@pytest.fixture(scope="module")
def good_cache(tmp_path_factory):
    """A mesh cache holding the one entry of :data:`FORCE`, made by a run of it."""
    folder = tmp_path_factory.mktemp("cache")
    assert main([*FORCE, "--mesh-cache", str(folder / "meshes"), "--quiet",
                 "--out", str(folder / "run")]) == 0
    return folder / "meshes"


def cached_force_run(tmp_path, capsys, good_cache, damage):
    """`force` with the cache entry of :data:`FORCE` damaged by ``damage(path)``."""
    cache = shutil.copytree(good_cache, tmp_path / "cache")
    (entry,) = cache.glob("*.vol.gz")
    damage(entry)
    assert main([*FORCE, "--mesh-cache", str(cache), "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith(f"mesh cache entry {entry} is damaged (") and \
        err[0].endswith("discarded, meshing again")
    assert geometry._cache_problem(entry) is None          # re-meshed and stored again
    assert (tmp_path / "b" / "force_displacement.csv").is_file() and not leftovers(tmp_path)
    return err[0]


def test_truncated_cache_file_is_meshed_again(tmp_path, capsys, good_cache):
    def truncate(path):
        path.write_bytes(path.read_bytes()[:1000])
    line = cached_force_run(tmp_path, capsys, good_cache, truncate)
    assert "(1000 bytes, the sidecar says" in line


def test_empty_cache_file_is_meshed_again(tmp_path, capsys, good_cache):
    line = cached_force_run(tmp_path, capsys, good_cache, lambda p: p.write_bytes(b""))
    assert "(0 bytes, the sidecar says" in line


def test_random_cache_file_is_meshed_again(tmp_path, capsys, good_cache):
    def scramble(path):
        path.write_bytes(os.urandom(path.stat().st_size))
    line = cached_force_run(tmp_path, capsys, good_cache, scramble)
    assert "(SHA-256 differs from the sidecar)" in line


def test_cache_entry_without_sidecar_is_meshed_again(tmp_path, capsys, good_cache):
    def drop_sidecar(path):
        geometry._sidecar(path).unlink()
    line = cached_force_run(tmp_path, capsys, good_cache, drop_sidecar)
    assert "(no valid sidecar with its size and SHA-256)" in line


def test_cache_location(tmp_path, monkeypatch):
    monkeypatch.setenv(geometry.CACHE_VARIABLE, str(tmp_path / "c"))
    assert geometry.mesh_cache_dir() == tmp_path / "c"
    monkeypatch.delenv(geometry.CACHE_VARIABLE)
    assert geometry.mesh_cache_dir() == ROOT / "meshes"      # a source checkout
    monkeypatch.setattr(geometry, "__file__", str(tmp_path / "site-packages" / "copdea_fem"
                                                  / "fe" / "quadrant" / "geometry.py"))
    import platformdirs
    assert geometry.mesh_cache_dir() == Path(platformdirs.user_cache_dir("copdea-fem")) / "meshes"


# ------------------------------------------------------------------- input files


def test_unreadable_study_is_refused(work, capsys, monkeypatch):
    path = study_file(work, "load: {z: 1 mm}\n")

    class Denied(type(path)):
        def read_bytes(self):
            raise PermissionError(13, "Permission denied")
    monkeypatch.setattr("copdea_fem.inputs.Path", Denied)   # root reads any file: simulate
    line = refused(["check", path], work, capsys)
    assert line.startswith("error: study file = ") and \
        "is not allowed (cannot be read: Permission denied)" in line


# -------------------------------------------------------------- resource guard


def test_bundled_studies_pass_the_guard():
    from copdea_fem.study import load_study
    for path in sorted((ROOT / "studies").glob("*.yaml")):
        study = load_study(path)
        engines.check_size(study, engine=engines.engine_for(study))


# -------------------------------------------------------------- solver failures


def test_version(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith("copdea-fem ")


def test_leftover_cleaning_spares_look_alike_folders(tmp_path):
    """Only folders named as result_directory names them are cleaned: a user's
    ``.out.staging-notes`` and an ``.out.old-<8 hex>`` without a manifest stay."""
    from copdea_fem.folders import claim

    target = tmp_path / "out"
    mine_staging = tmp_path / ".out.staging-0123abcd"
    look_alikes = [tmp_path / ".out.staging-notes", tmp_path / ".out.old-89abcdef"]
    for folder in [mine_staging, *look_alikes]:
        folder.mkdir()
        (folder / "data.txt").write_text("keep")
    with claim(target, "solve"):
        pass
    assert not mine_staging.exists()
    assert all((folder / "data.txt").read_text() == "keep" for folder in look_alikes)


# ------------------------------------------------------------------- FE cache (issue 22)

def fake_fe(monkeypatch, seconds=0.0):
    """FEModel._solve replaced by a counted stand-in taking ``seconds``: returns the list
    of keys solved (one item per solve, from any thread)."""
    from copdea_fem.diagnosis import fe

    solved = []

    def solve(self, run, key, merge_pairs=True):
        time.sleep(seconds)
        solved.append(key)
        self.solves += 1
        return fe.FEResult((fe.FEMode("(0,1)", "axisymmetric", 505.8),
                            fe.FEMode("(1,1)", "non-axisymmetric", 511.6, 0.01)),
                           "axisymmetric", False, seconds, key)
    monkeypatch.setattr(fe.FEModel, "_solve", solve)
    return solved


def fe_entry(cache: Path, monkeypatch) -> tuple:
    """A good cache entry of :data:`DRY_STUDY` written by a (fake) solve: (study, path)."""
    from copdea_fem.diagnosis import fe
    from copdea_fem.study import load_study
    study = load_study(DRY_STUDY)
    fake_fe(monkeypatch)
    result = fe.FEModel(cache_dir=cache).modes(study)
    return study, cache / f"{result.key}.json"


@pytest.mark.parametrize("damage, problem", [
    (lambda d: d["modes"][0].update(frequency_hz="abc"),
     "modes[0].frequency_hz = 'abc', not a finite number > 0"),
    (lambda d: d["modes"][1].update(damping_ratio=float("nan")), "NaN is not a finite number"),
    (lambda d: d["modes"][0].update(frequency_hz=float("inf")),
     "Infinity is not a finite number"),
    (lambda d: d["modes"][0].update(frequency_hz=True), "modes[0].frequency_hz = True"),
    (lambda d: d["modes"][0].update(label=7), "modes[0].label = 7, not a label"),
    (lambda d: d["modes"][0].pop("kind"), "modes[0] is not an object with keys"),
    (lambda d: d.update(modes={"(0,1)": 505.8}), "modes is not a list"),
    (lambda d: d.update(coupled="no"), "coupled = 'no', not true or false"),
    (lambda d: d.pop("engine"), "no 'engine'"),
    (lambda d: d.update(seconds=-1), "seconds = -1, not a finite number >= 0"),
    (lambda d: d.clear() or d.update(modes=[]), "no 'engine', 'coupled', 'seconds'"),
], ids=["text frequency", "NaN", "Infinity", "bool", "label type", "missing kind",
        "modes dict", "coupled text", "no engine", "negative seconds", "keys missing"])
def test_a_damaged_fe_cache_entry_is_solved_again_and_replaced(tmp_path, monkeypatch, caplog,
                                                               damage, problem):
    import json

    from copdea_fem.diagnosis import fe
    study, path = fe_entry(tmp_path / "cache", monkeypatch)
    good = json.loads(path.read_text())
    document = json.loads(path.read_text())
    damage(document)
    path.write_text(json.dumps(document))
    solved = fake_fe(monkeypatch)
    model = fe.FEModel(cache_dir=tmp_path / "cache")
    with caplog.at_level("WARNING", logger="copdea_fem.diagnosis.fe"):
        result = model.modes(study)
    assert len(solved) == 1                                  # solved again ...
    assert all(isinstance(m.frequency_hz, float) for m in result.modes)
    assert json.loads(path.read_text()) == good             # ... and replaced
    warnings = [r.getMessage() for r in caplog.records]
    assert len(warnings) == 1 and "\n" not in warnings[0]
    assert warnings[0].startswith(f"FE cache entry {path} is damaged (") and problem in \
        warnings[0] and warnings[0].endswith("); solving it again and replacing it")
    assert fe.FEModel(cache_dir=tmp_path / "cache").modes(study) == result and len(solved) == 1


def test_fe_cache_option_naming_a_file_is_refused_before_work(work, capsys):
    data = work / "data"
    shutil.copytree(EXAMPLE, data)
    line = refused(["diagnose", data / "measured.yaml", "--fe-cache", work / "notes.txt",
                    "--out", work / "report"], work, capsys)
    assert line == (f"error: --fe-cache = '{work / 'notes.txt'}' is not allowed (an existing "
                    "file, not a folder); allowed: a folder (created when missing)")
    line = refused(["diagnose", data / "measured.yaml", "--fe-cache",
                    work / "notes.txt" / "fe", "--out", work / "report"], work, capsys)
    assert f"is not allowed ({work / 'notes.txt'} is an existing file)" in line


def test_fe_cache_variable_naming_a_file_is_ignored_with_a_warning(tmp_path, monkeypatch,
                                                                   caplog):
    from copdea_fem.diagnosis import fe
    from copdea_fem.study import load_study
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    monkeypatch.setenv(fe.CACHE_VARIABLE, str(notes))
    solved = fake_fe(monkeypatch)
    with caplog.at_level("WARNING", logger="copdea_fem.diagnosis.fe"):
        model = fe.FEModel()
        model.modes(load_study(DRY_STUDY))
    assert [r.getMessage() for r in caplog.records] == [
        f"FE cache {notes} ignored (an existing file, not a folder); FE solves are kept in "
        "memory only"]
    assert len(solved) == 1 and notes.read_text() == "my notes\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_an_unwritable_fe_cache_never_fails_a_diagnosis(tmp_path, monkeypatch, caplog):
    """The folder turns into a file after the model was made (or cannot be written)."""
    from copdea_fem.diagnosis import fe
    from copdea_fem.study import load_study
    cache = tmp_path / "cache"
    model = fe.FEModel(cache_dir=cache)
    cache.write_text("now a file\n")
    solved = fake_fe(monkeypatch)
    with caplog.at_level("WARNING", logger="copdea_fem.diagnosis.fe"):
        result = model.modes(load_study(DRY_STUDY))
    assert len(solved) == 1 and result.modes and cache.read_text() == "now a file\n"
    assert all(str(cache) in r.getMessage() for r in caplog.records) and caplog.records


def test_two_diagnoses_sharing_an_fe_cache_solve_an_entry_once(tmp_path, monkeypatch):
    """Two runs (threads here; the lock is per open file, as between processes) need the
    same entry at once: the second waits for the first's <key>.lock and reads its entry."""
    import threading

    from copdea_fem.diagnosis import fe
    from copdea_fem.study import load_study
    study = load_study(DRY_STUDY)
    solved = fake_fe(monkeypatch, seconds=1.0)
    results = []

    def diagnose():
        results.append(fe.FEModel(cache_dir=tmp_path / "cache").modes(study))
    runs = [threading.Thread(target=diagnose) for _ in range(2)]
    for run in runs:
        run.start()
        time.sleep(0.1)
    for run in runs:
        run.join(timeout=30)
    assert len(solved) == 1 and len(results) == 2 and results[0] == results[1]
    assert sorted(p.name for p in (tmp_path / "cache").iterdir()) == [f"{results[0].key}.json"]


def test_an_fe_cache_entry_locked_too_long_is_solved_here(tmp_path, monkeypatch, caplog):
    import fcntl

    from copdea_fem.diagnosis import fe
    from copdea_fem.study import load_study
    study = load_study(DRY_STUDY)
    solved = fake_fe(monkeypatch)
    key = fe.fe_key(fe.fe_study(study))
    (tmp_path / "cache").mkdir()
    holder = os.open(tmp_path / "cache" / f"{key}.lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(holder, fcntl.LOCK_EX)                   # a hung run holding the entry
    os.write(holder, b"4242\n")
    try:
        start = time.perf_counter()
        with caplog.at_level("WARNING", logger="copdea_fem.diagnosis.fe"):
            fe.FEModel(cache_dir=tmp_path / "cache", lock_wait=0.5).modes(study)
        assert time.perf_counter() - start >= 0.5     # waited lock_wait, then went on
    finally:
        os.close(holder)
    assert len(solved) == 1 and (tmp_path / "cache" / f"{key}.json").is_file()
    assert [r.getMessage() for r in caplog.records] == [
        f"FE cache entry {tmp_path / 'cache' / key}.json is still being computed by process "
        "4242 after 0.5 s; solving it here too"]


# ------------------------------------------------------------- paths in messages (issue 22)

def test_a_missing_data_file_is_named_whole_in_the_refusal(work, capsys):
    """A path above the 60-character preview of other values is shown whole."""
    data = work / "a_campaign_folder_with_a_rather_long_name" / "day_1"
    shutil.copytree(EXAMPLE, data)
    (data / "z16_v2_resonances.csv").rename(data / "z16_v2_resonances_moved.csv")
    path = data / "z16_v2_resonances.csv"
    assert len(repr(str(path))) > 60
    line = refused(["diagnose", data / "measured.yaml", "--out", work / "report"], work, capsys)
    assert line.startswith(f"error: conditions[1].resonances = {str(path)!r} is not allowed "
                           "(file does not exist)"), line


def test_the_path_preview_keeps_the_name_and_the_limit():
    from pathlib import PurePosixPath

    from copdea_fem.inputs import preview
    short = PurePosixPath("/data/z16.csv")
    assert preview(short) == "'/data/z16.csv'"
    deep = PurePosixPath("/" + "campaign/" * 20 + "z16_v2_resonances.csv")
    assert preview(deep) == repr(str(deep))                  # whole, not cut in the middle
    deeper = PurePosixPath("/" + "campaign/" * 60 + "z16_v2_resonances.csv")
    shown = preview(deeper)                                  # above PATH_CHARACTERS: cut
    assert shown.endswith(f".../z16_v2_resonances.csv' ({len(str(deeper))} characters)")
    assert len(shown.split(" (")[0]) == 500
    name = "n" * 600 + ".csv"                                # a name longer than the width
    assert preview(PurePosixPath("/d/" + name)) == f"'.../{name}' ({len(name) + 3} characters)"
    assert preview("x" * 100).endswith("... (102 characters)")   # other values: as before


# ------------------------------------------------------ response.* in the schema (issue 22)

BAD_MICROPHONES = [
    ("side = 0.5 m, 0 m", "", "(cannot read 'side = 0.5 m, 0 m')"),
    ("side = 0.5 m, 0 m, 1 m; side = 1 m, 0 m, 1 m", "", "(microphone 'side' repeated)"),
    ("axis = 1 m, 0 m, 1 m", "", "(microphone 'axis' repeated)"),
    ("side = 0.5 kg, 0 m, 1 m", "", "wrong unit, expected a quantity in m"),
    ("centre = 0, 0, 0", "", "(microphone 'centre' at the origin)"),
    ("low = 0.5 m, 0 m, 0 m", "geometry.frame=baffle",
     "(microphone 'low' at z = 0 lies on the rigid plane (position [0.5, 0.0, 0.0] m))"),
]


@pytest.mark.parametrize("command", ["check", "response"])
@pytest.mark.parametrize("microphones, extra, fragment", BAD_MICROPHONES,
                         ids=["two coordinates", "same name twice", "axis again", "not a length",
                              "at the origin", "on the baffle"])
def test_bad_microphones_are_refused_before_any_work(work, capsys, monkeypatch, command,
                                                     microphones, extra, fragment):
    def forbidden(*args, **kwargs):
        raise AssertionError("the run did work before refusing")
    monkeypatch.setattr("copdea_fem.forced_response.run.prepare_order_zero", forbidden)
    sets = ["--set", f"response.microphones={microphones}"] + (["--set", extra] if extra else [])
    out = ["--out", work / "r"] if command == "response" else []
    line = refused([command, ROOT / "studies" / "g1_z16_v2_quick.yaml", *sets, *out], work,
                   capsys)
    assert line.startswith("error: response.microphones = ") and fragment in line, line


# ------------------------------------------------- faults and signals in the swap (issue 22)

def is_new(out: Path) -> bool:
    """``out`` holds the complete result of the run at load.voltage = 1 kV."""
    from copdea_fem.study import load_study
    saved = load_study(out / "reduced_study.resolved.yaml")
    return saved.load.voltage == 1000.0 and set(folders.read_manifest(out)["files"]) == {
        p.name for p in out.iterdir() if p.name != folders.MANIFEST}


def swap_fault(monkeypatch, step, fault):
    """Make one step of the swap of ``run`` fail with ``fault`` (an exception instance):
    aside (run -> .run.old-*), in (.run.staging-* -> run), back (the previous result put
    back after a failed 'in'), remove (deleting the old copy: after its first file)."""
    real_rename, real_unlink = os.rename, os.unlink
    calls = {"unlink": 0}

    def rename(source, destination, *args, **kwargs):
        source, destination = Path(source), Path(destination)
        kind = ("aside" if destination.name.startswith(".run.old-") else
                "in" if source.name.startswith(".run.staging-") else
                "back" if source.name.startswith(".run.old-") else None)
        if kind == step or (step == "back" and kind == "in"):
            raise fault
        return real_rename(source, destination, *args, **kwargs)

    def unlink(path, *args, **kwargs):
        if step == "remove" and Path(path).parent.name.startswith(".run.old-"):
            calls["unlink"] += 1
            if calls["unlink"] == 2:
                raise fault
        return real_unlink(path, *args, **kwargs)
    monkeypatch.setattr(folders.os, "rename", rename)
    monkeypatch.setattr(folders.os, "unlink", unlink)


@pytest.mark.parametrize("step", ["aside", "in", "back", "remove"])
@pytest.mark.parametrize("fault", ["oserror", "interrupt"])
def test_a_fault_at_each_step_of_the_swap(tmp_path, capsys, monkeypatch, caplog, step, fault):
    """Whatever step fails, ``run`` holds a complete result (the previous or the new one),
    the message (one line) says which and where, and any old copy left is named there and
    removed by the next run."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run"
    assert main(["spectrum", str(REDUCED_STUDY), "--out", str(out)]) == 0
    previous = snapshot(out)
    argv = ["spectrum", str(REDUCED_STUDY), "--out", str(out), "--set", "load.voltage=1 kV"]
    capsys.readouterr()
    error = OSError(5, "Input/output error (injected)") if fault == "oserror" else \
        KeyboardInterrupt()
    with monkeypatch.context() as patched:
        swap_fault(patched, step, error)
        code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    old = sorted(tmp_path.glob(".run.old-*"))
    if step in ("aside", "in"):                         # the previous result back in place
        assert snapshot(out) == previous and not leftovers(tmp_path)
        where = f"previous result kept in {out}"
    elif step == "back":                                # it stays beside, named, put back
        assert not out.exists() and len(old) == 1 and snapshot(old[0]) == previous
        where = f"previous result kept in {old[0]} (the next run into {out} puts it back)"
    else:                                               # the new result is in place
        assert is_new(out) and len(old) == 1
        assert (old[0] / folders.MANIFEST).is_file()    # the manifest goes last
        where = f"the result in {out} is complete"
    if step == "remove" and fault == "oserror":         # a warning; the run succeeded
        assert code == 0 and [r.getMessage() for r in caplog.records] == [
            f"the previous result {old[0]} was not removed (Input/output error (injected)); "
            f"the next run into {out} tries again (or delete it)"]
    elif fault == "oserror":
        assert code == 1 and err == [f"error: output folder {out}: the result could not be "
                                     f"written (Input/output error (injected)); {where}"]
    else:
        assert code == 130 and len(err) == 1 and err[0].startswith(f"interrupted; {where}")
    if step == "remove" and fault == "interrupt":
        assert err[0].endswith(f"; the rest of the previous result, {old[0]}, is removed by "
                               "the next run into it (or delete it)")
    assert main(argv) == 0                              # the next run tidies up
    assert is_new(out) and not leftovers(tmp_path)


def test_a_signal_during_the_swap_is_acted_on_after_it(tmp_path, capsys, monkeypatch):
    """SIGTERM from another thread (as from NGSolve's or BLAS's, which a signal mask of
    the main thread does not cover) while the new result is moved in: the swap finishes,
    then the run ends with 143 saying the new result is complete; no old copy is left."""
    import threading
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run"
    assert main(["spectrum", str(REDUCED_STUDY), "--out", str(out)]) == 0
    capsys.readouterr()
    real_rename = os.rename
    go, sent = threading.Event(), threading.Event()

    def send():                  # a thread started before the swap: its signal mask is open
        go.wait(30)
        os.kill(os.getpid(), signal.SIGTERM)
        sent.set()
    sender = threading.Thread(target=send, daemon=True)
    sender.start()

    def rename(source, destination, *args, **kwargs):
        if Path(source).name.startswith(".run.staging-"):
            go.set()
            sent.wait(30)
            time.sleep(0.2)                             # the handler's chance to run here
        return real_rename(source, destination, *args, **kwargs)
    monkeypatch.setattr(os, "rename", rename)
    code = main(["spectrum", str(REDUCED_STUDY), "--out", str(out), "--set",
                 "load.voltage=1 kV"])
    sender.join(5)
    assert capsys.readouterr().err.strip().splitlines() == [
        f"interrupted; the result in {out} is complete"]
    assert code == 143 and is_new(out) and not leftovers(tmp_path)


# ------------------------------------------------------- pool sweep workers (issue 22)

SLOW_SWEEP = """\
# The CLI with every sweep point slowed down by {delay} s; the pool's spawned workers run this
# file's top level too (as __mp_main__), so their points are slowed as well.
import sys
import time

import copdea_fem.sweeps.executors as executors

_solve_point = executors.solve_point


def slow_solve_point(*args, **kwargs):
    time.sleep({delay})
    return _solve_point(*args, **kwargs)


executors.solve_point = slow_solve_point

if __name__ == "__main__":
    from copdea_fem.cli import main
    sys.exit(main(sys.argv[1:]))
"""


def children_of(pid: int) -> list:
    """Process ids whose parent is ``pid`` (from /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def running(pid: int) -> bool:
    """The process exists and is not a zombie (a container's init may not reap one)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def finished_points(out: Path) -> set:
    return {p.name for p in (out / "points").glob("*") if (p / "result.json").is_file()}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_pool_workers_die_with_a_killed_sweep(tmp_path):
    """SIGKILL to a `sweep --executor pool --workers 2` after its first point: no worker
    (nor the resource tracker) lives on, and no point folder appears afterwards."""
    script = tmp_path / "slow_sweep.py"
    script.write_text(SLOW_SWEEP.format(delay=1.0))
    out = tmp_path / "sweep"
    process = subprocess.Popen(
        [sys.executable, str(script), "sweep",
         str(ROOT / "studies" / "sweeps" / "coarse_reduced_grid.yaml"), "--executor", "pool",
         "--workers", "2", "--quiet", "--out", str(out)], cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE)
    children = []
    try:
        start = time.perf_counter()
        while not finished_points(out):
            assert process.poll() is None, process.communicate()
            assert time.perf_counter() - start < 120, "no point written"
            time.sleep(0.05)
        children = children_of(process.pid)
        assert len(children) >= 2                       # two workers (and the tracker)
        process.kill()
        process.wait()
        time.sleep(1.0)
        at_kill = finished_points(out)
        assert len(at_kill) < 12
        time.sleep(3.0)                                 # three more points each, were they alive
        assert [pid for pid in children if running(pid)] == []
        assert finished_points(out) == at_kill
    finally:
        if process.poll() is None:
            process.kill()
        for pid in children:
            if running(pid):
                os.kill(pid, signal.SIGKILL)


def test_two_threads_claiming_one_folder_the_second_is_refused(tmp_path):
    """A claim is re-entrant within its own thread only: a second thread of the same
    process (two API calls at once) is refused like another process, and the first
    thread's writer below its claim still takes it."""
    import threading
    import time

    target, seen = tmp_path / "out", []
    held = threading.Event()

    def first():
        with folders.claim(target, "solve"):
            held.set()
            with folders.result_directory(target, "solve") as staging:   # below the claim
                (staging / "a.txt").write_text("a")
            time.sleep(0.3)

    def second():
        held.wait()
        try:
            with folders.claim(target, "solve"):
                seen.append("claimed")
        except folders.OutputFolderError as error:
            seen.append(str(error))

    threads = [threading.Thread(target=first), threading.Thread(target=second)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(seen) == 1 and "is being written by another copdea-fem run" in seen[0]
    assert (target / "a.txt").read_text() == "a"
    with folders.claim(target, "solve"):          # released: claimed again
        pass


def test_two_threads_writing_one_folder(tmp_path, monkeypatch):
    """Two threads of one process writing one result at once (two API ``write`` calls): the
    second is refused with OutputFolderError while the first holds the folder, always (the
    first is held inside its write phase by the test gate, whatever the machine's load),
    and the first writes its result."""
    import threading

    import copdea_fem as cf
    from copdea_fem.api import ForceCurve

    study = cf.load_study(DRY_STUDY, {"output.plots": False})
    curve = ForceCurve(study, np.array([0.0, 1e-3]), [0.0], np.array([[0.0, 0.1]]))
    out, gate = tmp_path / "same", tmp_path / "gate"
    monkeypatch.setenv(folders.WRITE_DELAY_VARIABLE, "60")
    monkeypatch.setenv(folders.WRITE_GATE_VARIABLE, str(gate))
    first = threading.Thread(target=curve.write, args=(out,))
    first.start()
    try:
        deadline = time.monotonic() + 60
        while not list(tmp_path.glob(".same.staging-*")) and time.monotonic() < deadline:
            time.sleep(0.01)
        with pytest.raises(OutputFolderError, match="is being written by another copdea-fem run"):
            curve.write(out)
    finally:
        gate.write_text("")
        first.join()
    assert (out / "force_displacement.csv").is_file() and not leftovers(tmp_path)


def _without_dac(argv) -> list:
    """``argv`` run without root's permission bypass (setpriv drops CAP_DAC_OVERRIDE and
    CAP_DAC_READ_SEARCH from the bounding set, so the new process never has them)."""
    if os.geteuid() != 0:
        return list(argv)
    return [SETPRIV, "--bounding-set=-dac_override,-dac_read_search", *argv]


SETPRIV = shutil.which("setpriv")
NO_SETPRIV = os.name != "posix" or (os.geteuid() == 0 and (
    SETPRIV is None or subprocess.run([SETPRIV, "--bounding-set=-dac_override", "true"],
                                      capture_output=True).returncode != 0))


def _spectrum_run(work: Path, out: Path) -> subprocess.CompletedProcess:
    return subprocess.run(_without_dac([sys.executable, "-m", "copdea_fem.cli", "spectrum",
                                        str(REDUCED_STUDY), "--out", str(out)]),
                          cwd=work, env={**os.environ, "PYTHONPATH": str(ROOT)},
                          capture_output=True, text=True, timeout=300)


@pytest.mark.skipif(NO_SETPRIV, reason="needs setpriv to run without root's permission bypass")
@pytest.mark.parametrize("previous", [False, True], ids=["empty", "holding a result"])
def test_a_read_only_output_folder_is_refused(tmp_path, previous):
    """A folder of mode 555 is refused with exit 2 before any work: not swapped for a
    writable one, no old copy left beside it, a previous result inside unchanged."""
    out = tmp_path / "ro"
    if previous:
        assert _spectrum_run(tmp_path, out).returncode == 0
    else:
        out.mkdir()
    before = snapshot(tmp_path)
    out.chmod(0o555)
    try:
        run = _spectrum_run(tmp_path, out)
        assert run.returncode == 2, run.stderr
        assert run.stderr.strip().splitlines() == [
            f"error: output folder {out} cannot be written (Permission denied); nothing was "
            "written: make it writable or choose another folder"]
        assert out.stat().st_mode & 0o777 == 0o555
    finally:
        out.chmod(0o755)
    assert snapshot(tmp_path) == before and not leftovers(tmp_path)


@pytest.mark.skipif(NO_SETPRIV, reason="needs setpriv to run without root's permission bypass")
def test_a_leftover_that_cannot_be_removed_is_named_truthfully(tmp_path):
    """An old copy a killed run left, holding a folder the run may not empty: the run
    succeeds and names the copy once as not removed (never 'removed')."""
    out = tmp_path / "r"
    assert _spectrum_run(tmp_path, out).returncode == 0
    old = tmp_path / ".r.old-0123abcd"
    shutil.copytree(out, old)
    (old / "locked").mkdir()
    (old / "locked" / "data.txt").write_text("x")
    (old / "locked").chmod(0o555)
    try:
        run = _spectrum_run(tmp_path, out)
        assert run.returncode == 0, run.stderr
        assert run.stderr.count(old.name) == 1, run.stderr
        assert f"{old} (a replaced result an earlier run left) could not be removed " \
               "(Permission denied); delete it by hand" in run.stderr
        assert "removed .r.old" not in run.stderr and old.is_dir()
    finally:
        (old / "locked").chmod(0o755)


# ------------------------------------------------------------------ correlate, synth --format uff

SCAN_EXAMPLE = ROOT / "studies" / "measured_scan_example"


def test_correlate_without_a_scan_is_refused(work, capsys):
    data = work / "data"
    shutil.copytree(EXAMPLE, data)
    line = refused(["correlate", data / "measured.yaml", "--out", work / "pairs"], work,
                   capsys)
    assert line.startswith("error: ") and "no condition names a scan" in line


@pytest.mark.parametrize("pairing, expected", [
    ("{window: 0}", "pairing.window = 0 is not allowed"),
    ("{window: 1_000 %}", "pairing.window = '1_000 %' is not allowed"),
    ("{window: .nan}", "pairing.window = nan is not allowed"),
    ("{window: 2e3 V}", "pairing.window = '2e3 V' is not allowed"),
    ("{mac_min: [0.5]}", "pairing.mac_min = [0.5] is not allowed"),
    ("{windw: 0.3}", "pairing.windw = 0.3 is not allowed (unknown key)"),
    ("0.3", "pairing = 0.3 is not allowed; allowed: a mapping"),
])
def test_bad_pairing_settings_are_refused(work, capsys, pairing, expected):
    data = work / "data"
    shutil.copytree(SCAN_EXAMPLE, data)
    manifest = data / "measured.yaml"
    manifest.write_text(manifest.read_text() + f"\npairing: {pairing}\n")
    line = refused(["correlate", manifest, "--out", work / "pairs"], work, capsys)
    assert expected in line, line


@pytest.mark.parametrize("observed, expected", [
    ("[]", "observed = [] is not allowed"),
    ("(m,1)", "observed = '(m,1)' is not allowed"),
    ("['(m,0)']", "observed[0] = '(m,0)' is not allowed"),
    ("[{m: 1}]", "observed[0] = {'m': 1} is not allowed"),
    ("[out of plane]", "observed[0] = 'out of plane' is not allowed"),
])
def test_bad_observed_families_are_refused(work, capsys, observed, expected):
    data = work / "data"
    shutil.copytree(EXAMPLE, data)
    manifest = data / "measured.yaml"
    manifest.write_text(manifest.read_text() + f"\nobserved: {observed}\n")
    line = refused(["diagnose", manifest, "--out", work / "report"], work, capsys)
    assert expected in line, line


def test_synth_uff_refuses_an_effect_the_fe_does_not_hold(work, capsys):
    line = refused(["synth", SCAN_EXAMPLE / "base_study.yaml", "--format", "uff",
                    "--effects", "spring_mass", "--out", work / "synth"], work, capsys)
    assert "--effects spring_mass is not allowed with --format uff" in line


def test_synth_uff_refuses_a_bad_frequency_noise(work, capsys):
    line = refused(["synth", SCAN_EXAMPLE / "base_study.yaml", "--format", "uff",
                    "--frequency-noise", "nan", "--out", work / "synth"], work, capsys)
    assert "frequency_noise = nan is not allowed" in line


# ------------------------------------------------------------------ correlate on too few points

def test_correlate_on_one_scan_point_warns_that_shapes_are_not_told_apart(tmp_path, capsys):
    """The bundled scan cut to one point (3 channels): the pairs are written (exit 0) but
    every one is marked (pairs.csv fe_auto_mac >= the pairing's mac_min) and a warning
    says the channels cannot tell the shapes apart; the full scan has no such warning."""
    import csv
    import dataclasses

    from copdea_fem.measured import read_scan, write_scan

    scan = read_scan(SCAN_EXAMPLE / "z16_v2.uff")
    channels = np.flatnonzero(scan.channel_point == 0)
    one = dataclasses.replace(scan, nodes=scan.nodes[:1], positions=scan.positions[:1],
                              channel_point=scan.channel_point[channels],
                              channel_direction=scan.channel_direction[channels],
                              values=scan.values[channels])
    data = tmp_path / "data"
    shutil.copytree(SCAN_EXAMPLE, data)
    write_scan(data / "z16_v2.uff", one)
    assert main(["correlate", str(data / "measured.yaml"), "--out", str(tmp_path / "pairs"),
                 "--quiet"]) == 0
    error = capsys.readouterr().err
    assert "z16_v2: the measured channels cannot tell the FE's shapes apart" in error, error
    with open(tmp_path / "pairs" / "pairs.csv", newline="") as stream:
        rows = [row for row in csv.DictReader(stream) if row["label"]]
    assert rows and all(float(row["fe_auto_mac"]) >= 0.5 for row in rows)
    assert "cannot tell the FE's shapes apart" in (tmp_path / "pairs" / "report.md").read_text()
# ------------------------------------------------------------------ enclosures that must work

def _finite_modes(folder: Path) -> np.ndarray:
    import csv
    with open(folder / "modes.csv") as handle:
        frequencies = np.array([float(row["freq_hz"]) for row in csv.DictReader(handle)])
    assert frequencies.size and np.all(np.isfinite(frequencies)), frequencies
    return np.sort(frequencies)


def test_a_bowl_at_its_default_depth_a_hemisphere_solves(tmp_path, capsys):
    # the cavity's depth is 0 at a hemisphere's rim: the air's motion was 0/0 there
    # (EigenInputError: A has non-finite entries); its modes must continue those of a
    # bowl a hair shallower
    base = [str(QUICK), "--set", "geometry.enclosure=bowl", "--set", "geometry.frame=none",
            "--quiet"]
    assert main(["solve", *base, "--out", str(tmp_path / "hemisphere")]) == 0
    assert main(["solve", *base, "--set", "geometry.enclosure_depth=35.4 mm",
                 "--out", str(tmp_path / "shallower")]) == 0
    hemisphere, shallower = (_finite_modes(tmp_path / name)
                             for name in ("hemisphere", "shallower"))
    assert hemisphere.size == shallower.size
    # measured: within 1e-4 (0.3 % shallower)
    assert np.allclose(hemisphere, shallower, rtol=2e-3)


def test_synth_uff_of_a_sealed_enclosure_writes_physical_frfs(tmp_path, capsys):
    # the static correction of a sealed cavity is taken without its static pair: before,
    # ~1e11 m/s/V (the direct solve's agreement: tests/forced_response)
    from copdea_fem.measured.uff import read_scan

    out = tmp_path / "synth"
    assert main(["synth", str(ENCLOSURE_CYLINDER), "--format", "uff", "--conditions",
                 "load.z=16 mm, load.voltage=2 kV", "--out", str(out)]) == 0
    scan = read_scan(next(out.glob("*.uff")))
    largest = float(np.max(np.abs(scan.values)))
    assert 1e-4 < largest < 0.1, largest          # measured: 6.6e-3 m/s/V


def test_a_microphone_inside_a_sealed_enclosure_hears_the_trapped_air(tmp_path, capsys):
    import csv

    out = tmp_path / "r"
    assert main(["response", str(ENCLOSURE_CYLINDER), "--set", "geometry.frame=none",
                 "--set", "response.microphones=inside = 0 m, 0 m, -10 mm", "--set",
                 "excitation.f_end=400 Hz", "--quiet", "--out", str(out)]) == 0
    with open(out / "spl.csv") as handle:
        rows = list(csv.DictReader(handle))
    inside = np.array([float(row["spl_inside"]) for row in rows])
    outside = np.array([float(row["spl_axis"]) for row in rows])
    # the FE's own pressure inside (~69 dB near 351 Hz; before: the far-field formula,
    # -37 dB): far above the sound 1 m in front
    assert np.all(inside > outside + 30), (inside.min(), outside.max())
    assert 60 < inside.max() < 80, inside.max()


@pytest.mark.parametrize("in_file, options", [
    ("set:\n  mesh.engine: axisymmetric\n", []),
    ("", ["--set", "mesh.engine=axisymmetric"]),
    ("", []),
], ids=["engine-in-the-sweep-file", "engine-on-the-command-line", "engine-auto"])
def test_the_enclosure_study_sweeps_at_its_own_z(tmp_path, capsys, in_file, options):
    """The issue's sweep: the bundled enclosure study over load.z 10..16 mm (below 0.009 m
    only the 3-D engine refuses), the axisymmetric engine named in the sweep file, on the
    command line, or picked by mesh.engine: auto; the sweep's default executor.  Every
    point is solved, up to the study's own z = 16 mm."""
    import csv

    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"name: enclosure_z\nstudy: {ENCLOSURE_CYLINDER}\n{in_file}"
                     "model: coupled\naxes:\n  load.z: 10..16 mm, 2 points\n")
    assert main(["sweep", str(sweep), *options, "--quiet", "--out", str(tmp_path / "s")]) == 0
    with open(tmp_path / "s" / "sweep.csv", newline="") as table:
        rows = list(csv.DictReader(table))
    assert {round(float(row["load.z_m"]) * 1e3, 6) for row in rows} == {10.0, 16.0}
    assert {row["status"] for row in rows} == {"ok"}
