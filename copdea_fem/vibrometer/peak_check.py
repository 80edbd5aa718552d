"""A cross-check of an identification: the peaks of the summed FRF that no mode explains.

The pole choice (:mod:`copdea_fem.vibrometer.identification`) may miss modes - few
channels, a short record, modes weakly driven - and then reports fewer modes without a
word.  A peak search does not depend on the channels' number: the sum of the FRFs'
magnitudes over the channels,

    S(f) = sum_c |H_c(f)|,

has a local maximum near every resonance that stands out of its neighbours (two modes
closer than a half-power width give one peak; Ewins, *Modal testing*, 2nd ed., Sect. 4.2,
peak picking).  A peak of ``log10 S`` whose prominence (its height above the higher of the
two lowest points that separate it from a higher value or the ends, as
:func:`scipy.signal.find_peaks` defines it; computed here, scipy.signal costing 0.3 s of
imports)
exceeds :data:`PEAK_PROMINENCE` and that has no identified mode within
:data:`PEAK_TOLERANCE_LINES` lines is *unexplained*: a mode is there that the
identification did not find (or two poles of one resonance were dropped).  The converse
does not hold - a split pair is one peak and two modes - so only missing modes are
flagged.
"""

from __future__ import annotations

import numpy as np

#: Least prominence of a peak of log10 of the summed |H| [decades]: 0.05 (12 %, 1 dB).
#: On the example scan (60 dB noise) it finds 10 peaks on the full scan and on its 34
#: out-of-plane records alike; noise alone, summed over the channels, stays below it.
PEAK_PROMINENCE = 0.05
#: A peak is explained by a mode within this many lines of it (the peak of a resonance
#: between two lines, or of a pair, lies up to a line or two off either pole).
PEAK_TOLERANCE_LINES = 2.0


def summed_peaks(frequencies, values) -> np.ndarray:
    """Frequencies [Hz] of the peaks of ``log10 sum_c |H_c|`` (module notes).

    Parameters
    ----------
    frequencies : (F,) float array
        The lines [Hz].
    values : (C, F) complex array
        FRFs (any unit: the prominence is relative).

    Returns
    -------
    (n,) float array
        The peaks' lines [Hz], ascending; the first and last line are never a peak.
    """
    total = np.sum(np.abs(np.asarray(values)), axis=0)
    if not np.all(total > 0):
        return np.zeros(0)
    level = np.log10(total)
    index = [i for i in _local_maxima(level) if _prominence(level, i) >= PEAK_PROMINENCE]
    return np.asarray(frequencies, float)[np.array(index, int)]


def _local_maxima(level) -> np.ndarray:
    """Indices of the strict local maxima of ``level`` (a flat top: its middle), the ends
    excluded."""
    rising = np.flatnonzero(np.diff(level) > 0) + 1          # level[i] > level[i - 1]
    maxima = []
    for start in rising:
        end = start
        while end + 1 < level.size and level[end + 1] == level[start]:
            end += 1
        if end + 1 < level.size and level[end + 1] < level[start]:
            maxima.append((start + end) // 2)
    return np.array(sorted(set(maxima)), int)


def _prominence(level, peak: int) -> float:
    """The peak's height above the higher of the lowest points on either side before a
    higher value (or the end)."""
    height = level[peak]
    left = peak
    while left > 0 and level[left - 1] <= height:
        left -= 1
    right = peak
    while right + 1 < level.size and level[right + 1] <= height:
        right += 1
    return float(height - max(level[left:peak + 1].min(), level[peak:right + 1].min()))


def unexplained_peaks(peaks, mode_frequencies, line_spacing: float) -> np.ndarray:
    """The ``peaks`` [Hz] with no mode of ``mode_frequencies`` [Hz] within
    :data:`PEAK_TOLERANCE_LINES` x ``line_spacing`` [Hz] of them."""
    peaks = np.asarray(peaks, float)
    modes = np.asarray(mode_frequencies, float)
    if modes.size == 0:
        return peaks
    distance = np.min(np.abs(peaks[:, None] - modes[None, :]), axis=1)
    return peaks[distance > PEAK_TOLERANCE_LINES * line_spacing]


__all__ = ["PEAK_PROMINENCE", "PEAK_TOLERANCE_LINES", "summed_peaks", "unexplained_peaks"]
