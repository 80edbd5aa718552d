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
  frequency of that label; else, with ``effects.air_added_mass =
  incompressible``, the incompressible-air estimate
  (:mod:`copdea_fem.reduced.airmass`); else 0 (dry).
- ``(0,n)``, n >= 3: the FE frequency; else the estimate as above; else 0.
- every ``(0,n)``: times ``effects.air_mass_scale``.

Effect keys (section ``effects``, used by :mod:`copdea_fem.diagnosis`):
``stiffness_scale`` multiplies c10, c20, c01; ``maxwell_scale`` multiplies
the electrostatic term of the static equilibrium and of K_s (eq. 14) -- the
equilibrium is solved at V_eff = sqrt(maxwell_scale) V_b, and the forcing
keeps V_b dC/dq; ``viscoelastic_strength``/``viscoelastic_time`` make the
modal stiffness frequency dependent (:class:`ReducedModel`).  Static
solves are cached per (ring model, z, V_b, maxwell_scale): the diagnosis
re-evaluates the same operating points many times.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np

from copdea_fem.reduced.chirp_response import (
    Chirp,
    ReducedModel,
    added_mass_ratio_from_frequency,
    assemble_reduced_model,
)
from copdea_fem.reduced.modal import ModalBasis, modal_decomposition
from copdea_fem.reduced.rings import Linearisation, RingModel
from copdea_fem.reduced.spring import pumping_added_mass, pumping_frequencies
from copdea_fem.study.schema import damping_key  # noqa: F401  (the reduced model's keys)

_COUPLED_KEYS = {"P1": "coupled_freq_p1", "(0,1)": "coupled_freq_01", "(0,2)": "coupled_freq_02"}


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


def ring_model_of(study, ring_count: int | None = None) -> RingModel:
    """The study's ring model, c10, c20, c01 times ``effects.stiffness_scale``."""
    model = RingModel.from_study(study, ring_count=ring_count)
    scale = study.effects.stiffness_scale
    if scale != 1.0:
        m = model.membrane
        model = model.with_membrane(replace(m, c10=scale * m.c10, c20=scale * m.c20,
                                            c01=scale * m.c01))
    return model


@functools.lru_cache(maxsize=1024)
def operating_point(ring_model: RingModel, z: float, voltage: float,
                    maxwell_scale: float = 1.0):
    """Equilibrium, eq. (14) and dry modes at (z, V_b), electrostatic term scaled (cached).

    Returns
    -------
    linearisation : Linearisation
        K_s with ``maxwell_scale`` V_b^2/2 d2C/dq2; forcing V_b dC/dq (nominal).
    basis : ModalBasis
        Dry modes (eq. 15).
    elastic_hessian : ndarray
        d2U_m/dq2 of the membrane over the generalised coordinates [N/m] (eq. 13,
        no spring, no electrostatic term): the part a visco-elastic modulus stiffens.
    """
    effective = voltage * maxwell_scale ** 0.5
    linearisation = ring_model.operating_point(z, effective)
    eq = linearisation.equilibrium
    free = ring_model.free_dofs
    if effective != voltage:
        gradient, _ = ring_model.capacitance_derivatives(eq.radii, eq.heights, hessian=False)
        linearisation = replace(linearisation, forcing_per_volt=voltage * gradient[free])
    _, hessian = ring_model.elastic_derivatives(eq.radii, eq.heights)
    elastic = hessian[np.ix_(free, free)]
    for array in (linearisation.mass_matrix, linearisation.stiffness_matrix,
                  linearisation.forcing_per_volt, elastic):
        array.setflags(write=False)
    return linearisation, modal_decomposition(ring_model, linearisation), elastic


@functools.lru_cache(maxsize=4096)
def _air_added_mass_ratio(ring_model: RingModel, z: float, voltage: float, maxwell_scale: float,
                          label: str, air_density: float) -> float:
    from copdea_fem.reduced.airmass import ring_mode_added_mass
    linearisation, basis, _ = operating_point(ring_model, z, voltage, maxwell_scale)
    mode = basis[label]
    return ring_mode_added_mass(linearisation.equilibrium, mode.radial, mode.axial, air_density)


