"""Resonance peaks of a velocity spectrum: frequency, height, width (quality factor).

Used when a condition gives a spectrum and no resonance list
(:func:`condition_peaks`: the measured peaks of a condition), and to read
peak heights and widths for the amplitude/width ratios of the report.

Method, on ``L = ln(v_axial + v_radial)`` (|FFT|/N magnitudes [m/s]):

- line noise ``sigma_L`` from the second differences of L (for white noise
  in L their variance is 6 sigma_L^2), estimated robustly as
  ``1.4826 MAD / sqrt(6)``;
- peaks are local maxima with a topographic prominence of at least
  ``max(5 sigma_L, ln 1.5)`` (:func:`scipy.signal.find_peaks`): five noise
  standard deviations, and never less than a factor 1.5 that the chirp's
  line-to-line ripple (+-25 %, Sect. 4.2) cannot make; and at least 1 % of
  the largest line (a 40 dB usable range: below it the floor's own wiggles
  pass the prominence test);
- frequency: vertex of a parabola fitted to L over the lines within ln sqrt(2)
  of the top (at least the 3 lines around it);
- half-power width from the lines where the spectrum crosses top / sqrt(2)
  (linear interpolation), ``Q = f / width``; nan when the width is under two
  line spacings (not resolved); a hump with Q < 3 is no resonance and dropped
  (the paper's peaks have Q > 10, Sect. 4.3).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.signal

from copdea_fem.diagnosis.compare import MeasuredPeak

MIN_QUALITY = 3.0
DYNAMIC_RANGE = 0.01     # peaks below this fraction of the largest line are not identified


def line_noise(log_values) -> float:
    """Robust standard deviation of the line-to-line noise of a log spectrum [-]."""
    d2 = np.diff(np.asarray(log_values, float), 2)
    mad = np.median(np.abs(d2 - np.median(d2)))
    return float(1.4826 * mad / math.sqrt(6))


def find_spectrum_peaks(frequency_hz, axial, radial, band=None) -> list[MeasuredPeak]:
    """Peaks of a measured spectrum inside ``band`` (module notes)."""
    f = np.asarray(frequency_hz, float)
    total = np.asarray(axial, float) + np.asarray(radial, float)
    positive = total > 0
    floor = np.min(total[positive]) if np.any(positive) else 1.0
    log_total = np.log(np.maximum(total, floor))
    threshold = max(5 * line_noise(log_total), math.log(1.5))
    indices, _ = scipy.signal.find_peaks(log_total, prominence=threshold,
                                         height=math.log(DYNAMIC_RANGE * np.max(total)))
    spacing = float(np.median(np.diff(f)))
    peaks = []
    for index in indices:
        if band is not None and not band[0] <= f[index] <= band[1]:
            continue
        top = log_total[index]
        left = index
        while left > 0 and log_total[left - 1] >= top - 0.5 * math.log(2) and index - left < 50:
            left -= 1
        right = index
        while (right < f.size - 1 and log_total[right + 1] >= top - 0.5 * math.log(2)
               and right - index < 50):
            right += 1
        left, right = min(left, max(index - 1, 0)), max(right, min(index + 1, f.size - 1))
        x, y = f[left:right + 1], log_total[left:right + 1]
        frequency, height = f[index], top
        if x.size >= 3:
            c2, c1, c0 = np.polyfit(x - f[index], y, 2)
            if c2 < 0:
                vertex = -c1 / (2 * c2)
                if abs(vertex) <= (right - left) * spacing:
                    frequency = f[index] + vertex
                    height = c0 - c1 ** 2 / (4 * c2)
        peak_value = math.exp(height)
        width = _half_power_width(f, total, index, peak_value)
        quality = frequency / width if width >= 2 * spacing else math.nan
        if quality < MIN_QUALITY:
            continue                      # a hump, not a resonance
        near = slice(max(index - 1, 0), index + 2)
        ax, rad = float(np.mean(np.asarray(axial)[near])), float(np.mean(np.asarray(radial)[near]))
        peaks.append(MeasuredPeak(frequency_hz=float(frequency), quality_factor=quality,
                                  height=peak_value, radial_ratio=rad / ax if ax > 0 else math.nan,
                                  source="spectrum"))
    return peaks


def _half_power_width(f, values, index, peak_value) -> float:
    level = peak_value / math.sqrt(2)
    left = index
    while left > 0 and values[left] > level:
        left -= 1
    right = index
    while right < f.size - 1 and values[right] > level:
        right += 1
    if values[left] > level or values[right] > level:
        return math.nan
    f_left = np.interp(level, [values[left], values[left + 1]], [f[left], f[left + 1]])
    f_right = np.interp(level, [values[right], values[right - 1]], [f[right], f[right - 1]])
    return float(f_right - f_left)


def peak_height(frequency_hz, values, target_hz, relative_window: float = 0.03) -> float:
    """Largest value within +-``relative_window`` of ``target_hz`` [unit of values]."""
    f = np.asarray(frequency_hz, float)
    inside = np.abs(f / target_hz - 1) <= relative_window
    if not np.any(inside):
        return math.nan
    return float(np.max(np.asarray(values, float)[inside]))


def peak_width(frequency_hz, values, target_hz, relative_window: float = 0.03) -> float:
    """Half-power width [Hz] of the peak nearest ``target_hz`` (nan when not resolved)."""
    f = np.asarray(frequency_hz, float)
    inside = np.flatnonzero(np.abs(f / target_hz - 1) <= relative_window)
    if inside.size == 0:
        return math.nan
    index = int(inside[np.argmax(np.asarray(values)[inside])])
    width = _half_power_width(f, np.asarray(values, float), index, float(values[index]))
    return width if width >= 2 * float(np.median(np.diff(f))) else math.nan


def condition_peaks(condition) -> list[MeasuredPeak]:
    """The measured peaks of a condition: its resonance list (heights and radial ratios
    read from its spectrum, if any), else the peaks found in its spectrum."""
    spectrum = condition.spectrum
    if condition.resonances is None:
        return find_spectrum_peaks(spectrum.frequency_hz, spectrum.axial, spectrum.radial,
                                   condition.band)
    peaks = []
    for r in condition.resonances:
        height = ratio = math.nan
        if spectrum is not None:
            axial = peak_height(spectrum.frequency_hz, spectrum.axial, r.frequency_hz, 0.01)
            radial = peak_height(spectrum.frequency_hz, spectrum.radial, r.frequency_hz, 0.01)
            height = axial + radial
            ratio = radial / axial if axial > 0 else math.nan
        peaks.append(MeasuredPeak(r.frequency_hz, r.label, r.kind, r.quality_factor, height,
                                  ratio, "resonances"))
    return peaks
