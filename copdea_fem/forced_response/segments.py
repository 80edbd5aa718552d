r"""What each segment of a split electrode drives: the modal forces of ``modal_forcing.csv``
and the response of the segments driven at once.

The segment k driven alone by its AC voltage ``V~_k`` forces the membrane by
``f_k V~_k`` [N], ``f_k`` [N/V] the forcing of its indicator as a weight on the co-energy
(:mod:`copdea_fem.fe.forced.electrode`, :meth:`copdea_fem.fe.engines.Engine.electrode_forcing`):
on the axisymmetric engine the order-m forcing of ``1_r(R) cos(m theta)`` times the
segment's Fourier factors ``c_m``, ``s_m`` on the cos and sin families; on the 3-D quadrant
the forcing of the weight folded onto each symmetry sector.

**Modal force** (``modal_forcing.csv``).  For a structural mode j of the solve with
membrane (and disc) displacement ``u_j`` (the right eigenvector's structural part on the
part's unknowns), mass-normalised on the structural mass of the whole device,

    phi_j = u_j / sqrt(u_j^T M_s u_j),      Q_jk = phi_j^T f_k                       (1)

[N/(V sqrt(kg))]: the generalised force per volt of the segment's AC input on the modal
coordinate ``q_j`` [sqrt(kg) m] of ``u = sum_j phi_j q_j``, whose equation in vacuo is
``q_j'' + omega_j^2 q_j = Q_jk V~_k``.  The transposes are bilinear, not Hermitian (the
coupled modes are complex; for the dry, real modes (1) is the usual mass normalisation).
Its sign (phase) follows the mode's: each ``u_j`` is first turned so that its largest
entry is real and positive.  The quadrant's forms are a quarter of the device's (its mass
and its forcing), so (1) on a sector is twice the quadrant's ``u^T f / sqrt(u^T M u)``.

The twins of an axisymmetric pair (``family`` cos and sin) share their order's vector:
the cos twin's modal force is ``c_m`` times that of the order's forcing, the sin twin's
``s_m`` times it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from copdea_fem.forced_response.files import MODAL_FORCING_COLUMNS
from copdea_fem.forced_response.scan import part_modes

logger = logging.getLogger(__name__)



@dataclass(frozen=True)
class ModalForce:
    """One row of ``modal_forcing.csv``: the modal force (1) of a mode per volt of a
    segment's AC input.

    Attributes
    ----------
    segment : str
        The segment's name.
    label : str
        The mode's label as ``solve`` gives it.
    freq_hz : float
        The mode's frequency Re f [Hz].
    force : complex
        Q_jk [N/(V sqrt(kg))] (module notes, eq. 1).
    """

    segment: str
    label: str
    freq_hz: float
    force: complex


def normalised_structural(part, vectors) -> np.ndarray:
    """The mass-normalised structural parts ``phi_j`` [1/sqrt(kg)] of a part's band vectors
    (module notes, eq. 1; on a 3-D symmetry sector normalised on the whole device's mass,
    four times the quadrant's)."""
    pencil = part.pencil
    structural = np.asarray(vectors, complex)[np.asarray(pencil.membrane_index)]
    largest = np.argmax(np.abs(structural), axis=0)
    turn = np.conj(structural[largest, np.arange(structural.shape[1])])
    structural = structural * (turn / np.abs(turn))[None, :]
    mass = np.einsum("ij,ij->j", structural, pencil.membrane.mass @ structural)
    if part.sector is not None:          # the quadrant's forms are a quarter of the device's
        mass = 4.0 * mass
    return structural / np.sqrt(mass)[None, :]


def modal_forcing(solution, study, weights) -> list[ModalForce]:
    """The modal force (1) of every labelled structural mode of ``solution`` per volt of
    each segment of ``weights``, in the order of the weights, then of the modes' frequency.

    Parameters
    ----------
    solution : copdea_fem.fe.SolveResult
        The solve of ``study`` (either engine; its ``engine`` forces it).
    study : Study
    weights : list of (str, weight, complex)
        The segments (:func:`copdea_fem.fe.forced.electrode.segment_weights`); their drives
        are not used (the force is per volt of each segment's own input).

    Returns
    -------
    list of ModalForce
    """
    rows: dict[str, list[ModalForce]] = {name: [] for name, _, _ in weights}
    for part in solution.engine.driven_parts(solution, study):
        part_modal_forces(solution.engine, solution.state, part,
                          part_modes(part, solution.modes), weights, rows)
    return [row for name in rows for row in sorted(rows[name], key=lambda r: r.freq_hz)]


def part_modal_forces(engine, state, part, columns: dict, weights, rows: dict) -> None:
    """Append to ``rows`` (segment name -> list) the modal forces (1) of one driven part's
    labelled modes ``columns`` (band column -> the modes of that column, the axisymmetric
    twins sharing one)."""
    if not columns:
        return
    phi = normalised_structural(part, part.band.vectors)
    forcings: dict = {}
    scale = 4.0 if part.sector is not None else 1.0      # quarter forcing (notes)
    for name, weight, _ in weights:
        families = dict(part.families(weight))
        key = getattr(weight, "radii", None) if part.m is not None else id(weight)
        if families and key not in forcings:     # an order's forcing depends on rho(R) alone
            forcings[key] = phi.T @ np.asarray(engine.electrode_forcing(state, part, weight),
                                               complex)
        for column, modes in columns.items():
            for mode in modes:                   # a mode the weight does not drive: 0
                factor = families.get(mode.family if part.m is not None else "cos", 0.0)
                force = scale * factor * forcings[key][column] if factor else 0.0
                rows[name].append(ModalForce(name, mode.label, float(mode.freq_hz),
                                             complex(force)))
    logger.debug("modal forcing: %s (%d modes)", part.key, len(columns))


def driven_modal_forcing(problem, weights, engine) -> list[ModalForce]:
    """The modal forces (1) of the structural modes of the study's band (``eigen.f_min`` to
    ``eigen.f_max``, ``|Im f| <= eigen.max_damping_ratio f_max``) of the part of the problem
    ``response`` drives (the order m = 0 or the even-even sector of an
    :class:`copdea_fem.fe.OrderZero`): all a drive reaches when every segment's weight
    drives only that part (one electrode over the whole membrane), at the cost of one band
    solve of its pencil."""
    import types

    from copdea_fem.fe.eigen import solve_band
    from copdea_fem.fe.forced.problem import DrivenPart
    from copdea_fem.fe.modes import AIR
    from copdea_fem.forced_response.run import band_modes

    coupled, eigen = problem.coupled, problem.study.eigen
    found = solve_band(coupled.stiffness, coupled.mass, eigen.f_min, eigen.f_max,
                       factorize=coupled.factorize, hermitian=False,
                       max_imag_hz=eigen.max_damping_ratio * eigen.f_max,
                       backend=eigen.backend, max_modes=eigen.max_modes,
                       residual_tol=eigen.residual_tol)
    modes = band_modes(problem, found.eigenvalues, found.vectors, found.residuals, eigen.f_max)
    band = types.SimpleNamespace(eigenvalues=np.asarray(found.eigenvalues),
                                 vectors=np.asarray(found.vectors))
    part = DrivenPart("driven", coupled, band, m=getattr(coupled.membrane, "m", None),
                      sector=getattr(coupled.membrane, "sector", None))
    columns = {k: [mode] for k, mode in enumerate(modes) if mode.kind != AIR and mode.label
               and eigen.f_min <= mode.freq_hz <= eigen.f_max}
    rows: dict[str, list[ModalForce]] = {name: [] for name, _, _ in weights}
    part_modal_forces(engine, problem.state, part, columns, weights, rows)
    return [row for name in rows for row in sorted(rows[name], key=lambda r: r.freq_hz)]


def drive_of(weights) -> list[tuple]:
    """``[(weight, complex drive), ...]`` of :func:`copdea_fem.fe.forced.electrode.segment_weights`'s
    ``[(name, weight, drive), ...]``."""
    return [(weight, drive) for _, weight, drive in weights]


def drive_segments(problem, weights, engine):
    """``problem`` (an :class:`copdea_fem.fe.OrderZero`) with its forcing replaced by that of
    every segment at once on its driven part (the order m = 0 or the even-even sector):
    ``sum_k conj(d_k) f_k`` [N per volt of input], ``d_k`` the segment's complex drive
    (``e^{+i omega t}``; the FE goes as ``e^{-i omega t}``) and ``f_k`` its weight's forcing
    (:func:`copdea_fem.forced_response.scan.driven_groups`).  The spectra and the sound of
    ``response`` are then the segments' drive on that part."""
    import dataclasses

    from copdea_fem.fe.forced.problem import DrivenPart
    from copdea_fem.forced_response.scan import driven_groups

    coupled = problem.coupled
    part = DrivenPart("driven", coupled, None, m=getattr(coupled.membrane, "m", None),
                      sector=getattr(coupled.membrane, "sector", None))
    total = 0.0
    for force, families in driven_groups(engine, problem.state, part, drive_of(weights)):
        total = total + dict(families).get("cos", 0.0) * np.asarray(force, complex)
    forcing = np.zeros(coupled.stiffness.shape[0], dtype=complex)
    forcing[np.asarray(coupled.membrane_index)] = total
    return dataclasses.replace(problem, forced=dataclasses.replace(problem.forced,
                                                                    forcing=forcing))


#: Angles per radius at which a segmented drive's velocity is sampled (its mean |v| over
#: them is the spectra's value at that radius).
SEGMENT_ANGLES = 16


def segments_velocity(solution, study, weights, frequency_hz, voltage_lines, fractions,
                      angles: int = SEGMENT_ANGLES) -> tuple[np.ndarray, np.ndarray]:
    """Mean |v_axial| and |v_radial| [m/s] (lines, radii) of every segment driven at once,
    through every part of the solve (:func:`copdea_fem.forced_response.scan.scan_response`,
    its modal path with the residual correction and the paper's modal b/m), at reference
    radii ``r_i + f (r_o - r_i)`` (``fractions`` f) on the prestressed device, averaged over
    ``angles`` equally spaced angles; ``voltage_lines`` the complex input per line [V]."""
    from copdea_fem.forced_response.run import modal_damping
    from copdea_fem.forced_response.scan import scan_response

    state = solution.state
    r_i, r_o = state.inner_radius, state.outer_radius
    radii = r_i + np.asarray(fractions, float) * (r_o - r_i)
    theta = 2 * np.pi * np.arange(angles) / angles
    grid_r, grid_theta = np.meshgrid(radii, theta, indexing="ij")       # (radii, angles)
    reference = np.column_stack([(grid_r * np.cos(grid_theta)).ravel(),
                                 (grid_r * np.sin(grid_theta)).ravel()])
    positions = solution.engine.prestressed_positions(state, reference, study.load.z)

    def damping(mode):
        return float(modal_damping([mode.label], [mode.kind], study)[0])

    frequency_hz = np.asarray(frequency_hz, float)
    scan = scan_response(solution, study, positions, frequency_hz, drive_of(weights),
                         damping_per_mass=damping)
    velocity = scan.velocity * np.abs(np.asarray(voltage_lines))[None, None, :]
    direction = reference / np.linalg.norm(reference, axis=1)[:, None]
    radial = np.einsum("pd,pdf->pf", direction, velocity[:, :2, :])
    shape = (radii.size, angles, frequency_hz.size)
    axial = np.abs(velocity[:, 2, :]).reshape(shape).mean(axis=1)
    radial = np.abs(radial).reshape(shape).mean(axis=1)
    return axial.T, radial.T


def segment_response(problem, engine):
    """``copdea-fem response`` of a study's electrode: the forced response of ``problem``
    (:func:`copdea_fem.forced_response.run.forced_response`) and the modal forces of
    ``modal_forcing.csv`` (``result.modal_forcing``).

    One electrode over the whole membrane (no ``electrodes.segments``): the response as it
    always was, and the modal forces of its driven part's band (:func:`driven_modal_forcing`).
    With segments: the driven part forced by every segment at once (:func:`drive_segments`:
    the sound at the axis microphone, which no order m >= 1 reaches), a solve of the study
    for the orders (sectors) the segments drive beyond it (its band up to
    ``response.modal_band`` times the last line, as the modal path's), the modal forces of all its
    parts (:func:`modal_forcing`) and the velocity spectra of every part at once
    (:func:`segments_velocity`, replacing the driven part's); the operating shapes of the
    driven part alone are not written (``result.segments`` names the segments)."""
    import time

    from copdea_fem.fe import run_solve
    from copdea_fem.fe.forced.electrode import segment_weights
    from copdea_fem.forced_response.run import forced_response, spectrum_peaks
    from copdea_fem.reduced.chirp_response import QUARTER_POINTS, scan_fractions

    study = problem.study
    weights = segment_weights(study)
    if not study.electrodes.segments:
        result = forced_response(problem)
        start = time.perf_counter()
        result.modal_forcing = driven_modal_forcing(problem, weights, engine)
        result.timings["modal_forcing"] = time.perf_counter() - start
        return result
    result = forced_response(drive_segments(problem, weights, engine))
    start = time.perf_counter()
    logger.info(f"{len(weights)} electrode segments: the modes of every order the segments "
                "drive (solve) ...")
    # the band of the modal path (response.modal_band times the last line), so that the
    # spectra hold the modes above the lines as the driven part's path does
    reach = max(study.eigen.f_max,
                study.response.modal_band * float(result.frequency_hz.max()))
    solved = study.replace({"eigen.f_max": reach}) if reach > study.eigen.f_max else study
    solution = run_solve(solved, engine=engine)
    result.modal_forcing = [row for row in modal_forcing(solution, solved, weights)
                            if row.freq_hz <= study.eigen.f_max]
    scan = scan_fractions(study.reduced.scan_radii)
    axial, radial = segments_velocity(solution, study, weights, result.frequency_hz,
                                      result.voltage_lines,
                                      np.concatenate([scan, QUARTER_POINTS]))
    result.average_axial = axial[:, :scan.size].mean(axis=1)
    result.average_radial = radial[:, :scan.size].mean(axis=1)
    result.point_axial, result.point_radial = axial[:, scan.size:], radial[:, scan.size:]
    result.peaks_hz = spectrum_peaks(result, study.response.peaks)
    result.segments = [name for name, _, _ in weights]
    result.timings["segments"] = time.perf_counter() - start
    return result


__all__ = ["MODAL_FORCING_COLUMNS", "SEGMENT_ANGLES", "ModalForce", "drive_of", "drive_segments",
           "driven_modal_forcing", "modal_forcing", "part_modal_forces", "normalised_structural", "segment_response", "segments_velocity"]
