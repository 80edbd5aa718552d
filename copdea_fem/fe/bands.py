"""Band rules shared by both engines: band-solver options, the dry partner band, the coupled
start count, and the stop rule of an order-by-order (axisymmetric) solve.

* The band solver is built once from ``study.eigen`` (:class:`BandSolver`) and handed
  to the engine.
* The dry partner band of a coupled solve reaches :data:`DRY_PARTNER_FACTOR` ``f_max``:
  a wet mode lies below its dry partner, and an added mass above 125 % of a modal mass
  would be needed for a wet mode below ``f_max`` with its dry partner above 1.5 ``f_max``
  (f_wet = f_dry / sqrt(1 + added/modal)).
* The coupled solve starts with as many Ritz vectors as there are dry partners in
  ``[f_min, 1.1 f_max]``, plus 2 (:func:`coupled_start_modes`).
* Order loops (:class:`OrderStop`): the modes of order m lie above the lowest mode of
  that order; frequency does not rise with m for the higher modes of an order, so an
  order with nothing in the band says nothing about the next one.  The loop stops at
  the first order m >= 1 whose lowest mode lies above the top of the band *and* above
  the lowest mode of order m - 1 (the lowest modes checked to rise, not assumed).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from copdea_fem.fe.eigen import solve_band
from copdea_fem.fe.eigen.damped import solve_structural_band

log = logging.getLogger(__name__)

#: The dry partner band of a coupled solve reaches this multiple of f_max (module doc).
DRY_PARTNER_FACTOR = 1.5
#: Pencils up to this size take their lowest eigenvalue from a dense solve.
DENSE_LOWEST = 400


@dataclass(frozen=True)
class BandSolver:
    """The band solves of one study (``study.eigen``): its band [Hz] and the options of
    :func:`copdea_fem.fe.eigen.solve_band`, read once."""

    f_min: float
    f_max: float
    backend: str
    max_modes: int
    residual_tol: float
    max_damping_ratio: float
    factor_memory_gb: float

    @classmethod
    def from_study(cls, study) -> "BandSolver":
        eigen = study.eigen
        return cls(eigen.f_min, eigen.f_max, eigen.backend, eigen.max_modes,
                   eigen.residual_tol, eigen.max_damping_ratio, eigen.factor_memory_gb)

    @property
    def dry_partner_top(self) -> float:
        """Top of the dry partner band of a coupled solve [Hz] (module doc)."""
        return DRY_PARTNER_FACTOR * self.f_max

    @property
    def max_imag_hz(self) -> float:
        """Half-height in Im f of a coupled band [Hz]: eigen.max_damping_ratio f_max."""
        return self.max_damping_ratio * self.f_max

    def solve(self, stiffness, mass, f_min: float, f_max: float, hermitian: bool = True,
              damping=None, **extra):
        """The band [f_min, f_max] with the study's options: :func:`copdea_fem.fe.eigen.solve_band`
        on ``K x = omega^2 M x``, or, with ``damping`` (:class:`copdea_fem.fe.eigen.damped.
        DampingTerms`: Rayleigh C, Prony branches), the quadratic/rational step in omega of
        :func:`copdea_fem.fe.eigen.damped.solve_structural_band`, whose band reaches
        ``|Im f| <= eigen.max_damping_ratio f_max`` when ``extra`` sets no ``max_imag_hz``."""
        options = dict(backend=self.backend, max_modes=self.max_modes,
                       residual_tol=self.residual_tol, hermitian=hermitian, **extra)
        if damping is None or damping.empty:
            return solve_band(stiffness, mass, f_min, f_max, **options)
        return solve_structural_band(stiffness, mass, f_min, f_max, damping,
                                     damped_imag_hz=self.max_damping_ratio * f_max, **options)


def coupled_start_modes(dry_freq_hz, f_min: float, f_max: float) -> int:
    """Ritz vectors the coupled band solve starts with: the dry partners in
    ``[f_min, 1.1 f_max]`` plus 2 (wet modes lie below their dry partners)."""
    dry = np.asarray(dry_freq_hz, dtype=float)
    return int(np.count_nonzero((dry >= f_min) & (dry <= 1.1 * f_max))) + 2


def lowest_frequency_hz(stiffness, mass) -> float:
    """Re f [Hz] of the lowest eigenvalue of the Hermitian pencil (K, M) (0 for an unstable
    one, lam < 0): a dense solve up to :data:`DENSE_LOWEST` unknowns, else shift-invert
    about sigma = -1 rad^2/s^2 (K - sigma M is definite for a stable state)."""
    n = stiffness.shape[0]
    if n == 0:
        return float("inf")
    if n <= DENSE_LOWEST:
        dense = [matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix)
                 for matrix in (stiffness, mass)]
        lam = float(sla.eigh(*dense, eigvals_only=True, subset_by_index=[0, 0])[0])
    else:
        lam = float(np.min(spla.eigsh(sp.csc_matrix(stiffness), k=1, M=sp.csc_matrix(mass),
                                      sigma=-1.0, which="LM", return_eigenvectors=False)))
    return float(np.sqrt(max(lam, 0.0)) / (2 * np.pi))


class OrderStop:
    """Stop rule of an order loop m = 0, 1, 2, ... (module doc).

    ``top_hz``: the highest frequency a mode of the loop may have and still matter
    (f_max for dry modes, :data:`DRY_PARTNER_FACTOR` f_max for the dry partners of a
    coupled solve).  :meth:`above` says whether an order can be skipped, :meth:`done`
    whether no higher order can hold a mode below ``top_hz``.
    """

    def __init__(self, top_hz: float):
        self.top_hz = float(top_hz)
        self.lowest_hz: list[float] = []

    def record(self, lowest_hz: float) -> None:
        """The lowest mode of the next order [Hz]."""
        self.lowest_hz.append(float(lowest_hz))

    def above(self) -> bool:
        """Whether the last order's lowest mode lies above the top."""
        return self.lowest_hz[-1] > self.top_hz

    def done(self) -> bool:
        """Whether the loop may stop after the last recorded order."""
        if len(self.lowest_hz) < 2 or not self.above():
            return False
        rising = self.lowest_hz[-1] > self.lowest_hz[-2]
        if not rising:
            log.debug("order %d: lowest mode %.6g Hz not above order %d's %.6g Hz; going on",
                      len(self.lowest_hz) - 1, self.lowest_hz[-1], len(self.lowest_hz) - 2,
                      self.lowest_hz[-2])
        return rising
