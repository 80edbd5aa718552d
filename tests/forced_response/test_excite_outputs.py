"""What ``copdea-fem excite`` writes, checked against what it did not make.

- **The operating shape** (``operating_shape_<target>.vtu``, read back with meshio) against
  the scan response (:func:`copdea_fem.forced_response.scan.scan_response`: the engine's
  point sampler, not the VTU writer's revolved grid) driving the designed drive at the
  target's frequency at the file's own points.
- **The ``--set`` lines** (``response_set.txt``) fed to ``copdea-fem response`` exactly as
  written: the drive ``response`` resolves cancels the modal force of the mode the drive
  holds down (``response``'s own ``modal_forcing.csv``, :mod:`.segments`' mass-normalised
  modes, not excite's modal model), and the spectra it writes at the two modes' lines are
  those excite's modal model predicts for that drive.

On the axisymmetric engine's coarse G1 at z = 16 mm, 2 kV (a second per solve).
"""

from __future__ import annotations

import csv
import shlex
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "studies" / "g1_z16_v2_quick.yaml"
AXISYMMETRIC = ["--set", "mesh.engine=axisymmetric", "--set", "geometry.frame=baffle"]
EIGHT_SECTORS = ("electrodes.segments=[" + ", ".join(
    f"{{name: s{k}, theta: [{45 * k}, {45 * (k + 1)}]}}" for k in range(8)) + "]")
RINGS = ("electrodes.segments=[{name: inner, theta: [0, 360], r: [0.017, 0.026]}, "
         "{name: outer, theta: [0, 360], r: [0.026, 0.0355]}]")


