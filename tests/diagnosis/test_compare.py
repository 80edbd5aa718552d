"""Matching, deviance and gap (copdea_fem.diagnosis.compare), and spectrum peaks."""

import math

import numpy as np
import pytest

from copdea_fem.diagnosis.compare import GATE, DevianceTerms, MeasuredPeak, gap, match_condition
from copdea_fem.diagnosis.peaks import find_spectrum_peaks
from copdea_fem.diagnosis.ring_predictor import ModelMode
from copdea_fem.measured import NoiseModel

BAND = (1.25, 1000.0)
NOISE = NoiseModel(frequency_relative=0.015, missing_probability=0.1,
                   spurious_per_condition=0.2)


def mode(label, f, kind=None, q=math.inf):
    return ModelMode(label, kind or ("pumping" if label.startswith("P") else "axisymmetric"),
                     f, q, math.nan, True)


MODES = [mode("P1", 55.0), mode("(0,1)", 400.0), mode("(0,2)", 940.0)]


def test_labels_pair_first_then_frequencies_one_to_one():
    peaks = [MeasuredPeak(56.0, "P1"), MeasuredPeak(520.0, kind="axisymmetric"),
             MeasuredPeak(930.0), MeasuredPeak(131.0, "P2")]
    match = match_condition("c", MODES, peaks, BAND, NOISE)
    pairs = {(p.model.label, p.peak.frequency_hz, p.by) for p in match.pairs}
    # (0,1) 30 % off pairs: its kind is known; P2 is a label the model lacks
    assert pairs == {("P1", 56.0, "label"), ("(0,1)", 520.0, "frequency"),
                     ("(0,2)", 930.0, "frequency")}
    assert [p.label for p in match.unexplained] == ["P2"] and match.unseen == ()


def test_a_peak_of_unknown_kind_pairs_only_within_the_noise():
    """A spurious-looking peak (no shape seen) 30 % off stays unexplained; the mode unseen."""
    match = match_condition("c", MODES[:2], [MeasuredPeak(520.0)], BAND, NOISE)
    assert match.pairs == () and [m.label for m in match.unseen] == ["P1", "(0,1)"]
    strict = DevianceTerms(NOISE, BAND).strict_gate()
    assert 3 * 0.015 < strict < 6 * 0.015


def test_kinds_must_agree():
    match = match_condition("c", MODES, [MeasuredPeak(60.0, kind="axisymmetric")], BAND, NOISE)
    assert match.pairs == ()


def test_non_axisymmetric_peaks_are_out_of_scope():
    peaks = [MeasuredPeak(300.0, "(1,1)", "non-axisymmetric"), MeasuredPeak(401.0, "(0,1)")]
    match = match_condition("c", MODES, peaks, BAND, NOISE)
    assert [p.label for p in match.out_of_scope] == ["(1,1)"] and len(match.pairs) == 1


def test_deviance_terms_follow_the_mixture_model():
    terms = DevianceTerms(NOISE, BAND)
    exact = terms.pair(mode("(0,1)", 400.0), MeasuredPeak(400.0))
    match = 2 * math.log(math.sqrt(2 * math.pi) * 0.015) - 2 * math.log(0.9)
    outlier = terms.miss + terms.spurious
    mixture = -2 * math.log(math.exp(-match / 2) + math.exp(-outlier / 2))
    assert exact == pytest.approx(mixture, abs=1e-9)
    assert exact == pytest.approx(match, abs=1e-3)     # the outlier branch weighs ~ e^-9
    one_sigma = terms.pair(mode("(0,1)", 400.0), MeasuredPeak(400.0 * math.exp(0.015)))
    assert one_sigma - exact == pytest.approx(1.0, rel=1e-3)     # (mixture: ~1e-4 less)
    far = terms.pair(mode("(0,1)", 400.0), MeasuredPeak(520.0))
    assert far == pytest.approx(terms.miss + terms.spurious, abs=1e-6)   # bounded: an outlier
    assert terms.miss == pytest.approx(-2 * math.log(0.1))
    assert terms.lone_mode(mode("(0,2)", 1000.0)) == pytest.approx(
        -2 * math.log(1 - 0.9 * 0.5), rel=1e-6)                    # at the band edge: p_in = 1/2
    assert terms.spurious == pytest.approx(-2 * math.log(0.2 / math.log(1000 / 1.25)))


def test_gap_is_the_rms_error_plus_unexplained_peaks_beyond_the_noise():
    peaks = [MeasuredPeak(50.0, "P1"), MeasuredPeak(440.0, "(0,1)"), MeasuredPeak(940.0, "(0,2)")]
    match = match_condition("c", MODES, peaks, BAND, NOISE)
    errors = [55 / 50 - 1, 400 / 440 - 1, 0.0]
    assert gap([match]) == pytest.approx(math.sqrt(sum(e * e for e in errors) / 3))
    # ten unexplained pistonic peaks are far beyond p_miss and lambda_s: each counts GATE
    extra = peaks + [MeasuredPeak(100.0 + 10 * i, kind="pumping") for i in range(10)]
    match = match_condition("c", MODES, extra, BAND, NOISE)
    expected, spread = match.expected_unexplained, math.sqrt(match.variance_unexplained)
    excess = 10 - expected - 2 * spread
    value = math.sqrt((sum(e * e for e in errors) + GATE ** 2 * excess) / (3 + excess))
    assert gap([match]) == pytest.approx(value)


def test_spectrum_peaks_recover_frequency_and_quality_factor():
    """Two oscillators on 1.25 Hz lines with 10 % line noise: f within 0.5 %, Q within 20 %."""
    rng = np.random.default_rng(3)
    f = np.arange(1, 801) * 1.25
    spectrum = np.zeros(f.size)
    for f0, q in ((380.0, 16.0), (930.0, 110.0)):
        spectrum += f / np.abs(f0 ** 2 - f ** 2 + 1j * f * f0 / q)
    noisy = spectrum * np.exp(rng.normal(0, 0.1, f.size))
    peaks = find_spectrum_peaks(f, noisy, 0.3 * noisy, BAND)
    assert len(peaks) == 2
    for peak, (f0, q) in zip(peaks, ((380.0, 16.0), (930.0, 110.0))):
        assert peak.frequency_hz == pytest.approx(f0, rel=0.005)
        assert peak.quality_factor == pytest.approx(q, rel=0.2)
        assert peak.radial_ratio == pytest.approx(0.3, rel=1e-9)
