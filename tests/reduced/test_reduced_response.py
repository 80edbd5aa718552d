"""Eq. (19) in air, chirp spectra and damping calibration (Sects 4.2, 5.1, 5.3)."""

import math

import numpy as np
import pytest
from reduced_helpers import paper_study

from copdea_fem.reduced.chirp_response import (
    QUARTER_POINTS,
    Chirp,
    added_mass_ratio_from_frequency,
    calibrate_damping,
    observation_matrix,
    vibrometer_spectrum,
)
from copdea_fem.reduced.model import build_reduced, spectra_of
from copdea_fem.reduced.rings import ReducedModelError


def test_chirp_lines_of_the_paper():
    chirp = Chirp()
    freqs, lines = chirp.lines()
    assert chirp.sample_count == 2000 and freqs.size == 800
    assert freqs[0] == pytest.approx(1.25) and freqs[-1] == pytest.approx(1000.0)
    # Parseval: the chirp's mean square A^2/2 spreads over 2 x 800 two-sided lines,
    # so in-band lines are ~ A / (2 sqrt(800)); the Fresnel ripple of a linear chirp
    # stays within +-25 % away from the band edges
    inside = np.abs(lines[40:-40])
    expected = chirp.amplitude / (2 * math.sqrt(800))
    assert np.all(np.abs(inside / expected - 1) < 0.25)


def test_vibrometer_normalisation_is_fft_over_n():
    """A sine of amplitude A on line k shows |FFT|/N = A/2 there (two-sided FFT/N)."""
    n, k, amplitude = 2000, 37, 3.0
    t = np.arange(n)
    spectrum = vibrometer_spectrum(amplitude * np.sin(2 * math.pi * k * t / n))
    assert abs(spectrum[k]) == pytest.approx(amplitude / 2, rel=1e-12)
    assert np.max(np.abs(np.delete(spectrum, k))) < 1e-12


def test_observation_points_sit_at_quarter_widths():
    setup = build_reduced(paper_study())
    eq = setup.linearisation.equilibrium
    matrix, radii = observation_matrix(eq, QUARTER_POINTS)
    width = eq.radii[0] - eq.radii[-1]
    assert np.allclose(radii, eq.radii[-1] + np.array(QUARTER_POINTS) * width)
    assert np.allclose(matrix.sum(axis=1), 1.0)
    assert np.allclose(matrix @ eq.radii, radii)        # the interpolation lands on the point


def test_average_spectrum_is_the_mean_magnitude_over_the_scan_points():
    """Two scan radii sit at 1/4 and 3/4 of the width, i.e. on Q1 and Q3."""
    result = spectra_of(build_reduced(paper_study(reduced__scan_radii=2)))
    assert np.allclose(result.average_axial, 0.5 * (result.point_axial[:, 0]
                                                    + result.point_axial[:, 2]), rtol=1e-12)
    assert np.allclose(result.average_radial, 0.5 * (result.point_radial[:, 0]
                                                      + result.point_radial[:, 2]), rtol=1e-12)


def test_single_mode_peak_height_and_width_match_the_closed_form():
    """One mode in air: |v| peaks at w_c with height |u f| V / b, half-power width b / (m + m_ad).

    A fine grid (spacing 1e-3 of the width) keeps the sampled peak within
    2 (0.5e-3 / 0.5)^2 ~ 2e-6 of the true one and the width within one spacing.
    """
    study = paper_study(motion="held", reduced__modes="(0,1)", reduced__coupled_freq_01=400.0,
                        reduced__damping_01=245.0)
    reduced = build_reduced(study).reduced
    m, k = reduced.modal_mass[0], reduced.modal_stiffness[0]
    m_total, b = m + reduced.added_mass[0], reduced.damping[0]
    force = reduced.modal_force_per_volt[0]
    assert math.sqrt(k / m_total) / (2 * math.pi) == pytest.approx(400.0, rel=1e-12)
    assert b / m == pytest.approx(245.0)
    width_hz = b / m_total / (2 * math.pi)
    spacing = 1e-3 * width_hz
    freqs = 400.0 + np.arange(-3000, 3001) * spacing
    result = reduced.spectra(freqs, np.ones(freqs.size))            # 1 V on every line
    speed = result.point_axial[:, 1]                                 # Q2
    expected_peak = abs(reduced.point_axial[1, 0] * force) / b
    assert np.max(speed) == pytest.approx(expected_peak, rel=1e-5)
    assert freqs[np.argmax(speed)] == pytest.approx(400.0, abs=spacing)
    band = freqs[speed >= np.max(speed) / math.sqrt(2)]
    assert band[-1] - band[0] == pytest.approx(width_hz, abs=2 * spacing)