def test_the_operating_shape_file_is_the_scan_response_at_its_points(tmp_path):
    """Eight sectors, the (2,1) target: a drive of the orders 2, 6, 10, ... (cos and sin
    families summed by the writer).  Away from the rims (where the point sampler keeps a
    point 1e-6 of the radius inside, docs: fe/points.py RIM_NUDGE) both evaluate one FE
    field at one point: round-off (measured 1e-10 of the peak)."""
    import meshio

    from copdea_fem.api import load_study
    from copdea_fem.cli import main
    from copdea_fem.fe.forced.electrode import segment_weights
    from copdea_fem.forced_response.run import modal_damping
    from copdea_fem.forced_response.scan import scan_response

    out = tmp_path / "e"
    assert main(["excite", str(QUICK), *AXISYMMETRIC, "--set", "eigen.f_max=900 Hz",
                 "--set", EIGHT_SECTORS, "--target", "(2,1)", "--out", str(out),
                 "--quiet"]) == 0
    assert "operating_shape_2_1_a.vtu" in (out / "operating_shape.pvd").read_text()
    mesh = meshio.read(out / "operating_shape_2_1_a.vtu")
    velocity = mesh.point_data["velocity_real"] + 1j * mesh.point_data["velocity_imag"]
    assert np.allclose(mesh.point_data["velocity_abs"],
                       np.linalg.norm(np.abs(velocity), axis=1))
    # the file's drive and frequency, from the files excite wrote beside it
    with open(out / "drive.csv", newline="") as handle:
        drive = {row["segment"]: float(row["amplitude"])
                 * np.exp(1j * np.radians(float(row["phase_deg"])))
                 for row in csv.DictReader(handle)}
    with open(out / "selectivity.csv", newline="") as handle:
        frequency = next(float(row["freq_hz"]) for row in csv.DictReader(handle)
                         if row["label"] == "(2,1)a")
    study = load_study(out / "study.resolved.yaml")
    from copdea_fem.fe import engine_for, run_solve
    solution = run_solve(study, engine=engine_for(study))
    radius = np.hypot(mesh.points[:, 0], mesh.points[:, 1])
    inside = np.flatnonzero((radius > 0.0171) & (radius < 0.0354))
    chosen = np.unique(np.r_[inside[:: max(1, inside.size // 40)],
                             inside[np.argmax(np.abs(velocity[inside, 2]))]])
    # drive.csv's phase is that of V(t) = A cos(omega t + phi): e^{+i omega t} amplitude
    scan = scan_response(solution, study, mesh.points[chosen], [frequency],
                         [(weight, drive[name]) for name, weight, _ in segment_weights(study)],
                         damping_per_mass=lambda mode: float(
                             modal_damping([mode.label], [mode.kind], study)[0]))
    reference = scan.velocity[:, :, 0]
    assert np.abs(reference).max() > 0
    assert np.abs(velocity[chosen] - reference).max() <= 1e-8 * np.abs(reference).max()


def test_no_operating_shape_without_paraview_files(tmp_path):
    from copdea_fem.cli import main

    out = tmp_path / "e"
    assert main(["excite", str(QUICK), *AXISYMMETRIC, "--set", RINGS, "--set",
                 "output.paraview=false", "--set", "output.plots=false",
                 "--target", "(0,2)", "--out", str(out), "--quiet"]) == 0
    assert (out / "drive.csv").exists()
    assert not list(out.glob("*.vtu")) and not list(out.glob("*.png"))


def test_the_operating_shape_of_a_mode_that_is_not_a_target_is_refused():
    from copdea_fem.api import excite, load_study
    from copdea_fem.study import StudyError

    result = excite(load_study(QUICK, [AXISYMMETRIC[1], AXISYMMETRIC[3], RINGS]), ["(0,2)"])
    with pytest.raises(StudyError, match=r"operating shape of '\(0,1\)': not a target; "
                                         r"allowed: \(0,2\)$"):
        result.operating_shape("(0,1)")
    shape = result.operating_shape()
    # rings drive the order 0 only: the shape is axisymmetric, |v| equal on every ring
    radius = np.round(np.hypot(shape.points[:, 0], shape.points[:, 1]), 9)
    ring = radius == radius[np.argmax(shape.point_data["velocity_abs"])]
    values = shape.point_data["velocity_abs"][ring]
    assert ring.sum() > 10 and np.ptp(values) <= 1e-9 * values.max()


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


@pytest.mark.slow
def test_response_fed_with_excites_set_lines_holds_the_01_down(tmp_path):
    """Rings, the (0,2) target: ``response`` run with response_set.txt's line as written.

    (a) The drive ``response`` resolved (its study.resolved.yaml) against ``response``'s
    own modal forces of the segments (modal_forcing.csv): the (0,1)'s modal force
    ``sum_k Q_k conj(d_k)`` (``d_k = amplitude e^{i phase}``, e^{+i omega t}; the FE's forcing
    goes as e^{-i omega t}) cancels to below 1e-2 (40 dB, the issue's figure) of the segments'
    single contributions ``max |Q_k d_k|``, while the (0,2)'s does not.
    The phase the lines carry (179.13 deg, not 180) matters: its sign flipped leaves
    2 sin(0.87 deg) = 3e-2 of the contributions (measured).

    (b) The spectra at the (0,1)'s and the (0,2)'s lines: the designed drive's velocity at
    Q1-Q3 over that of both rings at the same amplitude in phase (the chirp's line volts
    cancel) equals what excite's modal model gives for that drive, within 3e-2: response
    solves its band up to response.modal_band times the last line where the model holds
    the modes above eigen.f_max in its static correction (measured 1e-2 at the (0,2)'s line
    at Q2, near that mode's nodal circle; 3e-4 elsewhere)."""
    from copdea_fem.cli import main

    files_off = ["--set", "output.paraview=false", "--set", "output.plots=false"]
    common = [str(QUICK), *AXISYMMETRIC, *files_off]
    assert main(["excite", *common, "--set", RINGS, "--target", "(0,2)", "--out",
                 str(tmp_path / "e"), "--quiet"]) == 0
    lines = (tmp_path / "e" / "response_set.txt").read_text().split("\n")
    fed = [arg for line in lines if line.strip() for arg in shlex.split(line)]
    assert fed[0] == "--set" and len(fed) == 2
    assert main(["response", *common, *fed, "--out", str(tmp_path / "r"), "--quiet"]) == 0
    assert main(["response", *common, "--set", RINGS, "--out", str(tmp_path / "one"),
                 "--quiet"]) == 0
    resolved = yaml.safe_load((tmp_path / "r" / "study.resolved.yaml").read_text())
    drive = {segment["name"]: segment["drive"]["amplitude"]
             * np.exp(1j * np.radians(segment["drive"]["phase"]))
             for segment in resolved["electrodes"]["segments"]}
    forcing = _rows(tmp_path / "r" / "modal_forcing.csv")

    def terms(label):
        return np.array([complex(float(row["force_re"]), float(row["force_im"]))
                         * np.conj(drive[row["segment"]]) for row in forcing if row["label"] == label])

    held, lit = terms("(0,1)"), terms("(0,2)")
    assert len(held) == len(lit) == 2
    assert abs(held.sum()) <= 1e-2 * np.abs(held).max()
    assert abs(lit.sum()) >= 0.5 * np.abs(lit).max()       # measured 0.86

    # (b) excite's modal model for the same drive
    from copdea_fem.api import excite, load_study
    study = load_study(QUICK, ["mesh.engine=axisymmetric", "geometry.frame=baffle", RINGS])
    result = excite(study, ["(0,2)"])
    frequency = dict(zip(result.design.labels, result.design.freq_hz))
    designed = np.loadtxt(tmp_path / "r" / "response_points.csv", delimiter=",", skiprows=1)
    one = np.loadtxt(tmp_path / "one" / "response_points.csv", delimiter=",", skiprows=1)
    rows = [int(np.argmin(np.abs(designed[:, 0] - frequency[label])))
            for label in ("(0,1)", "(0,2)")]
    velocity, _ = result.model.frequency_response(designed[rows, 0])     # (F, P, 3, K)
    points = [result.model.point_names.index(f"q{i}_0deg") for i in (1, 2, 3)]
    inputs = np.array([drive[name] for name in result.model.inputs])
    for component, columns in ((2, slice(1, None, 2)), (0, slice(2, None, 2))):
        model = velocity[:, points, component, :]
        expected = np.abs(model @ inputs) / np.abs(model.sum(axis=-1))
        measured = designed[rows][:, columns] / one[rows][:, columns]
        assert np.abs(measured / expected - 1).max() <= 3e-2, (component, measured, expected)


@pytest.mark.slow
def test_the_acceptance_figures_on_the_3d_quadrant():
    """The issue's two figures (G1, z = 16 mm, 2 kV) on the bundled device's own engine and
    frame (3-D quadrant, square frame, its mesh one octant mirrored): the eight sectors
    light the (2,1) with every other out-of-plane mode at least 20 dB down but those
    reported as inseparable (coarse 6 mm: measured below -200 dB, the (6,1)a reported);
    the rings light the (0,2) with the (0,1) at least 40 dB down (4.5 mm: measured -52 dB;
    at 6 mm -35.6 dB, the square frame's A1 modes (4,1)a and (8,1)a taking the rings'
    second degree of freedom, docs/excitation.md)."""
    from copdea_fem.api import excite, load_study

    sectors = excite(load_study(QUICK, [EIGHT_SECTORS]), ["(2,1)"]).design
    reported = {line.split(":")[0] for line in sectors.inseparable}
    for label, level in zip(sectors.labels, sectors.level_db):
        if label not in sectors.targets and label not in reported:
            assert level <= -20.0, (label, level)
    rings = excite(load_study(QUICK, [RINGS, "mesh.membrane_size=4.5 mm"]), ["(0,2)"]).design
    assert dict(zip(rings.labels, rings.level_db))["(0,1)"] <= -40.0
