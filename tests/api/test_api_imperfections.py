"""Imperfect devices through the API and its files: a split pair's members in modes.csv and
in their ParaView files (which member a file holds, and its shape's orientation against the
axis the study gave), a synthetic scan holding the split pair where the FE puts it, and the
commands that need a round device refusing an imperfect one by name."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import pyvista as pv

import copdea_fem as cf
from copdea_fem.vtu import safe_name

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "studies/g1_z16_v2_quick.yaml"
#: the flat full membrane in vacuo (r_o = 35.5 mm, no disc, frame none, 1 kV) on the 3-D
#: engine, 2 % anisotropy along 30 deg: dry studies mesh the whole plane
FLAT_30 = {"geometry.inner_radius": 0, "geometry.frame": "none", "air.enabled": False,
           "load.z": 0, "load.voltage": "1 kV", "mesh.engine": "3d",
           "mesh.membrane_size": "6 mm", "mesh.order": 2, "eigen.f_max": "300 Hz",
           "membrane.prestretch_anisotropy": 0.02, "membrane.prestretch_axis": "30 deg",
           "output.plots": False}


def antinode_angle_deg(grid) -> float:
    """The angle [deg, in [0, 180)] of an m = 1 shape's antinode line from a mode VTU's
    points and normal displacement: the phase of its first Fourier coefficient in theta,
    sum w (cos theta, sin theta), over the points off the centre (independent of the
    solver's own sampling, :func:`copdea_fem.fe.modes.mode_orientation`)."""
    x, y = grid.points[:, 0], grid.points[:, 1]
    w = grid.point_data["normal_displacement_real"]
    if np.abs(grid.point_data["normal_displacement_imag"]).max() > np.abs(w).max():
        w = grid.point_data["normal_displacement_imag"]
    theta = np.arctan2(y, x)
    keep = np.hypot(x, y) > 1e-4
    angle = math.degrees(math.atan2(np.sum(w[keep] * np.sin(theta[keep])),
                                    np.sum(w[keep] * np.cos(theta[keep]))))
    return angle % 180.0


def test_split_members_carry_their_orientation_into_modes_csv_and_paraview(tmp_path):
    """The (1,1) members of a film stretched 2 % more along 30 deg: the stiffer one bends
    the film across the larger tension, so its antinode lies along the axis (30 deg), its
    partner's across it (120 deg).  modes.csv's orientation_deg, the VTU's field data and
    the VTU's own displacement field say so (the field within 2 deg: its points are the
    6 mm mesh's, not a circle)."""
    solution = cf.solve(cf.load_study(QUICK, FLAT_30))
    modes = solution.modes.set_index("label")
    upper, lower = sorted(("(1,1)a", "(1,1)b"), key=lambda label: -modes.loc[label, "freq_hz"])
    assert modes.loc[upper, "freq_hz"] / modes.loc[lower, "freq_hz"] - 1 > 0.01
    assert modes.loc[upper, "orientation_deg"] == pytest.approx(30.0, abs=0.5)
    assert modes.loc[lower, "orientation_deg"] == pytest.approx(120.0, abs=0.5)
    folder = solution.write(tmp_path / "flat")
    files = {path.name: path for path in folder.glob("mode_*.vtu")}
    for label, axis in ((upper, 30.0), (lower, 120.0)):
        name, = [n for n in files if re.fullmatch(rf"mode_\d+_{safe_name(label)}\.vtu", n)]
        grid = pv.read(files[name])
        assert grid.field_data["frequency_hz"][0] == pytest.approx(modes.loc[label, "freq_hz"])
        assert grid.field_data["orientation_deg"][0] == pytest.approx(
            modes.loc[label, "orientation_deg"])
        assert antinode_angle_deg(grid) == pytest.approx(axis, abs=2.0), label
    # an m = 0 mode has no orientation: NaN in both
    zero, = [n for n in files if re.fullmatch(r"mode_\d+_0_1\.vtu", n)]
    assert math.isnan(pv.read(files[zero]).field_data["orientation_deg"][0])
    assert math.isnan(modes.loc["(0,1)", "orientation_deg"])


def test_commands_of_the_round_ring_model_refuse_an_imperfect_device_by_name():
    """synth --format csv and spectrum use the axisymmetric ring model: an imperfect study
    is refused naming its keys (and synth names the format that can hold it)."""
    study = cf.load_study(QUICK, {"membrane.prestretch_anisotropy": 0.02})
    with pytest.raises(cf.StudyError, match=r"membrane.prestretch_anisotropy = 0.02 is not "
                       r"allowed with --format csv.*--format uff"):
        cf.synthesise(study, file_format="csv")
    with pytest.raises(cf.StudyError, match=r"membrane.prestretch_anisotropy = 0.02 is not "
                       r"allowed for the reduced model"):
        cf.spectrum(study)


@pytest.mark.slow
def test_a_synthetic_scan_of_an_anisotropic_device_holds_the_split_pair_at_the_fe_frequencies():
    """synth --format uff of G1 (coupled, coarse) with 2 % anisotropy along x, no frequency
    scatter: the scan's order-1 parts along x and along y (the axial FRFs of the membrane's
    points times cos theta, sin theta, summed: what an experimentalist's circumferential
    decomposition does; it removes the (0,1), which dominates the raw sum by 10 to 1) peak
    within two lines (0.5 Hz) of the (1,1)a and (1,1)b frequencies of an independent
    ``solve`` of the same study (11 Hz apart; half-power widths ~5 Hz): the member oriented
    along x (orientation_deg 0) in the cos theta part, the other in the sin theta part; the
    other part has only a flank there (the electrode's random order-1 weight drives the two
    members unequally, so the other member's flank may still be the larger; no measurement
    noise: 200 dB)."""
    from copdea_fem.diagnosis.synth_scan import ScanOptions

    study = cf.load_study(QUICK, {"membrane.prestretch_anisotropy": 0.02,
                                  "eigen.f_max": "560 Hz", "output.plots": False})
    modes = cf.solve(study).modes.set_index("label")
    data = cf.synthesise(study, conditions="load.z=16 mm", file_format="uff",
                         options=ScanOptions(frequency_noise=0.0, snr_db=200.0, f_min=420.0,
                                             f_max=490.0, resolution=0.25))
    scan = data.conditions[0].scan
    axial = np.abs(scan.channel_direction[:, 2]) > 0.99
    points = scan.positions[scan.channel_point[axial]]
    on_membrane = np.hypot(points[:, 0], points[:, 1]) > 0.018      # off the disc (r_i 17 mm)
    values = scan.values[axial][on_membrane]
    theta = np.arctan2(points[on_membrane, 1], points[on_membrane, 0])
    parts = {0.0: np.abs(np.cos(theta) @ values), 90.0: np.abs(np.sin(theta) @ values)}
    for label in ("(1,1)a", "(1,1)b"):
        expected = modes.loc[label, "freq_hz"]
        orientation = round(modes.loc[label, "orientation_deg"] / 90.0) * 90.0
        assert orientation in parts, (label, modes.loc[label, "orientation_deg"])
        own, other = parts[orientation], parts[90.0 - orientation]
        window = np.flatnonzero(np.abs(scan.frequencies - expected) < 4.0)
        peak = window[np.argmax(own[window])]
        print(f"{label}: FE {expected:.2f} Hz, scan peak {scan.frequencies[peak]:.2f} Hz")
        assert 0 < peak - window[0] < window.size - 1, label             # a local maximum
        assert scan.frequencies[peak] == pytest.approx(expected, abs=0.5), label
        assert np.argmax(other[window]) in (0, window.size - 1), label    # only a flank
