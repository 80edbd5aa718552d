r"""The FE forced response where a vibrometer measures: FRFs of velocity per volt at scan points
(the synthetic export of ``copdea-fem synth --format uff``).

What a scanning vibrometer records on a device driven by ``V_b + V~ e^{i omega t}`` is, per
point and direction, the velocity per volt of drive.  The model's counterpart is the FE
forced response of :mod:`copdea_fem.fe.forced.harmonic` (its modal path with the residual
correction, as ``copdea-fem response --set response.method=modal``), with two additions a
real device needs:

- **an imperfect electrode** (:mod:`copdea_fem.fe.forced.electrode`, an input: the uniform
  electrode is ``ElectrodeImperfection()``): a uniform electrode drives only the
  axisymmetric order m = 0, yet a scan shows the (m,n) modes of m >= 1 too (Fig. 7); a drive
  weight ``w(theta) = 1 + sum_m delta_m cos(m (theta - theta_m))`` on the co-energy drives
  them, each by the forcing of its own order.  Every driven part of the solve
  (:meth:`copdea_fem.fe.engines.Engine.driven_parts`: each order m, cos and sin families, on
  the axisymmetric engine, each symmetry sector on the 3-D quadrant, the whole plane on a
  whole 3-D mesh) is forced with what the weight gives it
  (:meth:`copdea_fem.fe.engines.Engine.electrode_forcing`);
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
correction (the modes above the band) is the exact static one.  Over a sealed enclosure A
has no inverse (the static pair lambda = 0 of a uniform cavity pressure, which a forcing
of the membrane does not excite): the correction is then the static one of the other pairs
(:func:`copdea_fem.fe.forced.harmonic.null_pair`).

Each part's response on the lines (:class:`.observers.LineResponse`, as ``response``'s) is
observed at the scan points (:class:`.observers.ScanPoints`, the engine's fields there).

Convention: the FE's fields go as ``e^{-i omega t}`` (velocity ``-i omega u``); an FRF file
holds ``e^{+i omega t}`` (mobility ``i omega u``), so the returned FRFs are the complex
conjugates of the FE's velocities.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from copdea_fem.forced_response.observers import LineResponse, ScanPoints

logger = logging.getLogger(__name__)


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


def scan_response(solution, study, positions, frequencies, electrode, *,
                  damping_per_mass, frequency_factors=None) -> ScanResponse:
    """FRFs of velocity per volt at scan points from the FE forced response (module notes).

    Parameters
    ----------
    solution : copdea_fem.fe.SolveResult
        The solve of ``study`` (either engine, with or without air; its ``engine`` drives
        and samples it).
    study : Study
    positions : (P, 3) array
        Scan points [m] on the prestressed device
        (:meth:`copdea_fem.fe.engines.Engine.prestressed_positions`).
    frequencies : (F,) array
        Lines [Hz].
    electrode : weight or list of (weight, complex)
        The electrode's drive weight (the protocol of :mod:`copdea_fem.fe.forced.electrode`;
        ``ElectrodeImperfection()``: the uniform electrode), or a drive of several
        segments at once: ``[(weight, amplitude), ...]``, each segment's complex AC volts
        per volt of input in the FRFs' ``e^{+i omega t}`` convention
        (:func:`copdea_fem.fe.forced.electrode.segment_weights`'s drives).
    damping_per_mass : callable
        ``mode -> (b/m)`` [1/s] of a structural mode (a :class:`copdea_fem.fe.Mode` of the
        solve: its label, frequency, ...; module notes; air modes get none).
    frequency_factors : callable, optional
        ``label -> factor`` on a structural mode's frequency (the eigenvalue times its
        square); the twins of an axisymmetric pair share their column's (the first's).
    """
    engine, state = solution.engine, solution.state
    frequencies = np.asarray(frequencies, float)
    omega = 2 * np.pi * frequencies
    points = ScanPoints(engine.point_sampler(state, positions), frequencies.size)
    truth: dict = {}
    drive = list(electrode) if isinstance(electrode, (list, tuple)) else [(electrode, 1.0)]
    for part in engine.driven_parts(solution, study):     # an empty band: its static part
        for force, families in driven_groups(engine, state, part, drive):
            _drive_part(solution, study, part, force, families, points, frequencies,
                        damping_per_mass, frequency_factors, truth)
    velocity = np.conj(-1j * omega[None, None, :] * points.displacement)
    return ScanResponse(frequencies, velocity, truth)


def driven_groups(engine, state, part, drive) -> list[tuple[np.ndarray, list]]:
    """``(force, [(family, factor), ...])`` per forcing a part needs for a drive
    ``[(weight, amplitude), ...]`` (amplitudes complex, ``e^{+i omega t}``: the FE's
    ``e^{-i omega t}`` forcing takes their conjugates).  On the axisymmetric engine one per
    radial factor of the weights (the order's forcing of ``rho(R) cos m theta``), the
    family factors summed over the weights sharing it; on the 3-D engine one, the sum of
    the weights' forcings (factor 1).  One weight of amplitude 1: its own forcing and
    factors, unchanged."""
    groups: dict = {}
    for weight, amplitude in drive:
        families = part.families(weight)
        if not families:
            continue
        scale = np.conj(complex(amplitude))
        if part.m is not None:
            key = getattr(weight, "radii", None)
            if key not in groups:
                groups[key] = [engine.electrode_forcing(state, part, weight), {}]
            for family, factor in families:
                sums = groups[key][1]
                sums[family] = sums.get(family, 0.0) + (factor if scale == 1 else scale * factor)
        else:
            force = engine.electrode_forcing(state, part, weight)
            force = force if scale == 1 else scale * np.asarray(force, complex)
            if None in groups:
                groups[None][0] = groups[None][0] + force
            else:
                groups[None] = [force, {"cos": 1.0}]
    return [(force, [(family, factor) for family, factor in sums.items() if factor != 0.0])
            for force, sums in groups.values()]


def part_line_response(solution, study, part, force, frequencies, damping_per_mass,
                       frequency_factors=None):
    """One part's modal response (module notes) to the forcing ``force`` [N per volt] on the
    lines ``frequencies`` [Hz]: ``(LineResponse, ModalBasis, columns, damping)`` with
    ``columns`` of :func:`part_modes` and ``damping`` the modal b/m [1/s] per column."""
    import scipy.sparse as sp

    from copdea_fem.fe.forced.harmonic import ForcedOrder, ModalBasis
    from copdea_fem.forced_response.run import sealed_enclosure

    band = part.band
    size = part.pencil.membrane.stiffness.shape[0]
    forced = ForcedOrder.from_parts(part.pencil, force, sp.csr_matrix((size, size)), 0.0,
                                    study.eigen.backend)
    eigenvalues = np.asarray(band.eigenvalues, complex)
    columns = part_modes(part, solution.modes)          # structural, labelled
    # the paper's modal b/m (eq. 19) per label, in the modal path's denominator
    damping = np.zeros(eigenvalues.size)
    for column, modes in columns.items():
        damping[column] = float(damping_per_mass(modes[0]))
    basis = ModalBasis.build(forced, eigenvalues, band.vectors,
                             [columns[k][0].label if k in columns else ""
                              for k in range(eigenvalues.size)], damping,
                             singular=sealed_enclosure(study))
    if frequency_factors is not None:
        factors = np.ones(eigenvalues.size)
        for column, modes in columns.items():
            factors[column] = float(frequency_factors(modes[0].label))
        basis.eigenvalues = eigenvalues * factors ** 2
    response = LineResponse(forced, basis.basis, basis.coefficients(frequencies))
    return response, basis, columns, damping


def _drive_part(solution, study, part, force, families, points, frequencies, damping_per_mass,
                frequency_factors, truth) -> None:
    """The response of one part under one forcing ``force``, its families by ``families``,
    added to ``points``; its modes' frequency, damping and static reach into ``truth``."""
    from copdea_fem.fe.modes import membrane_energy_fractions

    if not families:
        return
    response, basis, columns, damping = part_line_response(
        solution, study, part, force, frequencies, damping_per_mass, frequency_factors)
    eigenvalues = np.asarray(part.band.eigenvalues, complex)
    shares = (np.asarray(membrane_energy_fractions(part.pencil, part.band))
              if len(part.pencil.pressure_index) and eigenvalues.size
              else np.ones(eigenvalues.size))
    static = basis.participation / (basis.norms * basis.eigenvalues)
    for family, factor in families:
        sampled = points.basis(response, part.pencil.membrane, family)
        points.add(response, sampled, factor)
        for column, modes in columns.items():
            peak = float(np.abs(factor * static[column]) * np.abs(sampled[..., column]).max())
            frequency = abs(np.sqrt(basis.eigenvalues[column]).real) / (2 * np.pi)
            material = damping[column] / (4 * np.pi * frequency) * shares[column]
            for mode in modes:
                if part.m is None or mode.family == family:
                    reach = max(peak, truth.get(mode.label, {}).get("static_displacement",
                                                                    0.0))
                    truth[mode.label] = {"freq_hz": float(frequency),
                                         "damping_ratio": float(mode.damping_ratio
                                                                + material),
                                         "static_displacement": reach}
    logger.debug("scan response: %s driven (%d modes of the band)", part.key,
                 eigenvalues.size)


def part_modes(part, modes) -> dict:
    """Column of the part's band -> the labelled structural modes of that column (the
    axisymmetric cos and sin twins share one), matched by their complex frequency."""
    from copdea_fem.fe import AIR

    freq = column_frequencies(part.band.eigenvalues)
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


def column_frequencies(eigenvalues) -> np.ndarray:
    """Complex frequencies [Hz] of eigenvalues ``lambda = omega^2`` (Re f >= 0), as the
    pipeline computes them."""
    freq = np.sqrt(np.asarray(eigenvalues, complex)) / (2 * np.pi)
    return np.where(freq.real < 0, -freq, freq)


__all__ = ["ScanResponse", "column_frequencies", "driven_groups", "part_line_response",
           "part_modes", "scan_response"]
