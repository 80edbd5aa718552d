"""Build the reduced model of a study: static state, eq. (14), modes, Annex I, eq. (19).

Pure: no files.  Coupled FE frequencies read from a ``modes.json`` come in as
a ``{label: frequency_hz}`` mapping (see :mod:`copdea_fem.reduced.io`).

Added mass per kept mode (eq. 19), first rule that applies:

- ``P1``: ``reduced.coupled_freq_p1``; else, with ``reduced.pumping_added_mass
  = spring``, the biasing spring's distributed mass projected on P1
  (:func:`copdea_fem.reduced.spring.pumping_added_mass`, so that P1 sits where
  Annex I puts it); else 0 (Sect. 5.1: the air's added mass on P1 is small
  next to the disc).  The FE's P1 is not used: the FE spring has no mass.
- ``(0,1)``, ``(0,2)``: ``reduced.coupled_freq_01/02``; else the FE
  frequency of that label; else 0 (dry).
- ``(0,n)``, n >= 3: the FE frequency; else 0 (dry).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from copdea_fem.reduced.modal import ModalBasis, modal_decomposition
from copdea_fem.reduced.response import (Chirp, ReducedModel, added_mass_ratio_from_frequency,
                                         assemble_reduced_model)
from copdea_fem.reduced.rings import Linearisation, RingModel
from copdea_fem.reduced.spring import pumping_added_mass, pumping_frequencies

_COUPLED_KEYS = {"P1": "coupled_freq_p1", "(0,1)": "coupled_freq_01", "(0,2)": "coupled_freq_02"}
_DAMPING_KEYS = {"P1": "damping_p1", "(0,1)": "damping_01", "(0,2)": "damping_02"}


def damping_key(label: str) -> str:
    """The study key holding b/m of a mode label (``reduced.damping_higher`` past (0,2))."""
    return "reduced." + _DAMPING_KEYS.get(label, "damping_higher")


@dataclass(frozen=True)
class ReducedSetup:
    """Everything the forced-response runs need, at one operating point.

    Attributes
    ----------
    ring_model : RingModel
    linearisation : Linearisation
        Equilibrium at (load.z, load.voltage) and eq. (14).
    basis : ModalBasis
        All dry modes (eq. 15).
    reduced : ReducedModel
        The truncated model in air (eq. 19).
    chirp : Chirp
        The excitation (Sect. 4.2).
    pumping_frequency_hz : ndarray
        P1, P2, P3 from eq. (22) with k_DE of the ring model [Hz]; empty when
        the disc is held.
    """

    ring_model: RingModel
    linearisation: Linearisation
    basis: ModalBasis
    reduced: ReducedModel
    chirp: Chirp
    pumping_frequency_hz: np.ndarray


def build_reduced(study, fe_frequencies: Mapping[str, float] | None = None) -> ReducedSetup:
    """Static solve, linearisation, modes, Annex I and eq. (19) for a study.

    Parameters
    ----------
    study : copdea_fem.study.Study
    fe_frequencies : mapping label -> Hz, optional
        Coupled frequencies of a FE solve (e.g. from ``modes.json``).
    """
    from copdea_fem.study import reduced_mode_labels
    ring_model = RingModel.from_study(study)
    load, spring = study["load"], study["spring"]
    linearisation = ring_model.operating_point(load["z"], load["voltage"])
    basis = modal_decomposition(ring_model, linearisation)
    labels = reduced_mode_labels(study["reduced"]["modes"], study["disc"]["motion"])
    modes = basis.truncate(labels)
    fe_frequencies = dict(fe_frequencies or {})
    ratios, sources, damping = [], [], []
    for mode in modes:
        key = _COUPLED_KEYS.get(mode.label)
        given = study["reduced"][key] if key else None
        if given is not None:
            ratio, source = added_mass_ratio_from_frequency(mode.frequency_hz, given,
                                                            mode.label), f"reduced.{key}"
        elif mode.label == "P1":
            if study["reduced"]["pumping_added_mass"] == "spring":
                disc_amplitude = mode.axial[-1]
                added, _ = pumping_added_mass(mode.angular_frequency ** 2, 1.0, disc_amplitude,
                                              spring["stiffness"], spring["mass"],
                                              spring["length"])
                ratio, source = added, "Annex I spring mass"
            else:
                ratio, source = 0.0, "none (Sect. 5.1)"
        elif mode.label in fe_frequencies:
            ratio = added_mass_ratio_from_frequency(mode.frequency_hz, fe_frequencies[mode.label],
                                                    mode.label)
            source = "modes.json"
        else:
            ratio, source = 0.0, "dry (no coupled frequency given)"
        ratios.append(ratio)
        sources.append(source)
        section, name = damping_key(mode.label).split(".")
        damping.append(study[section][name])
    reduced = assemble_reduced_model(ring_model, linearisation, modes, ratios, damping,
                                     study["reduced"]["scan_radii"], sources)
    pumping = (pumping_frequencies(linearisation.axial_stiffness, spring["stiffness"],
                                   study["disc"]["mass"], spring["mass"], spring["length"], 3)
               if ring_model.disc_free else np.array([]))
    return ReducedSetup(ring_model=ring_model, linearisation=linearisation, basis=basis,
                        reduced=reduced, chirp=Chirp.from_study(study),
                        pumping_frequency_hz=pumping)


def dry_frequencies(study, labels=("P1", "(0,1)", "(0,2)"), ring_count: int | None = None) -> dict:
    """Dry ring-model frequencies {label: Hz} at the study's operating point (eq. 15)."""
    ring_model = RingModel.from_study(study, ring_count=ring_count)
    lin: Linearisation = ring_model.operating_point(study["load"]["z"], study["load"]["voltage"])
    basis: ModalBasis = modal_decomposition(ring_model, lin)
    return {label: basis[label].frequency_hz for label in labels
            if label in basis.labels}


def spectra_of(setup: ReducedSetup, reduced: ReducedModel | None = None):
    """Velocity spectra of the setup's model under its chirp (Sect. 5.3)."""
    freqs, lines = setup.chirp.lines()
    return (reduced or setup.reduced).spectra(freqs, lines)
