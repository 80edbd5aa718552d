"""Modes another program identified (a condition's ``modes:`` mode set,
:class:`copdea_fem.measured.mode_sets.MeasuredModes`) as the test modes the pairing takes
(:class:`copdea_fem.vibrometer.identified.IdentifiedMode`), in place of the modes
:mod:`copdea_fem.vibrometer.identification` finds in a scan."""

from __future__ import annotations

from copdea_fem.vibrometer.identification import modal_phase_collinearity
from copdea_fem.vibrometer.identified import IdentifiedMode


def modes_of_set(mode_set, f_min: float = 0.0, f_max: float = float("inf")
                 ) -> tuple[IdentifiedMode, ...]:
    """The modes another program identified (:class:`copdea_fem.measured.mode_sets.
    MeasuredModes`) within ``[f_min, f_max]`` [Hz], as test modes along the set's channels
    (numbered 1.. in order of frequency; the MPC of each shape as for an identified one)."""
    kept = [k for k in range(mode_set.n_modes) if f_min <= mode_set.freq_hz[k] <= f_max]
    return tuple(IdentifiedMode(test_mode=number, freq_hz=float(mode_set.freq_hz[k]),
                                damping_ratio=float(mode_set.damping_ratio[k]),
                                shape=mode_set.shapes[:, k],
                                mpc=modal_phase_collinearity(mode_set.shapes[:, k]))
                 for number, k in enumerate(kept, 1))


__all__ = ["modes_of_set"]
