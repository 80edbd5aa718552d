r"""The FE forced response where a vibrometer measures: FRFs of velocity per volt at scan points.

What a scanning vibrometer records on a device driven by ``V_b + V~ e^{i omega t}`` is, per
point and direction, the velocity per volt of drive.  The model's counterpart is the FE
forced response of :mod:`copdea_fem.fe.forced.harmonic` (its modal path with the residual
correction, as ``copdea-fem response --set response.method=modal``), with two additions a
real device needs:

- **an imperfect electrode** (:mod:`copdea_fem.fe.forced.electrode`): a uniform electrode
  drives only the axisymmetric order m = 0, yet a scan shows the (m,n) modes of m >= 1 too
  (Fig. 7); a drive weight ``w(theta) = 1 + sum_m delta_m cos(m (theta - theta_m))`` on
  the co-energy drives them, each by the forcing of its own order.  Every driven part of
  the problem is forced with what the weight gives it: each order m (cos and sin families)
  on the axisymmetric engine, each symmetry sector on the 3-D quadrant, the whole plane
  on a whole 3-D mesh;
- **material damping**: each structural mode gets the modal damping of the paper's
  reduced model (Sect. 5.3, eq. 19: ``b_j = (b/m)_j m_j`` in the modal path's denominator,
  ``m_j`` the structural modal mass), ``(b/m)_j`` given per label (e.g. the study's
  ``reduced.damping_*``); its damping ratio is ``(b/m)_j / (2 omega_j)`` times the
  membrane's share of the mode's kinetic energy.  The radiation damping is the coupled
  pencil's own (its complex eigenvalues); a damped eigen step's (Rayleigh, Prony) is in the
  eigenvalues too, while the static correction is the undamped pencil's.

The modes come from the solve of the same study (:func:`copdea_fem.fe.pipeline.run_solve`:
its band per sector or order and the operators it solved), so a response holds exactly
the modes ``solve`` reports, with their labels.  Per mode, the eigenvalue may be moved by
a factor (``frequency_factors``: the scatter of a synthetic measurement); the residual
correction (the modes above the band) is the exact static one.

Convention: the FE's fields go as ``e^{-i omega t}`` (velocity ``-i omega u``); an FRF file
holds ``e^{+i omega t}`` (mobility ``i omega u``), so the returned FRFs are the complex
conjugates of the FE's velocities.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

logger = logging.getLogger(__name__)


@dataclass
class DrivenPart:
    """One independently solved part of the problem (a sector, an order or the whole mesh)
    with its band result.

    ``pencil``: the part's coupled operators (or :class:`copdea_fem.fe.forced.harmonic.DryPencil`),
    ``band``: its eigen result (eigenvalues, vectors on the pencil's unknowns),
    ``sector``: the 3-D sector (None elsewhere), ``m``: the axisymmetric order (None on 3-D).
    """

    key: str
    pencil: object
    band: object
    sector: object = None
    m: int | None = None


@dataclass
class ScanResponse:
    """FRFs of velocity per volt at scan points, and the modes they hold.

    Attributes
    ----------
    frequencies : (F,) array
        Lines [Hz].
    velocity : (P, 3, F) complex array
        Cartesian velocity per volt [m/s/V], ``e^{+i omega t}`` convention (module notes).
    modes : dict
        Structural label -> ``freq_hz`` (as driven, after the scatter), ``damping_ratio``,
        ``static_displacement`` (the mode's largest quasi-static displacement per volt at
        the points [m/V]: how strongly the drive reaches it).
    """

    frequencies: np.ndarray
    velocity: np.ndarray
    modes: dict


def driven_parts(solution, study) -> list[DrivenPart]:
    """The parts of a solve (:class:`copdea_fem.fe.pipeline.SolveResult`) with their pencils
    and band results, in solve order: the coupled operators the solve kept (with air), or
    the dry operators rebuilt for each order (axisymmetric) or the whole plane (3-D)."""
    from copdea_fem.fe.forced.harmonic import DryPencil
    from copdea_fem.vibrometer.sampling import isinstance_axisymmetric

    state, eigen = solution.state, solution.eigen
    bands = getattr(eigen, "by_sector", None) or {"all": eigen}
    axisymmetric = isinstance_axisymmetric(state)
    if solution.coupled is not None:
        pencils = list(solution.coupled.operators)
    elif axisymmetric:
        from copdea_fem.fe.axisymmetric.operators import OrderForms
        forms = OrderForms(state, study)
        pencils = [DryPencil(forms.operators(int(key.split("=")[1]))) for key in bands]
    else:
        from copdea_fem.fe.linearise import linearised_operators
        pencils = [DryPencil(linearised_operators(state, study))]
    parts = []
    for (key, band), pencil in zip(bands.items(), pencils):
        membrane = pencil.membrane
        parts.append(DrivenPart(key, pencil, band,
                                sector=None if axisymmetric else membrane.sector,
                                m=int(membrane.m) if axisymmetric else None))
    return parts


def part_forcing(state, part: DrivenPart, imperfection) -> np.ndarray:
    """The forcing [N/V] of the imperfect electrode on a part's membrane unknowns: the
    order's forcing of the weight ``cos(m theta)`` (axisymmetric: the families' factors are
    applied by the caller), or the sector's of the folded weight (3-D)."""
    if part.m is not None:
        from copdea_fem.fe.axisymmetric.forcing import order_forcing
        return order_forcing(state, part.pencil.membrane)
    from copdea_fem.fe.quadrant.forced import quadrant_forcing
    return quadrant_forcing(state, part.pencil.membrane, imperfection)[0]


