r"""Close pairs told apart by their shapes: one identified pole that is two modes.

Why the poles alone cannot.  Two modes of relative split ``delta = (f_2 - f_1) / f`` and
damping ratio ``zeta`` give two peaks in any one FRF only where ``delta`` exceeds about the
half-power bandwidth ``2 zeta`` (the peaks' half-power bands, ``f (1 +- zeta)``, then do not
overlap; Ewins, *Modal testing*, 2nd ed., Sect. 4.2).  Below it the sum of the two
resonances is, on every channel, one peak of nearly the shape of a single mode: the columns
``g(s) = (i w)^k / (i w - s)`` of the two poles differ by ``(s_2 - s_1) dg/ds``, a fraction
``~ delta / (2 zeta)`` of ``g`` in the half-power band.  The stabilisation diagram's merge
tolerance (``frequency_tolerance``, 1 %: tracks within it that never coexist are one mode,
:func:`copdea_fem.vibrometer.identification.choose_poles`) is of the order of the membranes'
``2 zeta`` (0.8-1.6 %), and the principal response functions the poles are fitted on (24)
are fewer than a scan's shapes (the FE-made G1 scan: about 36 above the noise), so the
weak member of a pair split by less than its half-power bandwidth is found neither as a
second track nor by the refinement's residual search.

What tells them apart is the *shapes*.  On the lines of the half-power band around the pole,
``|f - f_r| <= 2 zeta_r f_r`` (both members of a pair split by less than ``2 zeta`` are
there), the channels x lines FRF matrix ``D`` holds one shape per mode: two significant
singular values where two modes of different shapes share the band, however small the
split (the second member of a split (m,n) pair has the shape of the first turned by 90/m
degrees: orthogonal over a ring of points).  Significant: above the largest singular value
noise alone would give, ``sigma (sqrt C + sqrt L)`` (C channels, L lines, sigma^2 the noise
variance per complex value; the edge of the Marchenko-Pastur law) times
:data:`EDGE_MARGIN`.  Where there are two or more, the pole is split: the band's data
projected on its ``q`` significant left singular vectors (``Y``, lines x q) are fitted by
the FRF model of :mod:`copdea_fem.vibrometer.pole_refinement` (variable projection) with the
chosen poles near the band (fixed) and the pole ``s_r`` and a twin started a quarter of its
half-power width above or below it (both refined); the twin is kept when it lowers the cost
by more than the refinement's significance ``ADD_SIGNIFICANCE q sigma^2`` (what a pole fitted
to noise alone lowers it by: well below; :data:`~pole_refinement.ADD_SIGNIFICANCE`) and
stays inside the band with a damping in the allowed range.  The residues on every channel
(LSFD, after this step) then give each member its own shape.  A single mode's band has one
significant singular value (its shape, plus tails of neighbours that the fixed poles
explain): no twin is tried.
"""

from __future__ import annotations

import logging
import math

import numpy as np

logger = logging.getLogger(__name__)

#: Factor on the noise's largest singular value ``sigma (sqrt C + sqrt L)`` above which a
#: singular value of a band's FRF matrix is a shape (module notes): the edge's fluctuation
#: is of order ``sigma (C L)^(1/6)``, 2 % of it at 252 x 20, so 1.5 leaves room for the
#: model error of the neighbours' tails.
EDGE_MARGIN = 1.5
#: Fewest lines of a band (each side of the pole at least half of it): two poles, their
#: conjugates and the two residual terms are six columns of the local fit.
MIN_LINES = 12
#: Shapes (left singular vectors) of a band fitted at most.
MAX_SHAPES = 6


def significant_shapes(block: np.ndarray, noise_variance: float) -> int:
    """How many singular values of ``block`` (channels x lines, complex) exceed
    :data:`EDGE_MARGIN` times the noise's largest, ``sigma (sqrt C + sqrt L)`` (module
    notes); ``noise_variance`` sigma^2 per complex value [data unit^2]."""
    channels, lines = block.shape
    edge = math.sqrt(noise_variance) * (math.sqrt(channels) + math.sqrt(lines))
    singular = np.linalg.svd(block, compute_uv=False)
    return int(np.sum(singular > EDGE_MARGIN * edge))


def band_lines(omega: np.ndarray, pole: complex) -> np.ndarray:
    """Indices of the lines ``|w - w_r| <= 2 zeta_r |s_r|`` (the half-power bandwidth each
    side), widened to :data:`MIN_LINES` around the pole where the band holds fewer."""
    width = 2 * (-pole.real)
    distance = np.abs(omega - pole.imag)
    inside = np.flatnonzero(distance <= width)
    if inside.size >= MIN_LINES:
        return inside
    return np.sort(np.argsort(distance)[:MIN_LINES])


