"""Poles refined on the FRF model itself, and the modes the stabilisation diagram missed.

The stabilisation diagram (:mod:`copdea_fem.vibrometer.identification`) chooses poles that
LSCF returns at many orders; LSCF's polynomial is a linearised fit, and modes closer than
a half-power width that are weakly excited (a device's non-axisymmetric modes, driven by
its imperfections only) come and go between orders.  Here the chosen poles are taken as a
start of the *nonlinear* least-squares fit of the FRF model of the identification's module
notes,

    H(w) = Phi(w; s) A,   Phi = [(i w)^k / (i w - s_r), (i w)^k / (i w - conj(s_r)),
                                 (i w)^(k - 2), (i w)^k],

on the scan's principal response functions ``Y`` (lines x q; the first ``q`` left singular
vectors of the channels x lines FRF matrix: the same fit on every channel up to the noise
left out).  The residues ``A`` enter linearly, so they are eliminated (variable projection,
Golub & Pereyra, SIAM J. Numer. Anal. 10, 1973): the cost of the poles alone is

    J(s) = || (I - P(s)) Y ||_F^2,   P = the orthogonal projector on the columns of Phi,

minimised over every pole's damped frequency and decay rate (scipy's trust-region least
squares).  Two poles a fraction of a half-power width apart are told apart by this fit
where the peaks merge.

**Missing modes** are then added one at a time (a greedy, residual-driven search): the
pole ``s`` on a grid (every line of the band at a few damping ratios) whose column, made
orthogonal to the current model's, takes the most of the residual ``(I - P) Y`` is added,
all poles refined again, and the mode kept when it lowers the cost by more than chance
would: ``dJ > ADD_SIGNIFICANCE x q x sigma^2`` with ``sigma^2`` the noise variance per
complex value, estimated from the channel space outside the q principal functions (the
singular values of the FRF matrix past the q-th hold noise only), and by more than
``ENERGY_FLOOR`` of the data's energy (clean data: no mode fitted to round-off).  The
new pole and its neighbours within 10 % are fitted at each step, all poles once at the
end.  Last, a pole is dropped when removing it (the residues refitted) raises the cost by
less than the same threshold: a pole the noise would hide is not a mode.
"""

from __future__ import annotations

import logging
import math

import numpy as np

logger = logging.getLogger(__name__)

#: A mode is added when the cost drops by more than this many q sigma^2 (module notes; with
#: pure noise the best of the grid's candidates lowers it by about 2-3 q sigma^2: two
#: complex residues per principal function, the frequency and damping chosen on the grid).
ADD_SIGNIFICANCE = 8.0
#: ... and by more than this fraction of the data's energy (a mode 60 dB below the data).
ENERGY_FLOOR = 1e-6
#: Damping ratios of the candidate poles of the search (the membrane's 0.5-2 %).
CANDIDATE_DAMPINGS = (0.003, 0.007, 0.015, 0.03)
#: The least damping ratio a refined pole may take (the fit's bound; a pole there is a
#: spike between two lines, not a resolved resonance).
LEAST_DAMPING = 1e-5
#: Modes added to one scan at most.
MAX_ADDED = 24


def _basis(omega, poles, power):
    """Phi of the module notes on ``omega`` [rad/s, scaled] for ``poles`` (n,) complex."""
    iw = 1j * omega[:, None]
    columns = [iw ** power / (iw - poles[None, :]), iw ** power / (iw - np.conj(poles)[None, :]),
               iw ** (power - 2), iw ** power]
    return np.hstack(columns)


def _orthonormal(matrix):
    """An orthonormal basis of the column space (rank-revealing: duplicates add nothing)."""
    left, singular, _ = np.linalg.svd(matrix, full_matrices=False)
    return left[:, singular > 1e-10 * singular[0]] if singular.size else left


def _poles(parameters):
    """Poles from (damped frequency, log decay rate) pairs (scaled units)."""
    omega_d, log_decay = parameters[0::2], parameters[1::2]
    return -np.exp(log_decay) + 1j * omega_d


def _parameters(poles):
    return np.column_stack([poles.imag, np.log(-poles.real)]).ravel()


def model_residual(omega, data, poles, power):
    """``(I - P) Y`` of the module notes: the data the model's columns leave (the residues
    and residual terms fitted by least squares), (F, q) like ``data``."""
    basis = _orthonormal(_basis(omega, poles, power))
    return data - basis @ (basis.conj().T @ data)