def test_added_mass_from_the_coupled_frequency():
    assert added_mass_ratio_from_frequency(500.0, 400.0) == pytest.approx(0.5625)
    with pytest.raises(ReducedModelError, match="coupled frequency of \\(0,1\\) = 600 Hz"):
        added_mass_ratio_from_frequency(500.0, 600.0, "(0,1)")


def test_paper_added_mass_ranges_give_frequencies_in_the_paper_band():
    """Added mass 45-80 % / 25-30 % of modal mass (Sect. 5.1) puts both structural
    peaks inside the chirp band, with dry frequencies up to 30 % above (Sect. 5.2)."""
    study = paper_study(reduced__coupled_freq_01=400.0, reduced__coupled_freq_02=930.0)
    reduced = build_reduced(study).reduced
    ratio = reduced.added_mass / reduced.modal_mass
    assert 0.45 <= ratio[1] <= 0.80 and 0.25 <= ratio[2] <= 0.30
    assert np.all(reduced.dry_frequency_hz[1:] / reduced.frequency_hz[1:] <= 1.30)


def peak_heights(z, voltage):
    """Average-spectrum peak heights (mean of axial and radial) of P1, (0,1), (0,2).

    Added masses at fixed shares of the modal mass inside the paper's ranges
    (Sect. 5.1: 60 % for (0,1), 27 % for (0,2)), so that only V_b changes.
    """
    dry = build_reduced(paper_study(z=z, voltage=voltage)).reduced.dry_frequency_hz
    setup = build_reduced(paper_study(z=z, voltage=voltage,
                                      reduced__coupled_freq_01=dry[1] / math.sqrt(1.60),
                                      reduced__coupled_freq_02=dry[2] / math.sqrt(1.27)))
    result = spectra_of(setup)
    heights = []
    for f in setup.reduced.frequency_hz:
        near = np.abs(result.frequency_hz - f) <= 0.05 * f
        heights.append(0.5 * (result.average_axial[near].max() + result.average_radial[near].max()))
    return np.array(heights)


def test_raising_the_bias_raises_the_peaks_at_z_18mm():
    """Sect. 5.3, Fig. 13: 2 -> 3 kV at z = 18 mm raises every resonance peak (paper: 30-40 %)."""
    assert np.all(peak_heights(0.018, 3000.0) > peak_heights(0.018, 2000.0))


def test_flat_membrane_has_no_axial_response():
    """z = 0 is the singular configuration (Sect. 2): dC/dz = 0, no axial forcing."""
    result = spectra_of(build_reduced(paper_study(z=0.0)))
    assert np.max(result.average_axial) == 0.0


def test_damping_calibration_recovers_the_damping_that_made_the_spectrum():
    study = paper_study(reduced__coupled_freq_01=400.0, reduced__coupled_freq_02=930.0)
    setup = build_reduced(study)
    measured = spectra_of(setup)                                   # b/m = 45, 245, 57
    start = setup.reduced.with_damping_per_mass([10.0, 500.0, 150.0])
    calibration = calibrate_damping(start, setup.chirp, measured.frequency_hz,
                                    measured.average_axial, measured.average_radial)
    assert np.allclose(calibration.damping_per_mass, [45.0, 245.0, 57.0], rtol=1e-6)
    assert np.allclose(calibration.model_peak, calibration.measured_peak, rtol=1e-8)


def test_damping_calibration_refuses_an_unreachable_peak():
    setup = build_reduced(paper_study(reduced__coupled_freq_01=400.0,
                                      reduced__coupled_freq_02=930.0))
    measured = spectra_of(setup)
    with pytest.raises(ReducedModelError, match="measured peak of P1"):
        calibrate_damping(setup.reduced, setup.chirp, measured.frequency_hz,
                          1e3 * measured.average_axial, 1e3 * measured.average_radial)
    dry = build_reduced(paper_study())                 # dry (0,2) at ~1054 Hz: out of band
    with pytest.raises(ReducedModelError, match="\\(0,2\\) at 1054.0 Hz is not allowed"):
        calibrate_damping(dry.reduced, dry.chirp, measured.frequency_hz,
                          measured.average_axial, measured.average_radial)
