"""Mode sets from other programs (a condition's ``modes: FILE.unv``, dataset 55): read as
channels (copdea_fem.measured.mode_sets), paired with the FE by shape as a scan's modes are
(copdea_fem.diagnosis.scanned.pair_condition), in ``correlate`` and ``diagnose``.

The "other program" here is pyuff writing dataset 55 records of shapes the FE made on the
bundled scan example's grid (in mm, dataset 164 saying so; complex and real shapes): each
written mode must come back paired with the FE mode it was made from, its MAC 1 and its
frequency error 0.  The real mode sets (LMS Test.Lab exports in ../shared/realdata, read in
place) are read with the mode counts their README gives and go through the pairing's input
checks.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from vibrometer_helpers import REALDATA

from copdea_fem.cli import main

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "studies" / "measured_scan_example"
LMS = REALDATA / "gvt_xhale_lms_testlab"
needs_lms = pytest.mark.skipif(not LMS.is_dir(), reason=f"{LMS} absent (real LMS exports)")
#: The modes the written set holds: the FE's in this band [Hz] (out-of-plane and in-plane)
BAND = (400.0, 800.0)


@pytest.fixture(scope="module")
def fe_on_the_grid():
    """The example's FE modes along its scan's channels (3 axes per point), as correlate
    and diagnose pair them."""
    from copdea_fem.diagnosis import load_measured
    from copdea_fem.diagnosis.scanned import scan_fe_study
    from copdea_fem.vibrometer.model_shapes import fe_shapes

    measured = load_measured(EXAMPLE / "measured.yaml")
    (condition,) = measured.conditions
    return condition.scan, fe_shapes(scan_fe_study(measured, condition), condition.scan)


def write_mode_set(path: Path, scan, fe, *, complex_shapes: bool) -> list[str]:
    """The FE modes in BAND as a dataset 55 export (164 in mm, 2411, one 55 per mode) by
    pyuff; returns the labels written, in file order (highest frequency first, so that the
    reader's frequency order is tested)."""
    import pyuff

    keep = [k for k in np.argsort(fe.freq_hz)[::-1] if BAND[0] <= fe.freq_hz[k] <= BAND[1]]
    millimetre = 1e3
    sets = [pyuff.prepare_164(units_code=2, units_description="mm", temp_mode=1,
                              length=millimetre, force=1.0, temp=1.0, temp_offset=273.15),
            pyuff.prepare_2411(node_nums=np.asarray(scan.nodes, int),
                               def_cs=np.zeros(scan.n_points, int),
                               disp_cs=np.zeros(scan.n_points, int),
                               color=np.full(scan.n_points, 8, int),
                               x=millimetre * scan.positions[:, 0],
                               y=millimetre * scan.positions[:, 1],
                               z=millimetre * scan.positions[:, 2])]
    rng = np.random.default_rng(5)
    for number, k in enumerate(keep, 1):
        shape = fe.shapes[:, k] / np.max(np.abs(fe.shapes[:, k]))
        per_node = np.zeros((scan.n_points, 3), complex)
        for channel, point in enumerate(scan.channel_point):
            axis = int(np.argmax(np.abs(scan.channel_direction[channel])))
            per_node[point, axis] = shape[channel] * np.sign(scan.channel_direction[channel,
                                                                                    axis])
        reference = per_node.ravel()[np.argmax(np.abs(per_node.ravel()))]
        per_node *= abs(reference) / reference                      # the largest one real
        zeta, omega = 0.01 + 0.01 * rng.random(), 2 * math.pi * fe.freq_hz[k]
        common = dict(model_type=1, id1="copdea-fem test", id2="NONE", id3="NONE",
                      id4=f"MODE NO. {number}", id5="NONE", data_ch=2, spec_data_type=8,
                      n_data_per_node=3, node_nums=np.asarray(scan.nodes, int), load_case=1,
                      mode_n=number)
        if complex_shapes:       # a complex eigenvalue s = -zeta w + i w sqrt(1 - zeta^2)
            rotated = per_node * np.exp(2j * math.pi * rng.random())
            eigenvalue = complex(-zeta * omega, omega)   # |Im s| / 2 pi: the frequency
            record = pyuff.prepare_55(**common, analysis_type=3, data_type=5,
                                      r1=rotated[:, 0], r2=rotated[:, 1], r3=rotated[:, 2],
                                      eig=eigenvalue, modal_a=0j, modal_b=0j)
        else:
            real = per_node.real
            record = pyuff.prepare_55(**common, analysis_type=2, data_type=2, r1=real[:, 0],
                                      r2=real[:, 1], r3=real[:, 2], freq=fe.freq_hz[k],
                                      modal_m=0.0, modal_damp_vis=zeta, modal_damp_his=0.0)
        sets.append(record)
    with contextlib.redirect_stdout(io.StringIO()):
        pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    return [fe.labels[k] for k in keep]


def write_manifest(folder: Path, condition: dict) -> Path:
    raw = {"name": "mode_set_test", "base_study": str(EXAMPLE / "base_study.yaml"),
           "conditions": [{"name": "z16_v2", "set": {"load.z": "16 mm",
                                                    "load.voltage": "2 kV"}, **condition}]}
    path = folder / "measured.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.mark.parametrize("complex_shapes", [True, False], ids=["complex", "real"])
def test_a_mode_set_of_the_fe_shapes_pairs_each_mode_with_its_own(tmp_path, capsys,
                                                                   fe_on_the_grid,
                                                                   complex_shapes):
    from copdea_fem.vibrometer.pairing import unit_key

    scan, fe = fe_on_the_grid
    labels = write_mode_set(tmp_path / "modes.unv", scan, fe, complex_shapes=complex_shapes)
    assert len(labels) >= 8
    manifest = write_manifest(tmp_path, {"modes": "modes.unv"})
    out = tmp_path / "correlate"
    assert main(["correlate", str(manifest), "--out", str(out), "--quiet"]) == 0
    assert f"z16_v2: {len(labels)} of {len(labels)} test modes paired by shape" in \
        capsys.readouterr().out
    with open(out / "pairs.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    # the reader sorts by frequency: the written modes (highest first) in reverse
    written = labels[::-1]
    assert len(rows) == len(written)
    for row, label in zip(rows, written):
        # a pair's two members are one unit (either member may take the written one)
        assert unit_key(row["label"]) == unit_key(label), (row, label)
        assert float(row["mac"]) > 0.999
        # frequencies written with 6 significant digits (pyuff's 55 format)
        assert abs(float(row["freq_error"])) < 1e-5
        assert 0.01 <= float(row["test_damping_ratio"]) <= 0.02
    with open(out / "comac.csv", newline="") as stream:
        comac = list(csv.DictReader(stream))
    # the held disc does not move in any mode: its points' zeros are "not measured" and
    # left out; every membrane point keeps its three directions
    disc = {int(node) for node, z in zip(scan.nodes, scan.positions[:, 2]) if z > 0.015}
    assert len(disc) == 4
    assert {int(row["node"]) for row in comac} == {int(node) for node in scan.nodes} - disc
    assert len(comac) == scan.n_channels - 3 * len(disc)


def test_the_diagnosis_takes_a_mode_set_as_labelled_peaks(tmp_path, fe_on_the_grid):
    """diagnose turns a mode set into resonances as it does a scan: the file's frequency,
    Q = 1 / (2 zeta) and the label of the FE mode its shape matches (in-plane ones out)."""
    from copdea_fem.diagnosis import load_measured
    from copdea_fem.diagnosis.scanned import resonances_from_scans

    scan, fe = fe_on_the_grid
    labels = write_mode_set(tmp_path / "modes.unv", scan, fe, complex_shapes=True)
    measured, pairings = resonances_from_scans(load_measured(write_manifest(
        tmp_path, {"modes": "modes.unv"})))
    (condition,) = measured.conditions
    out_of_plane = [label for label in labels if not label.startswith("ip")]
    assert len(pairings) == 1 and len(pairings[0].modes) == len(labels)
    assert condition.resonances
    assert {r.label for r in condition.resonances} <= {label.rstrip("ab")
                                                       for label in out_of_plane} | set(
        out_of_plane)
    for resonance in condition.resonances:
        assert 1 / (2 * 0.02) <= resonance.quality_factor <= 1 / (2 * 0.01)


def test_a_condition_with_scan_and_modes_is_refused_by_name(tmp_path, fe_on_the_grid,
                                                           capsys):
    scan, fe = fe_on_the_grid
    write_mode_set(tmp_path / "modes.unv", scan, fe, complex_shapes=True)
    manifest = write_manifest(tmp_path, {"scan": str(EXAMPLE / "z16_v2.uff"),
                                         "modes": "modes.unv"})
    out = tmp_path / "out"
    assert main(["correlate", str(manifest), "--out", str(out), "--quiet"]) == 2
    error = capsys.readouterr().err
    assert "conditions[0].modes = 'modes.unv' is not allowed" in error
    assert "scan: or modes:, not both" in error
    assert not out.exists()


@pytest.mark.parametrize("condition, message", [
    ({"modes": str(EXAMPLE / "z16_v2.uff")}, "no mode shape (no dataset 55)"),
    ({"modes": "modes.unv", "scan_directions": [0, 0, 1]},
     "conditions[0].scan_directions = [0, 0, 1] is not allowed"),
    ({"modes": "missing.unv"}, "the file does not exist"),
    ({"modes": 3}, "conditions[0].modes = 3 is not allowed"),
    ({"modes": "modes.unv", "scan_frame": {"origin": [0, 0, 50]}},
     "conditions[0].modes: node"),
])
def test_bad_mode_sets_are_refused_with_exit_2(tmp_path, fe_on_the_grid, capsys, condition,
                                               message):
    scan, fe = fe_on_the_grid
    write_mode_set(tmp_path / "modes.unv", scan, fe, complex_shapes=False)
    out = tmp_path / "out"
    assert main(["correlate", str(write_manifest(tmp_path, condition)), "--out", str(out),
                 "--quiet"]) == 2
    error = capsys.readouterr().err
    assert message in error and len(error.strip().splitlines()) == 1, error
    assert not out.exists()


@needs_lms
@pytest.mark.parametrize("name, modes, points, channels", [
    ("beam_OOP_inb_0_30Hz_complex_polymax.unv", 16, 26, 26),    # z only: x, y written as 0
    ("wing_Bradens_example_modes_alt.unv", 15, 8, 8),
    ("xhale_Out_time_mdof_complex_conf1.unv", 11, 36, 54),
    ("xhale_full_outb.unv", 36, 36, 54),
    ("xhale_gvt1all.unv", 13, 36, 54),
])
def test_the_lms_mode_sets_are_read_as_channels(name, modes, points, channels):
    """Every LMS Test.Lab mode set: the mode counts of its README, the nodes with data (not
    the geometry's extra ones), only the directions measured; frequencies from the complex
    eigenvalue (record 8) against the text header's ("MODE NO. k, FREQUENCY f(Hz)")."""
    import re

    from copdea_fem.measured import read_mode_set
    from copdea_fem.measured.uff import read_mode_sets

    mode_set = read_mode_set(LMS / name)
    assert mode_set.n_modes == modes
    assert mode_set.channels.n_points == points and mode_set.channels.n_channels == channels
    assert mode_set.shapes.shape == (channels, modes) and np.iscomplexobj(mode_set.shapes)
    assert np.all(np.diff(mode_set.freq_hz) >= 0)
    assert np.all((mode_set.damping_ratio > 0) & (mode_set.damping_ratio < 0.2))
    headers = {record.mode: record.header for record in read_mode_sets(LMS / name)}
    for mode, frequency in zip(mode_set.file_modes, mode_set.freq_hz):
        found = re.search(r"FREQUENCY\s*([\d.]+)", headers[mode], re.IGNORECASE)
        if found:                # the header rounds: two decimals at least
            assert frequency == pytest.approx(float(found[1]), abs=0.01)


@needs_lms
def test_a_real_mode_set_goes_through_the_pairing_checks():
    """The beam's complex PolyMAX shapes, paired with themselves as the "model" (each its
    own unit), pair one-to-one with MAC 1; on other channels, or with NaN, they are
    refused by name."""
    from copdea_fem.measured import read_mode_set
    from copdea_fem.vibrometer.pairing import CorrelationError, FEShapes, correlate_shapes

    mode_set = read_mode_set(LMS / "beam_OOP_inb_0_30Hz_complex_polymax.unv")
    model = FEShapes(tuple(f"P{k}" for k in range(1, mode_set.n_modes + 1)),
                     mode_set.freq_hz, mode_set.shapes)
    correlation = correlate_shapes(mode_set.freq_hz, mode_set.shapes, model,
                                   test_damping_ratio=mode_set.damping_ratio)
    assert [pair.label for pair in correlation.pairs] == list(model.labels)
    assert all(pair.mac == pytest.approx(1.0, abs=1e-9) for pair in correlation.pairs)
    with pytest.raises(CorrelationError, match="test shapes on 25 channels, FE shapes on 26"):
        correlate_shapes(mode_set.freq_hz, mode_set.shapes[1:], model)
    shapes = mode_set.shapes.copy()
    shapes[0, 0] = np.nan
    with pytest.raises(CorrelationError, match="hold NaN or inf"):
        correlate_shapes(mode_set.freq_hz, shapes, model)


@needs_lms
def test_a_real_mode_set_off_the_device_is_refused_naming_the_node(tmp_path, capsys):
    """The beam (3.7 m long) is no membrane: measured.yaml's modes: refused before any
    work, naming the node, its distance and scan_frame."""
    manifest = write_manifest(tmp_path, {"modes": str(LMS / "beam_OOP_inb_0_30Hz_complex_"
                                                       "polymax.unv")})
    assert main(["correlate", str(manifest), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    error = capsys.readouterr().err
    assert "conditions[0].modes: node" in error and "check scan_frame" in error