def build_reduced(study, fe_frequencies: Mapping[str, float] | None = None) -> ReducedSetup:
    """Static solve, linearisation, modes, Annex I and eq. (19) for a study.

    Parameters
    ----------
    study : copdea_fem.study.Study
    fe_frequencies : mapping label -> Hz, optional
        Coupled frequencies of a FE solve (e.g. from ``modes.json``).
    """
    from copdea_fem.study import reduced_mode_labels
    ring_model = ring_model_of(study)
    load, spring, effects = study.load, study.spring, study.effects
    operating = (ring_model, load.z, load.voltage, effects.maxwell_scale)
    linearisation, basis, elastic_hessian = operating_point(*operating)
    labels = reduced_mode_labels(study.reduced.modes, study.disc.motion)
    modes = basis.truncate(labels)
    fe_frequencies = dict(fe_frequencies or {})
    ratios, sources, damping = [], [], []
    for mode in modes:
        key = _COUPLED_KEYS.get(mode.label)
        given = study.get(f"reduced.{key}") if key else None
        if given is not None:
            ratio, source = added_mass_ratio_from_frequency(mode.frequency_hz, given,
                                                            mode.label), f"reduced.{key}"
        elif mode.label == "P1":
            if study.reduced.pumping_added_mass == "spring":
                disc_amplitude = mode.axial[-1]
                added, _ = pumping_added_mass(mode.angular_frequency ** 2, 1.0, disc_amplitude,
                                              spring.stiffness, spring.mass,
                                              spring.length)
                ratio, source = added, "Annex I spring mass"
            else:
                ratio, source = 0.0, "none (Sect. 5.1)"
        elif mode.label in fe_frequencies:
            ratio = added_mass_ratio_from_frequency(mode.frequency_hz, fe_frequencies[mode.label],
                                                    mode.label)
            source = "modes.json"
        elif effects.air_added_mass == "incompressible":
            ratio = _air_added_mass_ratio(*operating, mode.label, study.air.density)
            source = "incompressible-air estimate"
        else:
            ratio, source = 0.0, "dry (no coupled frequency given)"
        if mode.label != "P1" and effects.air_mass_scale != 1.0:
            ratio *= effects.air_mass_scale
            source += f" x {effects.air_mass_scale:.4g}"
        ratios.append(ratio)
        sources.append(source)
        damping.append(study.get(damping_key(mode.label)))
    reduced = assemble_reduced_model(ring_model, linearisation, modes, ratios, damping,
                                     study.reduced.scan_radii, sources)
    if effects.viscoelastic_strength > 0:
        shapes = np.stack([mode.shape / mode.largest_displacement for mode in modes], axis=1)
        reduced = replace(reduced, elastic_stiffness=np.einsum("ij,ik,kj->j", shapes,
                                                               elastic_hessian, shapes),
                          viscoelastic_strength=effects.viscoelastic_strength,
                          viscoelastic_time=effects.viscoelastic_time)
    pumping = (pumping_frequencies(linearisation.axial_stiffness, spring.stiffness,
                                   study.disc.mass, spring.mass, spring.length, 3)
               if ring_model.disc_free else np.array([]))
    return ReducedSetup(ring_model=ring_model, linearisation=linearisation, basis=basis,
                        reduced=reduced, chirp=Chirp.from_study(study),
                        pumping_frequency_hz=pumping)


def dry_frequencies(study, labels=("P1", "(0,1)", "(0,2)"), ring_count: int | None = None) -> dict:
    """Dry ring-model frequencies {label: Hz} at the study's operating point (eq. 15)."""
    ring_model = ring_model_of(study, ring_count=ring_count)
    _, basis, _ = operating_point(ring_model, study.load.z, study.load.voltage,
                                  study.effects.maxwell_scale)
    return {label: basis[label].frequency_hz for label in labels
            if label in basis.labels}


def spectra_of(setup: ReducedSetup, reduced: ReducedModel | None = None):
    """Velocity spectra of the setup's model under its chirp (Sect. 5.3)."""
    freqs, lines = setup.chirp.lines()
    return (reduced or setup.reduced).spectra(freqs, lines)
