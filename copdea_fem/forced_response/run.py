"""``copdea-fem response``: study -> prestress -> m = 0 pencil -> forced response -> files.

Pipeline: mesh, prestress (as ``solve``), the ALE air and the one coupled pencil a uniform
electrode drives -- the engine's forced problem
(:meth:`copdea_fem.fe.engines.Engine.forced_problem`): the order m = 0 on the axisymmetric
engine, the even-even symmetry sector on the 3-D quadrant (any frame, the square one
included) -- the voltage forcing (:mod:`copdea_fem.fe.forced.harmonic`), then either

- ``response.method: auto`` (default): on the 3-D engine ``reduced_modal`` where the
  damping is the paper's modal b/m, ``reduced`` where the membrane states its own loss;
  ``modal`` on the axisymmetric one (:func:`resolved_method`);
- ``response.method: reduced_modal``: the reduced basis below built without a loss of its
  own, its projected pencil's modes damped with ``reduced.damping_*`` as the modal path
  damps its modes (:mod:`.reduced_basis`, eq. 3): the modal path's model at the reduced
  path's cost (refused with ``membrane.loss_factor``, Rayleigh or Prony);
- ``response.method: modal``: the coupled modes with ``Re f <= modal_band f_end``
  and ``|Im f| <= modal_band f_end``, the paper's modal damping ``reduced.damping_*`` and
  ``membrane.loss_factor`` projected per mode, residual correction
  (:mod:`copdea_fem.fe.forced.harmonic`);
- ``response.method: direct``: one sparse solve per line with ``membrane.loss_factor``
  (the modal b/m has no meaning there and is not applied);
- ``response.method: reduced``: the direct path's model (loss factor, Rayleigh, Prony)
  projected on a rational Krylov basis built from a few shifts in the band
  (:mod:`.reduced_basis`), a small dense solve per line.

Lines: the chirp's (``excitation.*``, :class:`copdea_fem.reduced.chirp_response.Chirp`), each
response line ``H(omega_k) V~_k`` with the chirp's line values (|FFT|/N), so the spectra
compare with ``spectrum``'s line for line.

The response on the lines (:class:`.observers.LineResponse`) is observed twice: the membrane
velocity at the scan radii (the driven sector's observer) and the sound at the microphones
(:class:`.observers.Microphones`).

Files (column names are a contract):

- ``response_average.csv``: ``freq_hz, v_axial, v_radial`` [Hz, m/s, m/s] -- the mean of
  |v| over ``reduced.scan_radii`` projected radii, as ``spectrum_average.csv`` (3-D: also
  over the four angles of the driven sector's observer, :class:`copdea_fem.fe.OrderZero`)
- ``response_points.csv``: ``freq_hz, v_axial_q1, v_radial_q1, ..., v_radial_q3`` (3-D: |v|
  averaged over those angles)
- ``spl.csv``: ``freq_hz, spl_<microphone>...`` [Hz, dB re 20 uPa]
- ``response_modes.csv``: ``label, kind, freq_hz, freq_im_hz, damping_per_mass,
  membrane_energy_fraction`` of the modes used (modal path)
- ``modal_forcing.csv``: ``segment, label, freq_hz, force_re, force_im`` -- the modal force
  of each in-band structural mode per volt of each electrode segment's AC input
  [N/(V sqrt(kg))], the mode mass-normalised (:mod:`.segments`; one segment
  ``electrode`` without ``electrodes.segments``)
- ``response.json``: method, far-field method, microphones [m], peaks, powers, timings
- PNGs (``output.plots``): ``response_average.png`` (Fig. 12 style, the reduced model's
  spectrum dashed), ``response_points.png``, ``spl.png``
- ParaView (``output.paraview``): ``ods.pvd`` / ``air_ods.pvd`` -- operating-deflection shapes
  (membrane displacement per volt of the line and velocity; air pressure) at the peaks
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from copdea_fem.fe import check_air_lift
from copdea_fem.forced_response.files import AVERAGE_COLUMNS, MODE_COLUMNS, POINT_COLUMNS  # noqa: F401
from copdea_fem.forced_response.microphone_places import FIELD, microphone_places
from copdea_fem.forced_response.observers import LineResponse, Microphones
from copdea_fem.study import DEFAULT_MICROPHONE, StudyError, listed_microphones

if TYPE_CHECKING:
    from copdea_fem.fe import Engine, Mode, OrderZero
    from copdea_fem.fe.forced.harmonic import ModalBasis
    from copdea_fem.forced_response.reduced_basis import ReducedBasis

logger = logging.getLogger(__name__)


def parse_microphones(study) -> list[tuple[str, np.ndarray]]:
    """Named microphone positions (x, y, z) [m]: ``axis`` at ``response.microphone_distance``
    on the +z axis, then those of ``response.microphones`` ("name = x, y, z; ...", units
    allowed, e.g. ``side = 0.5 m, 0 m, 0.5 m``), parsed and checked as the study was read
    (:func:`copdea_fem.study.listed_microphones`), so a bad one never reaches a solve."""
    response = study.response
    axis = (0.0, 0.0, float(response.microphone_distance))
    listed = listed_microphones(response.microphones, study.geometry.frame,
                                study.geometry.enclosure)
    return [(name, np.array(position))
            for name, position in [(DEFAULT_MICROPHONE, axis), *listed]]


def check_driven_state(study, command: str) -> None:
    """Refuse an operating point where the voltage drives nothing (StudyError naming the key,
    its value and what ``command`` allows): no bias (``load.voltage = 0``) or the flat
    membrane (``load.z = 0``), where the linear forcing V_b dC/du vanishes (the messages
    say why) and every response would be round-off.  Shared by
    ``response`` and ``synth`` (whose data are responses to the voltage)."""
    if study.load.voltage <= 0:
        raise StudyError(f"load.voltage = 0 is not allowed for `{command}`; allowed: > 0 V "
                         "(the linear forcing V_b dC/du vanishes without a bias)")
    if study.load.z == 0:
        raise StudyError(f"load.z = 0 is not allowed for `{command}`; allowed: > 0 m (on the "
                         "flat membrane the voltage does not drive this state: the linear "
                         "forcing V_b dC/du is the divergence of a displacement that vanishes "
                         "at the membrane's fixed edges, int div u dA = 0, so every line's "
                         "response would be round-off)")


def prepare_order_zero(study, *, engine: Engine) -> OrderZero:
    """Mesh, prestress, ALE air and the forced pencil of the driven part of the problem (the
    order m = 0 or the even-even sector: the engine's
    :meth:`copdea_fem.fe.engines.Engine.forced_problem`; ``engine``: the study's, resolved
    by the caller)."""
    check_driven_state(study, "response")
    if study.response.method == "modal" and sealed_enclosure(study):
        raise StudyError("response.method = modal is not allowed with a sealed enclosure; "
                         "allowed: direct, reduced or auto (the modal path's static "
                         "correction A^-1 F does not exist: a uniform cavity pressure and the "
                         "membrane's static deflection under it solve A x = 0, "
                         "copdea_fem.fe.cavity.without_static_solution)")
    if not study.air.outside:
        raise StudyError("air.outside = false is not allowed for `response`; allowed: true "
                         "(the sound at the microphones needs the outside air)")
    if study.electrodes.segments and study.response.microphones.strip():
        raise StudyError(f"response.microphones = {study.response.microphones!r} is not "
                         "allowed with electrodes.segments; allowed: '' (the axis microphone "
                         "alone: the orders m >= 1 a segmented drive reaches radiate nothing "
                         "onto the axis, and their sound elsewhere is not computed)")
    microphone_places(study, parse_microphones(study))
    check_air_lift(study)
    return engine.forced_problem(study)


def modal_solution(problem: OrderZero, f_end: float):
    """(ModalBasis, modes) of the m = 0 band (module doc), labelled as ``solve`` labels them."""
    from copdea_fem.fe.eigen import solve_band
    from copdea_fem.fe.forced.harmonic import ModalBasis

    study, coupled = problem.study, problem.coupled
    reach = study.response.modal_band * f_end
    eigen = study.eigen
    logger.info(f"coupled modes of the {problem.sector.name}, Re f <= {reach:g} Hz, "
                f"|Im f| <= {reach:g} Hz ...")
    result = solve_band(coupled.stiffness, coupled.mass, 0.0, reach, factorize=coupled.factorize,
                        hermitian=False, max_imag_hz=reach, backend=eigen.backend,
                        max_modes=eigen.max_modes, residual_tol=eigen.residual_tol)
    modes = band_modes(problem, result.eigenvalues, result.vectors, result.residuals, reach)
    if study.membrane.prony:
        logger.warning("response.method: modal with membrane.prony: the modal path is a few % "
                       "off the exact response (its static correction uses the relaxed "
                       "stiffness; docs/response.md); response.method: reduced (or direct) is "
                       "exact for any damping")
    damping = modal_damping([m.label for m in modes], [m.kind for m in modes], study)
    basis = ModalBasis.build(problem.forced, result.eigenvalues, result.vectors,
                             [m.label for m in modes], damping)
    return basis, modes


#: Rounds of shifts for the unconverged structural Ritz modes inside the lines.
RITZ_ROUNDS = 3


def band_modes(problem: OrderZero, eigenvalues, vectors, residuals, band_top_hz: float):
    """Classified, labelled modes of the eigenpairs of the driven part's band up to
    ``band_top_hz`` [Hz], named by the rule ``solve`` names them with (the driven sector's
    :attr:`~copdea_fem.fe.forced.problem.DrivenSector.label`: over an enclosure a vent's
    Helmholtz mode is ``cavity(0,0,0)`` and the membrane modes are numbered from their dry
    partners, so that the damping chosen by label, :func:`modal_damping`, is the mode's).
    Air/PML modes (little membrane energy, or damped beyond what ``solve`` looks for: its
    band holds |Im f| <= eigen.max_damping_ratio f_max; PML modes reach zeta ~ 1) get kind
    AIR."""
    import types

    from copdea_fem.fe import AIR

    study = problem.study
    eigen = study.eigen
    freq = np.sqrt(np.asarray(eigenvalues, complex)) / (2 * np.pi)
    freq = np.where(freq.real < 0, -freq, freq)
    result = types.SimpleNamespace(eigenvalues=np.asarray(eigenvalues), vectors=vectors,
                                   freq_hz=freq.real, freq_im_hz=freq.imag,
                                   residuals=np.asarray(residuals))
    modes, pressures = problem.sector.classify(problem, result)
    for mode in modes:
        if (mode.membrane_energy_fraction < study.air.min_membrane_energy
                or mode.damping_ratio > eigen.max_damping_ratio):
            mode.kind = AIR
    problem.sector.label(problem, modes, pressures, band_top_hz)
    return modes


def reduced_modal_solution(problem: OrderZero, frequency_hz):
    """(RitzModes, modes): the reduced basis of the lines (no loss of its own), its modes
    damped with the paper's modal b/m as the modal path damps its modes
    (:mod:`.reduced_basis`, eq. 3).

    The Ritz modes with ``Re f`` and ``|Im f|`` up to ``response.modal_band`` times the last
    line and a relative residual <= ``eigen.residual_tol`` are classified and labelled as
    ``solve`` labels them, and damped by label (:func:`modal_damping`); a structural Ritz
    mode inside the lines above that residual gets a shift of its own and the basis is built
    again (at most :data:`RITZ_ROUNDS` rounds)."""
    import types

    from copdea_fem.fe.modes import AIR, membrane_energy_fractions
    from copdea_fem.forced_response.reduced_basis import build_reduced_basis, ritz_modes

    study, forced = problem.study, problem.forced
    frequency_hz = np.asarray(frequency_hz, float)
    f_last = float(frequency_hz.max())
    reach = study.response.modal_band * f_last
    tolerance = study.eigen.residual_tol
    extra: list[float] = []
    for round_ in range(RITZ_ROUNDS):
        reduced = build_reduced_basis(forced, frequency_hz, 0.0,
                                      tol=study.response.reduced_tol,
                                      extra_shifts_hz=extra)
        ritz = ritz_modes(forced, reduced)
        freq = ritz.frequency
        in_band = (freq.real <= reach) & (np.abs(freq.imag) <= reach)
        converged = in_band & (ritz.residuals <= tolerance)
        suspects = np.flatnonzero(in_band & ~converged & (freq.real <= f_last)
                                  & (freq.real >= float(frequency_hz.min())))
        if suspects.size:
            record = types.SimpleNamespace(vectors=ritz.vectors[:, suspects],
                                           eigenvalues=ritz.eigenvalues[suspects])
            fractions = np.array(membrane_energy_fractions(problem.coupled, record))
            suspects = suspects[fractions >= study.air.min_membrane_energy]
        if not suspects.size:
            break
        if round_ + 1 == RITZ_ROUNDS:
            logger.warning(f"reduced_modal: {suspects.size} structural Ritz mode(s) in the "
                           f"lines not converged (residual > eigen.residual_tol = "
                           f"{tolerance:g}) after {RITZ_ROUNDS} rounds; left undamped")
            break
        extra += [float(f) for f in freq[suspects].real]
        logger.info(f"reduced_modal: {suspects.size} structural Ritz mode(s) not converged; "
                    f"shifts added at " + ", ".join(f"{f:.2f}" for f in freq[suspects].real)
                    + " Hz")
    index = np.flatnonzero(converged)
    index = index[np.argsort(freq[index].real)]
    modes = band_modes(problem, ritz.eigenvalues[index], ritz.vectors[:, index],
                       ritz.residuals[index], reach)
    damping = modal_damping([m.label for m in modes], [m.kind for m in modes], study)
    damped = index[damping > 0]
    ritz.damping[damped] = damping[damping > 0] * ritz.kinetic_shares(forced, damped)
    ritz.mode_index, ritz.damping_per_mass = index, damping
    logger.info(f"reduced_modal: {ritz.size} Ritz modes, {index.size} converged in the band, "
                f"{damped.size} damped with the modal b/m ("
                f"{sum(m.kind != AIR for m in modes)} structural)")
    return ritz, modes


def modal_damping(labels, kinds, study) -> np.ndarray:
    """(b/m)_j [1/s] per mode: ``reduced.damping_*`` by label (the reduced model's key of
    the label, :func:`copdea_fem.study.schema.damping_key`), 0 for air/PML modes."""
    from copdea_fem.fe import AIR
    from copdea_fem.study.schema import damping_key
    values = []
    for label, kind in zip(labels, kinds):
        if kind == AIR:
            values.append(0.0)
            continue
        values.append(float(study.get(damping_key(label))))
    return np.array(values)


def states_material_damping(study) -> bool:
    """Whether the membrane carries its own loss (``membrane.loss_factor``, Rayleigh or a
    Prony series): the model the direct and reduced paths solve, with no modal b/m."""
    membrane = study.membrane
    return bool(membrane.loss_factor > 0 or membrane.rayleigh_alpha > 0
                or membrane.rayleigh_beta > 0 or membrane.prony)


def sealed_enclosure(study) -> bool:
    """Whether the study's membrane closes an enclosure without a vent (air enabled)."""
    g = study.geometry
    return (study.air.enabled and g.enclosure != "none"
            and g.enclosure_vent_radius == 0)


def resolved_method(problem: OrderZero) -> str:
    """``response.method``, with ``auto`` resolved: ``direct`` over a sealed enclosure (no
    static correction, :func:`sealed_enclosure`); else by what the driven sector prefers:
    where the study's damping is the paper's modal b/m (``reduced.damping_*``: no loss of the
    membrane's own), the sector's ``modal_method`` -- ``reduced_modal`` on the 3-D engine
    (its modal band costs minutes; the reduced basis's own modes, damped per mode),
    ``modal`` on the axisymmetric one; else its ``default_method`` -- ``reduced`` on the
    3-D engine, ``modal`` on the axisymmetric one."""
    method = problem.study.response.method
    if method != "auto":
        return method
    if sealed_enclosure(problem.study):
        return "direct"
    if problem.sector is None:
        return "modal"
    if not states_material_damping(problem.study):
        return problem.sector.modal_method
    return problem.sector.default_method


@dataclass
class ResponseResult:
    """Spectra (per line, chirp amplitudes applied) and what produced them."""

    frequency_hz: np.ndarray
    average_axial: np.ndarray         # m/s
    average_radial: np.ndarray
    point_axial: np.ndarray           # (lines, 3) m/s
    point_radial: np.ndarray
    microphones: list[tuple[str, np.ndarray]]   # (name, position (x, y, z) [m])
    pressure: np.ndarray              # (lines, microphones) complex amplitude [Pa]
    spl_db: np.ndarray                # (lines, microphones)
    method: str
    far_field: str
    modes: list[Mode]
    basis: ModalBasis | ReducedBasis | None     # modal, reduced, or None (direct)
    vectors: np.ndarray               # (n, K) basis vectors
    weights: np.ndarray               # (lines, K): x(line) = vectors @ weights[line]
    problem: OrderZero
    timings: dict
    peaks_hz: list = field(default_factory=list)
    voltage_lines: np.ndarray | None = None     # (lines,) complex input per line [V]
    modal_forcing: list = field(default_factory=list)   # ModalForce rows (.segments)
    segments: list = field(default_factory=list)   # the segments driven (none: one electrode)

    def solution(self, line: int) -> np.ndarray:
        """Scaled solution vector of one line (chirp amplitude applied)."""
        return self.vectors @ self.weights[line]


def _far_field_method(study) -> str:
    if study.geometry.frame == "baffle":
        closed = study.geometry.enclosure != "none"
        return ("Rayleigh (baffle): Kirchhoff-Helmholtz with the half-space Green's function over "
                "the hemisphere on the microphone's side" + (
                    " (the front only: an enclosure closes the back)" if closed else ""))
    return "Kirchhoff-Helmholtz over a sphere inside the air (free-space Green's function)"


def forced_response(problem: OrderZero, frequency_hz=None,
                    voltage_lines=None) -> ResponseResult:
    """Spectra and SPL on the chirp's lines (or given lines and complex amplitudes [V])."""
    from copdea_fem.fe.forced.radiation import spl_db
    from copdea_fem.reduced.chirp_response import QUARTER_POINTS, Chirp, scan_fractions

    study, forced, coupled = problem.study, problem.forced, problem.coupled
    timings = dict(problem.timings)
    if frequency_hz is None:
        frequency_hz, voltage_lines = Chirp.from_study(study).lines()
    frequency_hz = np.asarray(frequency_hz, float)
    voltage_lines = np.asarray(voltage_lines, complex)
    method, eta = resolved_method(problem), study.membrane.loss_factor
    start = time.perf_counter()
    modes, basis = [], None
    if method == "modal":
        basis, modes = modal_solution(problem, float(frequency_hz.max()))
        vectors = basis.basis
        weights = basis.coefficients(frequency_hz, eta) * voltage_lines[:, None]
    elif method == "reduced_modal":
        logger.info(f"reduced basis (rational Krylov) on {frequency_hz.size} lines, its modes "
                    "damped with the modal b/m (reduced.damping_*) ...")
        basis, modes = reduced_modal_solution(problem, frequency_hz)
        vectors = basis.vectors
        weights = basis.coefficients(frequency_hz) * voltage_lines[:, None]
    elif method == "reduced":
        from copdea_fem.forced_response.reduced_basis import build_reduced_basis
        logger.info(f"reduced basis (rational Krylov) on {frequency_hz.size} lines; the "
                    "direct path's damping (membrane.loss_factor, rayleigh_*, prony and the "
                    "radiation), not the modal path's b/m (reduced.damping_*) ...")
        basis = build_reduced_basis(forced, frequency_hz, eta,
                                    tol=study.response.reduced_tol)
        vectors = basis.vectors
        weights = basis.line_coefficients * voltage_lines[:, None]
    else:
        logger.info(f"direct solves on {frequency_hz.size} lines ...")
        vectors = forced.direct(frequency_hz, eta)
        weights = np.diag(voltage_lines)
    timings["solve"] = time.perf_counter() - start
    response = LineResponse(forced, vectors, weights)
    start = time.perf_counter()
    omega = 2 * np.pi * frequency_hz
    observer_type, angles = problem.sector.observer, problem.sector.angles
    membrane = response.membrane()
    spectra = []
    for fractions in (scan_fractions(study.reduced.scan_radii), QUARTER_POINTS):
        obs = observer_type(problem.state, coupled.membrane, fractions)
        axial, radial = obs.observe(membrane)
        # |v| per point, then the mean over the angles of each radius (3-D: the square frame)
        spectra.append(tuple(np.abs(omega[:, None] * (weights @ part.T)).reshape(
            frequency_hz.size, angles, -1).mean(axis=1) for part in (axial, radial)))
    (scan_axial, scan_radial), (point_axial, point_radial) = spectra
    timings["velocity"] = time.perf_counter() - start
    start = time.perf_counter()
    microphones = parse_microphones(study)
    places = microphone_places(study, microphones)
    far_field = _far_field_method(study) + "".join(
        f"; {name}: the FE's own pressure at the point (inside the Kirchhoff sphere)"
        for (name, _), place in zip(microphones, places) if place == FIELD)
    observer = microphone_observer(study, problem.sector.sphere, coupled, microphones, places)
    pressure = observer.observe(response, frequency_hz)
    timings["sound"] = time.perf_counter() - start
    result = ResponseResult(frequency_hz, scan_axial.mean(axis=1), scan_radial.mean(axis=1),
                            point_axial, point_radial, microphones, pressure, spl_db(pressure),
                            method, far_field, modes, basis, vectors, weights,
                            problem, timings)
    result.peaks_hz = spectrum_peaks(result, study.response.peaks)
    result.voltage_lines = voltage_lines
    return result


def microphone_observer(study, sphere, coupled, microphones, places=None) -> Microphones:
    """The :class:`.observers.Microphones` of ``response`` on a driven part's ``coupled``
    pencil (``sphere``: its Kirchhoff sphere sampler type,
    :attr:`copdea_fem.fe.forced.problem.DrivenSector.sphere`); ``places`` as
    :func:`.microphone_places.microphone_places` gives them (None: found here)."""
    from copdea_fem.fe.forced.radiation import KIRCHHOFF_FRACTION
    if places is None:
        places = microphone_places(study, microphones)
    return Microphones(sphere, coupled, microphones,
                       KIRCHHOFF_FRACTION * study.air.domain_radius,
                       baffle=study.geometry.frame == "baffle",
                       enclosed=study.geometry.enclosure != "none",
                       sound_speed=study.air.sound_speed, places=places)


def spectrum_peaks(result: ResponseResult, count: int) -> list[float]:
    """The ``count`` highest local maxima of the average axial + radial spectrum [Hz]."""
    from scipy.signal import find_peaks
    total = result.average_axial + result.average_radial
    index, _ = find_peaks(total)
    best = index[np.argsort(total[index])[::-1][:count]]
    return sorted(float(result.frequency_hz[k]) for k in best)


def reduced_spectrum(study, result: ResponseResult):
    """The reduced model's spectra on the same lines, added masses from the FE coupled
    frequencies of this response (``None`` when the reduced model cannot be built)."""
    from copdea_fem.reduced.model import build_reduced, spectra_of
    from copdea_fem.reduced.rings import ReducedModelError
    fe = {mode.label: mode.freq_hz for mode in result.modes if mode.kind != "air"}
    try:
        setup = build_reduced(study, fe)
    except (ReducedModelError, StudyError):
        return None, None
    return setup, spectra_of(setup)


def summary_lines(result: ResponseResult) -> list[str]:
    study = result.problem.study
    g, load = study.geometry, study.load
    where = result.problem.sector.summary
    lines = [f"{study.name}: forced response ({where}, {result.method}), r_i = "
             f"{1e3 * g.inner_radius:g} mm, z = {1e3 * load.z:g} mm, V_b = "
             f"{load.voltage / 1e3:g} kV, frame {g.frame}, {result.frequency_hz.size} lines",
             f"far field: {result.far_field}"]
    if result.modes:
        listed = [(mode, damping) for mode, damping in zip(result.modes,
                                                          result.basis.damping_per_mass)
                  if mode.kind != "air" and mode.freq_hz <= result.frequency_hz.max()]
        width = max([8] + [len(mode.label) for mode, _ in listed])    # cavity(0,0,0): 13
        lines.append(f"{'mode':>{width}} {'Re f Hz':>9} {'Im f Hz':>9} {'b/m 1/s':>8} "
                     f"{'membrane KE':>11}")
        for mode, damping in listed:
            lines.append(f"{mode.label:>{width}} {mode.freq_hz:9.2f} {mode.freq_im_hz:9.2f} "
                         f"{damping:8.1f} {mode.membrane_energy_fraction:11.3f}")
    for f in result.peaks_hz:
        k = int(np.argmin(abs(result.frequency_hz - f)))
        lines.append(f"peak {f:8.2f} Hz: v_axial {1e3 * result.average_axial[k]:.4g} mm/s, "
                     f"v_radial {1e3 * result.average_radial[k]:.4g} mm/s, SPL "
                     + ", ".join(f"{name} {result.spl_db[k, j]:.1f} dB"
                                 for j, (name, _) in enumerate(result.microphones)))
    lines.append("timings: " + ", ".join(f"{k} {v:.2f} s" for k, v in result.timings.items()))
    return lines
