"""Eigenvalue <-> frequency, residuals and symmetry tests of a pencil ``A x = lam B x``.

``lam = omega**2`` (rad^2/s^2, ``omega`` the angular frequency in rad/s) and
``f = sqrt(lam) / (2 pi)`` (Hz), the square root with ``Re f >= 0``.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

TWO_PI = 2.0 * math.pi


def frequency_from_eigenvalue(eigenvalue):
    """Complex frequency of ``lam = omega**2``.

    Parameters
    ----------
    eigenvalue : complex or array_like
        ``lam`` (rad^2/s^2).

    Returns
    -------
    complex or numpy.ndarray
        ``f = sqrt(lam) / (2 pi)`` (Hz), principal root (``Re f >= 0``).  A
        negative real ``lam`` gives ``f = +i sqrt(-lam) / (2 pi)``.
    """
    lam = np.asarray(eigenvalue, dtype=complex)
    # ``imag + 0.0`` turns a signed zero (-0.0) into +0.0, so a negative real
    # lam lands on the +i side of the branch cut.
    lam = lam.real + 1j * (lam.imag + 0.0)
    return np.sqrt(lam) / TWO_PI


def eigenvalue_from_frequency(frequency_hz):
    """``lam = (2 pi f)**2`` (rad^2/s^2) of a (complex) frequency ``f`` (Hz)."""
    return (TWO_PI * np.asarray(frequency_hz)) ** 2


def matrix_norm_estimate(matrix) -> float:
    """Cheap upper bound of the spectral norm: ``sqrt(||M||_1 ||M||_inf)``.

    Equals the 1-norm for a symmetric/Hermitian matrix.  Used to scale the
    eigenpair residuals (see :func:`relative_residuals`).
    """
    magnitude = abs(sp.csr_matrix(matrix))
    one_norm = float(magnitude.sum(axis=0).max()) if magnitude.nnz else 0.0
    inf_norm = float(magnitude.sum(axis=1).max()) if magnitude.nnz else 0.0
    return math.sqrt(one_norm * inf_norm)


def relative_residuals(A, B, eigenvalues, vectors) -> np.ndarray:
    """Relative residual of each eigenpair, ``||A x - lam B x||_2 / (||A|| ||x||_2)``.

    ``||A||`` is :func:`matrix_norm_estimate` (``sqrt(||A||_1 ||A||_inf)``, an
    upper bound of the spectral norm, the 1-norm for symmetric ``A``).

    Parameters
    ----------
    A, B : scipy.sparse matrix, shape (n, n)
    eigenvalues : array_like, shape (k,)
        ``lam`` (rad^2/s^2).
    vectors : numpy.ndarray, shape (n, k)

    Returns
    -------
    numpy.ndarray, shape (k,)
        Dimensionless residuals.
    """
    vectors = np.asarray(vectors)
    if vectors.ndim == 1:
        vectors = vectors[:, None]
    eigenvalues = np.atleast_1d(np.asarray(eigenvalues))
    if vectors.shape[1] == 0:
        return np.zeros(0)
    scale = matrix_norm_estimate(A)
    if scale == 0.0:  # A = 0: fall back to the B term so the ratio stays meaningful
        scale = matrix_norm_estimate(B) * float(np.max(np.abs(eigenvalues)) or 1.0)
    lam = eigenvalues
    if not np.iscomplexobj(vectors) and np.all(np.imag(eigenvalues) == 0):
        lam = np.real(eigenvalues)  # keep a real pencil's residual in real arithmetic
    residual = A @ vectors - (B @ vectors) * lam[None, :]
    return np.linalg.norm(residual, axis=0) / (scale * np.linalg.norm(vectors, axis=0))


def is_hermitian(matrix, relative_tolerance: float = 1e-12) -> bool:
    """Whether ``max|M - M^H| <= relative_tolerance * max|M|``.

    The default 1e-12 is far above the round-off of an assembled symmetric
    FE matrix or of ``P^T K P`` reductions (a few ulp, ~1e-15 relative) and
    far below any genuine asymmetry (the u-p coupling blocks are O(1)).
    """
    matrix = sp.csr_matrix(matrix)
    largest = float(abs(matrix).max()) if matrix.nnz else 0.0
    difference = (matrix - matrix.conj().T).tocsr()
    if difference.nnz == 0:
        return True
    return float(abs(difference).max()) <= relative_tolerance * largest


def format_hz(value) -> str:
    """``f = sqrt(lam)/(2 pi)`` of a lam-plane point, as text (Hz)."""
    f = complex(frequency_from_eigenvalue(value))
    if abs(f.imag) <= 1e-9 * abs(f):
        return f"{f.real:.6g} Hz"
    return f"{f.real:.6g}{f.imag:+.4g}i Hz"


def format_radius(sigma, radius) -> str:
    """A disc radius about the real shift ``sigma`` (rad^2/s^2) and its real-axis extent in Hz."""
    if not np.isfinite(radius):
        return "inf"
    low = complex(frequency_from_eigenvalue(sigma - radius))
    high = complex(frequency_from_eigenvalue(sigma + radius))
    low_text = f"{low.real:.4g}" if abs(low.imag) <= abs(low.real) else f"{low.imag:.4g}i"
    return f"{radius:.4g} rad^2/s^2 (real axis {low_text}..{high.real:.4g} Hz)"
