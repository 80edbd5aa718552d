"""Reduced lumped-parameter model of the COP-DEA forced response (Sect. 3.2, Annex I).

Pipeline (each step a pure module; file glue in :mod:`copdea_fem.reduced.io`):

``rings``   ring model: energies (eqs 9-13), static equilibrium, F(z), eq. (14)
``modal``   dry modes (eqs 15-16), labels P1 / (0,n) / IPn, mode profiles (Fig. 9d)
``spring``  Annex I: pumping frequencies (eq. 22) and shapes (eq. 23)
``airmass`` incompressible-air added mass of the axisymmetric modes (eq. 19's m_ad)
``response`` eq. (19) in air, chirp spectra (Sects 4.2, 5.3), damping calibration
``fit``     c10, c20, c01 from force-displacement data (Sect. 5.1)
``model``   everything above for a study: :func:`build_reduced`

Its benchmark is ``python -m benchmarks.reduced`` (``benchmarks/reduced.py``, outside the
package).
"""

from copdea_fem.reduced.chirp_response import (
    QUARTER_POINTS,
    Chirp,
    DampingCalibration,
    ReducedModel,
    SpectrumResult,
    added_mass_ratio_from_frequency,
    assemble_reduced_model,
    calibrate_damping,
    observation_matrix,
    vibrometer_spectrum,
)
from copdea_fem.reduced.fit import MaterialFit, fit_material
from copdea_fem.reduced.modal import ModalBasis, Mode, modal_decomposition, mode_profile
from copdea_fem.reduced.model import ReducedSetup, build_reduced, dry_frequencies, spectra_of
from copdea_fem.reduced.rings import Equilibrium, Linearisation, ReducedModelError, RingModel
from copdea_fem.reduced.spring import (
    pumping_added_mass,
    pumping_frequencies,
    pumping_mode_shape,
    pumping_roots,
    spring_dynamic_stiffness,
)

__all__ = [
    "RingModel", "Equilibrium", "Linearisation", "ReducedModelError",
    "Mode", "ModalBasis", "modal_decomposition", "mode_profile",
    "pumping_frequencies", "pumping_roots", "pumping_mode_shape", "spring_dynamic_stiffness",
    "pumping_added_mass",
    "Chirp", "ReducedModel", "SpectrumResult", "DampingCalibration", "QUARTER_POINTS",
    "assemble_reduced_model", "added_mass_ratio_from_frequency", "calibrate_damping",
    "observation_matrix", "vibrometer_spectrum",
    "ReducedSetup", "build_reduced", "dry_frequencies", "spectra_of",
    "MaterialFit", "fit_material",
]