def close_partners(poles) -> np.ndarray:
    """(n,) bool: whether each pole has another within its half-power bandwidth,
    ``|w_r - w_p| <= 2 zeta_r |s_r|`` (the two share one resonance: module notes)."""
    poles = np.asarray(poles, complex)
    distance = np.abs(poles.imag[:, None] - poles.imag[None, :])
    np.fill_diagonal(distance, np.inf)
    return np.any(distance <= 2 * (-poles.real)[:, None], axis=1)


def split_close_poles(omega, values, poles, power, band, max_damping, noise_variance,
                      hz_per_unit=None):
    """``poles`` with a twin added to each pole whose half-power band holds two shapes
    (module notes).

    Parameters
    ----------
    omega : (F,) float array
        The band's angular frequencies, scaled (the poles' unit).
    values : (C, F) complex array
        Every channel's FRF on those lines.
    poles : (n,) complex array
        The chosen (refined) poles, Im > 0.
    power : int
        0, 1, 2: receptance, mobility, accelerance.
    band : (float, float)
        Bounds of the damped frequencies, in the unit of ``omega``.
    max_damping : float
        Upper bound of the damping ratio [-].
    noise_variance : float
        sigma^2 per complex value of ``values`` [data unit^2]
        (:func:`copdea_fem.vibrometer.identification.noise_variance`).
    hz_per_unit : float, optional
        Hz per unit of ``omega`` / (2 pi), for the log (default: rad/s).

    Returns
    -------
    (poles, split) : ((n + split,) complex array, int)
    """
    from copdea_fem.vibrometer.pole_refinement import (
        ADD_SIGNIFICANCE,
        LEAST_DAMPING,
        projection_cost,
        refine,
    )

    hz_per_unit = 1.0 / (2 * math.pi) if hz_per_unit is None else hz_per_unit
    poles = np.asarray(poles, complex)
    values = np.asarray(values, complex)
    out, split = list(poles), 0
    for pole in sorted(poles, key=lambda s: s.imag):
        lines = band_lines(omega, pole)
        block = values[:, lines]
        shapes = min(significant_shapes(block, noise_variance), MAX_SHAPES)
        if shapes < 2:
            continue
        left, _, _ = np.linalg.svd(block, full_matrices=False)
        data = (left[:, :shapes].conj().T @ block).T                   # lines x q
        local_omega = omega[lines]
        span = (local_omega[0], local_omega[-1])
        reach = 3 * (span[1] - span[0])
        neighbours = np.array([s for s in out if s != pole
                               and span[0] - reach <= s.imag <= span[1] + reach], complex)
        before = projection_cost(local_omega, data, np.append(neighbours, pole), power)
        threshold = ADD_SIGNIFICANCE * shapes * noise_variance
        best = None
        for sign in (1.0, -1.0):
            twin = pole + sign * 0.25 * 1j * (-pole.real)
            trial = np.concatenate([neighbours, [pole, twin]])
            free = np.zeros(trial.size, bool)
            free[-2:] = True
            trial = refine(local_omega, data, trial, power, band, max_damping, free=free)
            cost = projection_cost(local_omega, data, trial, power)
            if best is None or cost < best[0]:
                best = (cost, trial[-2:])
        cost, pair = best
        zeta = -pair.real / np.abs(pair)
        ok = (before - cost > threshold and np.all(zeta > 2 * LEAST_DAMPING)
              and np.all(zeta <= max_damping)
              and np.all((pair.imag >= span[0]) & (pair.imag <= span[1]))
              and abs(pair[0] - pair[1]) > 1e-9 * abs(pole))
        if not ok:
            logger.debug("pole at %.2f Hz: %d shapes in its band, one pole kept (cost %.3g -> "
                         "%.3g, threshold %.3g)", pole.imag * hz_per_unit, shapes, before,
                         cost, threshold)
            continue
        logger.info("pole at %.2f Hz split by its shapes (%d in its half-power band): %.2f "
                    "and %.2f Hz (cost %.3g -> %.3g, threshold %.3g)",
                    pole.imag * hz_per_unit, shapes, pair[0].imag * hz_per_unit,
                    pair[1].imag * hz_per_unit, before, cost, threshold)
        out = [s for s in out if s != pole] + list(pair)
        split += 1
    return np.array(sorted(out, key=lambda s: s.imag), complex), split


__all__ = ["EDGE_MARGIN", "MAX_SHAPES", "MIN_LINES", "band_lines", "close_partners",
           "significant_shapes", "split_close_poles"]
