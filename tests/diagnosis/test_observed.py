"""``observed:`` (the families a measurement can see) and ``pairing:`` in measured.yaml, and
what ``observed`` does to the gap: model modes outside the families cost nothing."""

import math
import re

import pytest
import yaml

from copdea_fem.diagnosis import load_measured
from copdea_fem.diagnosis.compare import (
    GATE,
    MeasuredPeak,
    gap,
    gap_parts,
    match_condition,
)
from copdea_fem.diagnosis.ring_predictor import ModelMode
from copdea_fem.measured import MeasuredDataError, NoiseModel
from copdea_fem.measured.observation import parse_observed, parse_pairing

BASE = "geometry:\n  inner_radius: 17 mm\ndisc:\n  motion: spring\n"
RESONANCES = "freq_hz,label\n388,(0,1)\n"


def _set(tmp_path, extra: dict):
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "r.csv").write_text(RESONANCES)
    manifest = {"base_study": "base.yaml",
                "conditions": [{"name": "z16", "set": {"load.z": "16 mm"},
                                "resonances": "r.csv"}], **extra}
    path = tmp_path / "measured.yaml"
    path.write_text(yaml.safe_dump(manifest))
    return path


def test_observed_and_pairing_are_read(tmp_path):
    measured = load_measured(_set(tmp_path, {"observed": ["(m, 1)", "(0,n)", "pumping"],
                                             "pairing": {"window": "30 %", "mac_min": 0.6}}))
    assert measured.observed.families == ("(m,1)", "(0,n)", "pumping")
    assert measured.pairing.window == pytest.approx(0.3)
    assert measured.pairing.mac_min == pytest.approx(0.6)
    plain = load_measured(_set(tmp_path, {}))
    assert plain.observed is None and plain.pairing.window == pytest.approx(0.5)


@pytest.mark.parametrize("label, kind, covered", [
    ("(3,1)a", "non-axisymmetric", True), ("(0,1)", "axisymmetric", True),
    ("(0,2)", "axisymmetric", True), ("(2,2)b", "non-axisymmetric", False),
    ("P1", "pumping", False)])
def test_families_cover_what_they_name(label, kind, covered):
    observed = parse_observed(["(m,1)", "(0,n)"])
    assert observed.covers(label, kind) is covered
    assert parse_observed(["out-of-plane"]).covers(label, kind)
    assert parse_observed(["(2,2)"]).covers(label, kind) is (label == "(2,2)b")


@pytest.mark.parametrize("value, where", [
    ("(m,1)", "observed = '(m,1)'"), ([], "observed = []"), (["(m,0)"], "observed[0]"),
    (["drum"], "observed[0] = 'drum'"), ([3], "observed[0] = 3"),
    ([None], "observed[0] = None")])
def test_bad_observed_is_refused(value, where):
    with pytest.raises(MeasuredDataError, match=re.escape(where) + r".* is not allowed.*"
                       "allowed: a non-empty list of families"):
        parse_observed(value)


@pytest.mark.parametrize("value, match", [
    ({"window": 0}, r"pairing.window = 0 is not allowed; allowed: a number in \[0.01, 2\]"),
    ({"window": "lots"}, "pairing.window = 'lots' is not allowed"),
    ({"window": True}, "pairing.window = True is not allowed"),
    ({"mac_min": float("nan")}, "pairing.mac_min = nan is not allowed"),
    ({"width": 0.2}, "pairing.width = 0.2 is not allowed .unknown key."),
    ([0.2], r"pairing = \[0.2\] is not allowed; allowed: a mapping")])
def test_bad_pairing_is_refused(value, match):
    with pytest.raises(MeasuredDataError, match=match):
        parse_pairing(value)


def test_a_manifest_with_a_bad_observed_fails_on_load(tmp_path):
    with pytest.raises(MeasuredDataError, match="observed"):
        load_measured(_set(tmp_path, {"observed": "everything"}))


def _drum_head():
    """A drum-head table: the (m,1) modes measured (each 1 % off), the model holding the
    (m,2) modes too - modes a table of the (m,1) family never reports."""
    model, peaks = [], []
    for m in range(4):
        f1 = 100.0 * (1 + 0.6 * m)
        kind = "axisymmetric" if m == 0 else "non-axisymmetric"
        model.append(ModelMode(f"({m},1)" if m == 0 else f"({m},1)a", kind, f1, math.inf,
                               math.nan, expected=True))
        model.append(ModelMode(f"({m},2)" if m == 0 else f"({m},2)a", kind, 2.3 * f1, math.inf,
                               math.nan, expected=True))
        peaks.append(MeasuredPeak(f1 * 1.01, model[-2].label, kind))
    return model, peaks


def test_modes_outside_the_observed_families_cost_nothing_in_the_gap():
    model, peaks = _drum_head()
    noise = NoiseModel(frequency_relative=0.01, missing_probability=0.05)
    band = (50.0, 2000.0)
    everything = match_condition("c", model, peaks, band, noise)
    seen = match_condition("c", model, peaks, band, noise,
                           observed=parse_observed(["(m,1)"]))
    assert len(everything.unseen) == 4 and len(seen.unseen) == 0
    assert gap([seen]) == pytest.approx(0.01 / 1.01, rel=1e-9)      # the pairs' error only
    assert gap([everything]) > 0.1                                   # 4 modes "not seen"
    assert seen.deviance < everything.deviance
    parts = gap_parts([everything])
    assert parts["paired_rms"] == pytest.approx(0.01 / 1.01, rel=1e-9)
    assert parts["excess"] > 0
    # the gap is the pairs' errors and the count penalty put together
    total = math.sqrt((parts["pairs"] * parts["paired_rms"] ** 2 + GATE ** 2 * parts["excess"])
                      / (parts["pairs"] + parts["excess"]))
    assert gap([everything]) == pytest.approx(total, rel=1e-12)