def projection_cost(omega, data, poles, power) -> float:
    """J of the module notes: the data's energy left outside the model's columns (the
    residues and residual terms fitted by least squares) [data unit^2]."""
    return float(np.sum(np.abs(model_residual(omega, data, poles, power)) ** 2))


def refine(omega, data, poles, power, band, max_damping, free=None):
    """Poles minimising J (module notes), started from ``poles``.

    Parameters
    ----------
    omega : (F,) float array
        Angular frequencies of the lines, scaled (any unit: the poles come back in it).
    data : (F, q) complex array
        Principal response functions on those lines.
    poles : (n,) complex array
        Start (Im > 0, Re < 0), in the unit of ``omega``.
    power : int
        0, 1, 2: receptance, mobility, accelerance.
    band : (float, float)
        Bounds of the damped frequencies, in the unit of ``omega``.
    max_damping : float
        Upper bound of the damping ratio.
    free : (n,) bool array, optional
        The poles fitted (default: all); the others stay as given.

    Returns
    -------
    (n,) complex array
        The refined poles (the start where the fit fails).
    """
    from scipy.optimize import least_squares

    poles = np.asarray(poles, complex)
    if poles.size == 0:
        return poles

    free = np.ones(poles.size, bool) if free is None else np.asarray(free, bool)
    fixed = _parameters(poles)
    mask = np.repeat(free, 2)

    def full(parameters):
        out = fixed.copy()
        out[mask] = parameters
        return out

    def residual(parameters):
        value = model_residual(omega, data, _poles(full(parameters)), power)
        return np.concatenate([value.real.ravel(), value.imag.ravel()])

    def jacobian(parameters):
        # Kaufman's approximation of the variable-projection Jacobian: d r / d theta =
        # -(I - P) (d Phi / d theta) A, A = Phi^+ Y the residues at theta (the term with
        # d Phi^+ / d theta dropped: it vanishes at a zero residual and costs as much again)
        current = _poles(full(parameters))
        n = current.size
        left, singular, right_h = np.linalg.svd(_basis(omega, current, power),
                                                full_matrices=False)
        rank = singular > 1e-10 * singular[0]
        left, singular, right_h = left[:, rank], singular[rank], right_h[rank]
        residues = right_h.conj().T @ ((left.conj().T @ data) / singular[:, None])
        index = np.flatnonzero(free)
        iw = 1j * omega[:, None]
        d_upper = iw ** power / (iw - current[None, index]) ** 2             # d column / d s
        d_lower = iw ** power / (iw - np.conj(current)[None, index]) ** 2    # ... d conj(s)
        d_upper = d_upper - left @ (left.conj().T @ d_upper)
        d_lower = d_lower - left @ (left.conj().T @ d_lower)
        # (F, q, free poles): each pole's two columns times their residues
        upper = d_upper[:, None, :] * residues[index].T[None, :, :]
        lower = d_lower[:, None, :] * residues[n + index].T[None, :, :]
        # s = -exp(log decay) + i omega_d: ds/d omega_d = i, ds/d log decay = -decay
        decay = np.exp(full(parameters)[1::2][index])
        by_frequency = -(1j * upper - 1j * lower)
        by_decay = decay * (upper + lower)
        out = np.empty((2, data.shape[0], data.shape[1], index.size, 2))
        out[0, ..., 0], out[1, ..., 0] = by_frequency.real, by_frequency.imag
        out[0, ..., 1], out[1, ..., 1] = by_decay.real, by_decay.imag
        return out.reshape(2 * data.size, 2 * index.size)

    start = fixed
    low = np.column_stack([np.full(poles.size, band[0]),
                           np.log(LEAST_DAMPING * np.abs(poles))]).ravel()
    high = np.column_stack([np.full(poles.size, band[1]),
                            np.log(max_damping * np.abs(poles) * 1.5)]).ravel()
    start = np.clip(start, low + 1e-9 * np.abs(low), high - 1e-9 * np.abs(high))[mask]
    low, high = low[mask], high[mask]
    try:
        result = least_squares(residual, start, jac=jacobian, bounds=(low, high), x_scale="jac",
                               max_nfev=30, method="trf")
    except (ValueError, np.linalg.LinAlgError) as error:
        logger.info("pole refinement failed (%s): the LSCF poles kept", error)
        return poles
    return _poles(full(result.x))


