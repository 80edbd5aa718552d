"""measured.yaml and its CSVs: formats, conversions, and clear messages for bad input."""

import math

import numpy as np
import pytest
import yaml

from copdea_fem.diagnosis import load_measured
from copdea_fem.measured import MeasuredDataError, normalise_label, read_spectrum
from copdea_fem.study import StudyError

BASE = "geometry:\n  inner_radius: 17 mm\ndisc:\n  motion: spring\n"


def _set(tmp_path, manifest: dict, files: dict | None = None):
    (tmp_path / "base.yaml").write_text(BASE)
    for name, text in (files or {}).items():
        (tmp_path / name).write_text(text)
    path = tmp_path / "measured.yaml"
    path.write_text(yaml.safe_dump(manifest))
    return path


GOOD = {"base_study": "base.yaml",
        "conditions": [{"name": "z16", "set": {"load.z": "16 mm", "load.voltage": "2 kV"},
                        "resonances": "r.csv"}]}
RESONANCES = "freq_hz,label,quality_factor,kind\n55.2,P1,9.8,pumping\n388, (0, 1) ,,\n941,,120,\n"


def test_a_valid_manifest_is_read_with_si_values_and_defaults(tmp_path):
    measured = load_measured(_set(tmp_path, GOOD, {"r.csv": RESONANCES}))
    condition = measured.conditions[0]
    assert measured.name == "measured" and measured.noise.frequency_relative == 0.015
    assert measured.study_of(condition).load.z == pytest.approx(0.016)
    labels = [(r.frequency_hz, r.label, r.kind) for r in condition.resonances]
    assert labels == [(55.2, "P1", "pumping"), (388.0, "(0,1)", "axisymmetric"),
                      (941.0, "", "")]
    assert math.isnan(condition.resonances[1].quality_factor)
    assert condition.band == pytest.approx((1.25, 1000.0))       # the chirp's lines


def test_labels_normalise_and_imply_their_kind():
    assert normalise_label("p2", "x") == ("P2", "pumping")
    assert normalise_label("(1,1)a", "x") == ("(1,1)a", "non-axisymmetric")
    with pytest.raises(MeasuredDataError, match="label = '0,1' is not allowed"):
        normalise_label("0,1", "label")


def test_cartesian_spectra_are_turned_into_axial_and_radial(tmp_path):
    f = np.arange(1, 11) * 1.25
    lines = ["freq_hz,v_x,v_y,v_z"] + [f"{x},0.3,0.4,2.0" for x in f]
    (tmp_path / "s.csv").write_text("\n".join(lines))
    average = read_spectrum(tmp_path / "s.csv", "average")
    point = read_spectrum(tmp_path / "s.csv", "Q2")
    assert np.allclose(average.axial, 2.0) and np.allclose(point.axial, 2.0)
    assert np.allclose(average.radial, math.pi / 4 * 0.7)      # mean |cos| = 2/pi per axis
    assert np.allclose(point.radial, 0.5)                      # hypot at one point


BAD = [
    ({**GOOD, "base_study": "nope.yaml"}, {}, "study file", "does not exist"),
    ({**GOOD, "colour": "red"}, {"r.csv": RESONANCES}, "colour = '...' is not allowed",
     "keys name, description, base_study"),
    (GOOD, {}, "conditions[0].resonances", "file does not exist"),
    (GOOD, {"r.csv": "frequency,label\n1,P1\n"}, "conditions[0].resonances columns",
     "freq_hz and optionally label"),
    (GOOD, {"r.csv": "freq_hz\n-3\n"}, "r.csv line 2 freq_hz = '-3' is not allowed",
     "a finite number > 0"),
    (GOOD, {"r.csv": "freq_hz,label\n50,P1\n60,P1\n"}, "label = 'P1' is not allowed",
     "each label once per condition"),
    (GOOD, {"r.csv": "freq_hz,label,kind\n50,P1,axisymmetric\n"}, "kind = 'axisymmetric' is "
     "not allowed", "pumping (the kind of label P1)"),
    ({**GOOD, "candidates": ["air_loading", "acoustics"]}, {"r.csv": RESONANCES},
     "candidates = 'acoustics' is not allowed (unknown effect)", "air_loading, "),
    ({**GOOD, "noise": {"frequency_relative": 2}}, {"r.csv": RESONANCES},
     "noise.frequency_relative = 2 is not allowed", "[0.0001, 0.5]"),
    ({"base_study": "base.yaml", "conditions": [{"name": "a", "set": {"load.z": "99 mm"},
                                                 "resonances": "r.csv"}]},
     {"r.csv": RESONANCES}, "conditions[0] (a).set: load.z = ", "2 * (r_o - r_i)"),
    ({"base_study": "base.yaml", "conditions": [{"name": "a", "set": {"spring.mass": "1 g"},
                                                 "resonances": "r.csv"}]},
     {"r.csv": RESONANCES}, "conditions[0].set.spring.mass", "switched by effect spring_mass"),
    ({"base_study": "base.yaml", "conditions": [{"name": "a"}]}, {}, "conditions[0] (a)",
     "resonances and/or spectrum"),
    ({"base_study": "base.yaml", "conditions": [{"name": "a", "spectrum": "s.csv"}]},
     {"s.csv": "freq_hz,v_axial\n1,2\n"}, "conditions[0].spectrum columns",
     "freq_hz, v_axial, v_radial or freq_hz, v_x, v_y, v_z"),
    ({"base_study": "base.yaml", "conditions": [{"name": "a b", "resonances": "r.csv"}]},
     {"r.csv": RESONANCES}, "conditions[0].name = 'a b' is not allowed", "letters, digits"),
    ({"base_study": "base.yaml", "conditions": [
        {"name": "a", "resonances": "r.csv"}, {"name": "a", "resonances": "r.csv"}]},
     {"r.csv": RESONANCES}, "conditions[1].name = 'a' is not allowed", "a name used once"),
]


@pytest.mark.parametrize("manifest, files, start, allowed", BAD,
                         ids=[f"bad{i}" for i in range(len(BAD))])
def test_bad_input_is_reported_before_any_work(tmp_path, manifest, files, start, allowed):
    with pytest.raises(StudyError) as caught:
        load_measured(_set(tmp_path, manifest, files))
    message = str(caught.value)
    assert start in message and allowed in message, message
    assert isinstance(caught.value, ValueError)
