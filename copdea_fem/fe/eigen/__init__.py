"""Shift-invert band eigensolver for the pencil ``A x = lam B x``.

The eigenvalue is ``lam = omega**2`` (rad^2/s^2, ``omega`` the angular
frequency in rad/s) and the frequency is ``f = sqrt(lam) / (2 pi)`` (Hz), the
square root with ``Re f >= 0``.  Two kinds of pencil are solved:

* Hermitian (the dry membrane): ``A``, ``B`` real symmetric or complex
  Hermitian, ``B`` positive semi-definite.  ``A`` may be indefinite (an
  unstable prestressed state): negative ``lam`` come out with ``Re f = 0`` and
  ``Im f = sqrt(-lam) / (2 pi) > 0``.
* General (membrane + air with a PML, the unsymmetric u-p form): ``A``, ``B``
  complex and non-Hermitian; ``lam`` complex, ``Im f`` measures the
  radiation damping.

The package follows the solve's jobs:

:mod:`~copdea_fem.fe.eigen.factorization`
    back-ends of ``A - sigma B`` (:class:`Factorization`: NGSolve UMFPACK / MKL
    PARDISO or SciPy SuperLU in METIS order; :class:`NativeShiftedInverse`:
    the coupled pencil natively complex in NGSolve), block solves;
:mod:`~copdea_fem.fe.eigen.pairs`
    the pairs found so far (de-duplication, clusters, Rayleigh-Ritz);
:mod:`~copdea_fem.fe.eigen.krylov`
    the deflated shift-invert Krylov run (block Krylov-Schur, or ARPACK);
:mod:`~copdea_fem.fe.eigen.region` and :mod:`~copdea_fem.fe.eigen.planner`
    the band as a lam-plane region, its cover by discs and their certification;
:mod:`~copdea_fem.fe.eigen.band`
    :func:`solve_band` and its results (:class:`BandResult`, :class:`SectorBandResults`);
:mod:`~copdea_fem.fe.eigen.frequencies` and :mod:`~copdea_fem.fe.eigen.errors`
    eigenvalue/frequency conversions, residuals; the exceptions.

Everything works on SciPy sparse matrices; NGSolve is only used as a
factorisation engine.
"""

from copdea_fem.fe.eigen.band import BandResult, SectorBandResults, solve_band
from copdea_fem.fe.eigen.errors import (
    BackendUnavailableError,
    EigenInputError,
    EigenResidualError,
    EigenSolverError,
    TooManyModesError,
)
from copdea_fem.fe.eigen.factorization import (
    BACKENDS,
    NESTED_DISSECTION_MIN,
    SUPERLU_PIVOT_THRESHOLD,
    Factorization,
    NativeShiftedInverse,
    available_backends,
    backend_available,
    factor_memory_estimate,
    fill_reducing_order,
)
from copdea_fem.fe.eigen.frequencies import (
    TWO_PI,
    eigenvalue_from_frequency,
    frequency_from_eigenvalue,
    is_hermitian,
    matrix_norm_estimate,
    relative_residuals,
)
from copdea_fem.fe.eigen.krylov import KRYLOV_METHODS

__all__ = [
    "BACKENDS", "KRYLOV_METHODS", "NESTED_DISSECTION_MIN", "SUPERLU_PIVOT_THRESHOLD", "TWO_PI",
    "BackendUnavailableError", "BandResult", "EigenInputError", "EigenResidualError",
    "EigenSolverError", "Factorization", "NativeShiftedInverse", "SectorBandResults",
    "TooManyModesError", "available_backends", "backend_available",
    "eigenvalue_from_frequency", "factor_memory_estimate", "fill_reducing_order", "frequency_from_eigenvalue",
    "is_hermitian", "matrix_norm_estimate", "relative_residuals", "solve_band",
]