def add_missing(omega, data, poles, power, band, max_damping, noise_variance, hz_per_unit=None):
    """``poles`` refined, with the modes the diagram missed added (module notes).

    Parameters as :func:`refine`; ``noise_variance`` [data unit^2] per complex value
    (None: unknown, no mode is added - a few channels leave no space for noise alone
    beside the modes', and without the noise's size an added pole fits model error: on
    three measured beam FRFs, eleven such poles).  ``hz_per_unit``: Hz per unit of
    ``omega`` / (2 pi) - the progress lines give the poles' frequencies in Hz (default:
    ``omega`` in rad/s).

    Returns
    -------
    (poles, added) : ((n,) complex array, int)
    """
    hz_per_unit = 1.0 / (2 * math.pi) if hz_per_unit is None else hz_per_unit
    energy = float(np.sum(np.abs(data) ** 2))
    poles = refine(omega, data, poles, power, band, max_damping)
    if noise_variance is None:
        return poles, 0
    # a start pole the fit ran off with (past max_damping: no mode, dropped by the caller)
    # would refuse every trial below; the search finds the mode it stood for again
    runaway = -poles.real / np.abs(poles) > max_damping
    if np.any(runaway):
        logger.info("%d start poles left out of the search (the fit took them past damping "
                    "%.3g): %s", int(np.sum(runaway)), max_damping,
                    ", ".join(f"{p.imag * hz_per_unit:.1f} Hz" for p in poles[runaway]))
        poles = poles[~runaway]
    cost = projection_cost(omega, data, poles, power)
    threshold = max(ENERGY_FLOOR * energy, ADD_SIGNIFICANCE * data.shape[1] * noise_variance)
    in_band = (omega >= band[0]) & (omega <= band[1])
    grid = np.array([complex(-zeta * w / math.sqrt(1 - zeta ** 2), w)
                     for w in omega[in_band] for zeta in CANDIDATE_DAMPINGS])
    added = 0
    while added < MAX_ADDED and cost > threshold:
        basis = _orthonormal(_basis(omega, poles, power))
        residual = data - basis @ (basis.conj().T @ data)
        iw = 1j * omega[:, None]
        candidates = iw ** power / (iw - grid[None, :])
        candidates = candidates - basis @ (basis.conj().T @ candidates)
        norms = np.sum(np.abs(candidates) ** 2, axis=0)
        gains = np.sum(np.abs(candidates.conj().T @ residual) ** 2, axis=1) / np.maximum(
            norms, 1e-300)
        best = int(np.argmax(gains))
        if gains[best] <= threshold:
            break
        # the new pole and its neighbours within 10 % fitted (the others barely move: a
        # resonance's column is small away from it), all of them once at the end
        trial = np.append(poles, grid[best])
        trial = refine(omega, data, trial, power, band, max_damping,
                       free=np.abs(trial.imag / grid[best].imag - 1) < 0.1)
        trial_cost = projection_cost(omega, data, trial, power)
        zeta = -trial.real / np.abs(trial)
        if cost - trial_cost <= threshold or np.any(zeta > max_damping):
            break
        logger.info("pole added at %.1f Hz (damping %.3g): cost %.3g -> %.3g (threshold "
                    "%.3g)", trial[-1].imag * hz_per_unit, zeta[-1], cost, trial_cost,
                    threshold)
        poles, cost, added = trial, trial_cost, added + 1
    if added:
        poles = refine(omega, data, poles, power, band, max_damping)
    return _pruned(omega, data, poles, power, threshold, hz_per_unit), added


def _pruned(omega, data, poles, power, threshold, hz_per_unit):
    """``poles`` without those whose removal raises the cost by less than ``threshold``
    (the residues refitted; the least needed one first, one at a time)."""
    cost = projection_cost(omega, data, poles, power)
    while poles.size:
        increases = [projection_cost(omega, data, np.delete(poles, r), power) - cost
                     for r in range(poles.size)]
        weakest = int(np.argmin(increases))
        if increases[weakest] > threshold:
            break
        logger.info("pole at %.1f Hz removed: the cost rises by %.3g only (threshold %.3g)",
                    poles[weakest].imag * hz_per_unit, increases[weakest], threshold)
        poles = np.delete(poles, weakest)
        cost += increases[weakest]
    return poles
