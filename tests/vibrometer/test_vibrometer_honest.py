"""Identification on what labs export: few channels, short records, bands past the lines,
resonances narrower than a line - the modes found, or said plainly that they are not."""

import logging
import math

import numpy as np
import pytest
from scan_subsets import SCAN_EXAMPLE, example_copy, out_of_plane, truth_frequencies
from vibrometer_helpers import make_scan, membrane_shapes, paper_grid, pole

from copdea_fem import api
from copdea_fem.measured import MeasuredDataError, read_scan
from copdea_fem.vibrometer import identification
from copdea_fem.vibrometer.identification import identify, identify_scan
from copdea_fem.vibrometer.peak_check import summed_peaks, unexplained_peaks


@pytest.fixture(scope="module")
def z_records():
    """The example's 34 out-of-plane records (one channel per point)."""
    return out_of_plane(read_scan(SCAN_EXAMPLE / "z16_v2.uff"))


def test_few_channels_find_the_modes(z_records):
    """34 channels (a 1-D scan): at least 10 of the ~30 true modes in 150-850 Hz found,
    each identified mode within 1 % of a true one (before: 2 modes)."""
    modes = identify(z_records, f_min=150.0, f_max=850.0)
    truth = truth_frequencies()
    found = np.array([m.freq_hz for m in modes])
    error = np.min(np.abs(found[:, None] / truth[None, :] - 1), axis=1)
    assert np.all(error < 0.01), found[error >= 0.01]
    matched = {int(np.argmin(np.abs(truth - f))) for f in found}
    assert len(matched) >= 10, found


def test_modes_not_found_are_said(z_records, monkeypatch, caplog):
    """Without the noise estimate (the principal functions taking every channel, as
    before) most modes are missed: the summed |H|'s peaks with no mode are named in a
    warning and kept in the diagram."""
    monkeypatch.setattr(identification, "MIN_NOISE_CHANNELS", 10 ** 6)
    with caplog.at_level(logging.WARNING, logger="copdea_fem"):
        found = identify_scan(z_records, f_min=150.0, f_max=850.0)
    assert len(found.modes) < 5
    missed = found.diagram.unexplained_peaks
    assert missed.size >= 5
    assert "could not be found" in caplog.text and f"{missed[0]:.1f}" in caplog.text


def test_peak_check_closed_form():
    """Two resonances (100, 200 Hz) in the sum: with the mode at 100 Hz only, the peak at
    200 Hz is unexplained; with both, none is."""
    frequencies = np.arange(1, 400) * 1.0
    values = np.array([1 / (100.0 ** 2 - frequencies ** 2 + 2j * 0.01 * 100 * frequencies)
                       + 1 / (200.0 ** 2 - frequencies ** 2 + 2j * 0.01 * 200 * frequencies)])
    peaks = summed_peaks(frequencies, values)
    assert peaks == pytest.approx([100.0, 200.0])
    assert unexplained_peaks(peaks, [100.3], 1.0) == pytest.approx([200.0])
    assert unexplained_peaks(peaks, [100.3, 199.2], 1.0).size == 0


def test_peaks_as_scipy_finds_them():
    """The peak search against :func:`scipy.signal.find_peaks` (the same prominence) on
    random walks, plateaus among them."""
    from scipy.signal import find_peaks

    from copdea_fem.vibrometer.peak_check import PEAK_PROMINENCE

    rng = np.random.default_rng(1)
    frequencies = np.arange(200.0)
    for trial in range(100):
        level = rng.normal(size=200).cumsum() * 0.05 + rng.normal(size=200) * 0.03
        if trial % 3 == 0:
            level = np.round(level, 1)
        index, _ = find_peaks(level, prominence=PEAK_PROMINENCE)
        assert summed_peaks(frequencies, 10 ** level[None, :]) == pytest.approx(
            frequencies[index])


