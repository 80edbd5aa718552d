"""Measured data: a ``measured.yaml`` and the files it names, read and checked before any
model runs.

``manifest``      ``measured.yaml`` -> :class:`MeasuredSet` (the base study, the conditions,
                  the noise model; :func:`load_measured`)
``csv_files``     the resonance and spectrum CSVs of a condition
``observation``   ``observed:`` (the mode families a measurement can see) and ``pairing:``
``scan``          :class:`ScanData`, one vibrometer scan in SI and in the model's frame
``scan_files``    :func:`read_scan`: a scan file read by the reader of its suffix
``mode_sets``     :func:`read_mode_set`: mode shapes another program identified (dataset 55)
                  as channels (:class:`MeasuredModes`)
``uff``           the Universal File Format reader (``uff_units``: its unit labels in SI;
                  ``uff_writer``: :func:`write_scan`)
``geometry``      where the scan points lie on the prestressed device
``errors``        :class:`MeasuredDataError`, raised by every reader here

The package sits below the vibrometer's identification and pairing
(:mod:`copdea_fem.vibrometer`) and the diagnosis (:mod:`copdea_fem.diagnosis`), which read
what it makes; the diagnosis gives the manifest reader its effects (:class:`EffectRules`).
"""

from copdea_fem.measured.csv_files import (
    Resonance,
    Spectrum,
    normalise_label,
    read_resonances,
    read_spectrum,
)
from copdea_fem.measured.errors import MeasuredDataError
from copdea_fem.measured.manifest import (
    Condition,
    EffectRules,
    MeasuredSet,
    NoiseModel,
    load_measured,
    parse_measured,
)
from copdea_fem.measured.mode_sets import MeasuredModes, read_mode_set
from copdea_fem.measured.observation import ObservedFamilies, PairingSettings
from copdea_fem.measured.scan import ScanData, ScanFrame
from copdea_fem.measured.scan_files import SCAN_READERS, read_scan
from copdea_fem.measured.uff_writer import write_scan

__all__ = ["SCAN_READERS", "Condition", "EffectRules", "MeasuredDataError", "MeasuredModes",
           "MeasuredSet", "NoiseModel", "ObservedFamilies", "PairingSettings", "Resonance",
           "ScanData", "ScanFrame", "Spectrum", "load_measured", "normalise_label",
           "parse_measured", "read_mode_set", "read_resonances", "read_scan", "read_spectrum",
           "write_scan"]