def scan_response(solution, study, positions, frequencies, imperfection, *,
                  damping_per_mass, frequency_factors=None) -> ScanResponse:
    """FRFs of velocity per volt at scan points from the FE forced response (module notes).

    Parameters
    ----------
    solution : copdea_fem.fe.pipeline.SolveResult
        The solve of ``study`` (either engine, with or without air).
    study : Study
    positions : (P, 3) array
        Scan points [m] on the prestressed device (:mod:`copdea_fem.vibrometer.sampling`).
    frequencies : (F,) array
        Lines [Hz].
    imperfection : copdea_fem.fe.forced.electrode.ElectrodeImperfection
    damping_per_mass : callable
        ``mode -> (b/m)`` [1/s] of a structural mode (a :class:`copdea_fem.fe.modes.Mode`
        of the solve: its label, frequency, ...; module notes; air modes get none).
    frequency_factors : callable, optional
        ``label -> factor`` on a structural mode's frequency (the eigenvalue times its
        square); the twins of an axisymmetric pair share their column's (the first's).
    """
    import scipy.sparse as sp

    from copdea_fem.fe.forced.harmonic import ForcedOrder, ModalBasis
    from copdea_fem.fe.modes import membrane_energy_fractions
    from copdea_fem.vibrometer.sampling import ScanSampler

    state = solution.state
    frequencies = np.asarray(frequencies, float)
    omega = 2 * np.pi * frequencies
    sampler = ScanSampler(state, positions)
    displacement = np.zeros((len(sampler.positions), 3, frequencies.size), dtype=complex)
    truth = {}
    for part in driven_parts(solution, study):
        families = [("cos", 1.0)] if part.m is None else [
            (family, factor) for family, factor in zip(
                ("cos", "sin"), imperfection.family_weights(part.m)) if factor != 0.0]
        band = part.band
        if not families or len(band.eigenvalues) == 0:
            continue
        force = part_forcing(state, part, imperfection)
        size = part.pencil.membrane.stiffness.shape[0]
        forced = ForcedOrder.from_parts(part.pencil, force, sp.csr_matrix((size, size)), 0.0,
                                        study.eigen.backend)
        eigenvalues = np.asarray(band.eigenvalues, complex)
        shares = (np.asarray(membrane_energy_fractions(part.pencil, band))
                  if len(part.pencil.pressure_index) else np.ones(eigenvalues.size))
        columns = _part_modes(part, solution.modes)          # structural, labelled
        # the paper's modal b/m (eq. 19) per label, in the modal path's denominator
        damping = np.zeros(eigenvalues.size)
        for column, modes in columns.items():
            damping[column] = float(damping_per_mass(modes[0]))
        basis = ModalBasis.build(forced, eigenvalues, band.vectors,
                                 [columns[k][0].label if k in columns else ""
                                  for k in range(eigenvalues.size)], damping)
        if frequency_factors is not None:
            factors = np.ones(eigenvalues.size)
            for column, modes in columns.items():
                factors[column] = float(frequency_factors(modes[0].label))
            basis.eigenvalues = eigenvalues * factors ** 2
        coefficients = basis.coefficients(frequencies)            # (lines, J + 2)
        membrane = forced.membrane(basis.basis)
        full = part.pencil.membrane.to_full(membrane)
        disc = membrane[-1] if part.pencil.membrane.disc_dof else np.zeros(membrane.shape[1])
        static = basis.participation / (basis.norms * basis.eigenvalues)
        for family, factor in families:
            sampled = np.stack([sampler.field_displacement(
                full[:, k], disc[k], sector=part.sector, operators=part.pencil.membrane,
                m=part.m or 0, family=family) for k in range(full.shape[1])], axis=-1)
            displacement += factor * np.einsum("pdk,fk->pdf", sampled, coefficients)
            for column, modes in columns.items():
                peak = float(np.abs(factor * static[column]) * np.abs(sampled[..., column]).max())
                frequency = abs(np.sqrt(basis.eigenvalues[column]).real) / (2 * np.pi)
                material = damping[column] / (4 * np.pi * frequency) * shares[column]
                for mode in modes:
                    if part.m is None or mode.family == family:
                        truth[mode.label] = {"freq_hz": float(frequency),
                                             "damping_ratio": float(mode.damping_ratio
                                                                    + material),
                                             "static_displacement": peak}
        logger.debug("scan response: %s driven (%d modes of the band)", part.key,
                     eigenvalues.size)
    velocity = np.conj(-1j * omega[None, None, :] * displacement)
    return ScanResponse(frequencies, velocity, truth)


def _part_modes(part: DrivenPart, modes) -> dict:
    """Column of the part's band -> the labelled structural modes of that column (the
    axisymmetric cos and sin twins share one), matched by their complex frequency."""
    from copdea_fem.fe.modes import AIR

    freq = _column_frequencies(part.band.eigenvalues)
    found: dict[int, list] = {}
    for mode in modes:
        if mode.kind == AIR or not mode.label:
            continue
        if part.m is not None and mode.m != part.m:
            continue
        if part.sector is not None and mode.sector != part.sector:
            continue
        target = complex(mode.freq_hz, mode.freq_im_hz)
        distance = np.abs(freq - target)
        column = int(np.argmin(distance)) if distance.size else -1
        if column >= 0 and distance[column] <= 1e-6 * max(abs(target), 1.0):
            found.setdefault(column, []).append(mode)
    return found


def _column_frequencies(eigenvalues) -> np.ndarray:
    """Complex frequencies [Hz] of eigenvalues ``lambda = omega^2`` (Re f >= 0), as the
    pipeline computes them."""
    freq = np.sqrt(np.asarray(eigenvalues, complex)) / (2 * np.pi)
    return np.where(freq.real < 0, -freq, freq)