def test_a_short_record_is_refused(tmp_path):
    """15 lines leave 6 LSCF orders: refused by name (before: 5 modes, two where none)."""
    with pytest.raises(MeasuredDataError, match=r"15 lines up to 237.5 Hz are not allowed .* "
                                                r"at least 22 lines"):
        api.identify(example_copy(tmp_path, lines=15))


def test_a_band_past_the_lines_is_clipped_naming_the_band(tmp_path, caplog):
    with caplog.at_level(logging.WARNING, logger="copdea_fem"):
        result = api.identify(example_copy(tmp_path, band=(150, 900)))
    assert "band: [150 Hz, 900 Hz] reaches past the scan's lines 150..850 Hz" in caplog.text
    assert "f_max" not in caplog.text
    assert result.sets[0].diagram.band == (150.0, 850.0)


def test_a_band_off_the_lines_is_refused_naming_it(tmp_path):
    with pytest.raises(MeasuredDataError, match=r"condition 'z16_v2' band = '\[900 Hz, 1000 Hz\]'"
                                                r" is not allowed"):
        api.identify(example_copy(tmp_path, band=(900, 1000)))


FREQUENCIES = np.arange(1, 401) * 1.25


def _scan(modes):
    positions = paper_grid()
    shapes = membrane_shapes(positions, [family for family, _ in modes])
    return make_scan(FREQUENCIES, [pole(f, zeta) for _, (f, zeta) in modes], shapes, positions)


def test_a_pole_on_the_band_s_last_line_is_dropped():
    """A mode exactly on the band's last line (455 Hz) is not resolved by the band: dropped;
    the one inside kept."""
    scan = _scan([((0, 1, 0.0), (300.0, 0.01)), ((2, 1, 0.3), (455.0, 0.01))])
    modes = identify(scan, f_min=200.0, f_max=455.0)
    assert [m.freq_hz for m in modes] == pytest.approx([300.0], rel=1e-3)


def test_damping_narrower_than_a_line_is_warned(caplog):
    """2 zeta f = 0.6 Hz < df = 1.25 Hz at 300 Hz: a warning names the mode."""
    scan = _scan([((0, 1, 0.0), (300.0, 0.001)), ((2, 1, 0.3), (455.0, 0.01))])
    with caplog.at_level(logging.WARNING, logger="copdea_fem"):
        modes = identify(scan)
    assert len(modes) == 2
    assert "2 zeta f < df = 1.25 Hz" in caplog.text and "300.0 Hz" in caplog.text
    assert "455.0 Hz" not in caplog.text


def test_progress_in_hz(z_records, caplog):
    """The refinement's progress lines give the added poles in Hz, within the band."""
    with caplog.at_level(logging.INFO, logger="copdea_fem"):
        identify(z_records, f_min=150.0, f_max=850.0)
    added = [r.getMessage() for r in caplog.records if r.getMessage().startswith("pole added")]
    assert added
    for message in added:
        frequency = float(message.split()[3])
        assert message.split()[4] == "Hz" and 150.0 <= frequency <= 850.0 + math.ulp(850.0)


@pytest.mark.parametrize("dampings, stable", [((0.001, 0.0012), False), ((0.01, 0.0101), True)])
def test_a_pole_stable_in_frequency_not_in_damping(dampings, stable):
    """One pole at 100 Hz at every order, its damping alternating between two values: 20 %
    apart it is frequency-stable only (the damping check is relative: 0.0002 apart is not
    stable at 0.001) and no mode is chosen; 1 % apart it is stable and chosen."""
    options = {**identification.check_options({}), "band": (50.0, 150.0)}
    orders = []
    for k in range(60):
        zeta = dampings[k % 2]
        omega_n = 2 * math.pi * 100.0 / math.sqrt(1 - zeta ** 2)
        orders.append((np.array([100.0]), np.array([zeta]),
                       np.array([complex(-zeta * omega_n, 2 * math.pi * 100.0)])))
    chosen, status = identification.choose_poles(orders, options)
    expected = identification.STABLE if stable else identification.FREQUENCY_STABLE
    assert all(state[0] == expected for state in status[1:])
    assert chosen.size == (1 if stable else 0)
