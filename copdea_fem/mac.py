"""The modal assurance criterion (MAC) of shape vectors, and of subspaces.

One implementation for the package: the sweeps' mode tracking
(:mod:`copdea_fem.sweeps.tracking`) compares the modes of neighbouring sweep points with it,
the vibrometer's correlation (:mod:`copdea_fem.vibrometer.pairing`) measured shapes with
the FE's.  Pure functions on arrays.

A degenerate pair (the ``cos m theta`` / ``sin m theta`` modes of a circular membrane) is
one two-dimensional eigenspace: a solver, or a measurement, returns an arbitrary basis of
it, so the MAC of one member means nothing while the subspace MAC (principal angles,
Bjorck & Golub 1973) does.
"""

from __future__ import annotations

import numpy as np


class ShapeComparisonError(ValueError):
    """Shapes that cannot be compared (vectors of different lengths)."""




def _as_columns(vectors) -> np.ndarray:
    array = np.asarray(vectors)
    return array[:, None] if array.ndim == 1 else array


def _weighted(vectors: np.ndarray, mass) -> np.ndarray:
    return vectors if mass is None else np.asarray(mass @ vectors)


def mac_matrix(first, second, mass=None) -> np.ndarray:
    """Modal assurance criterion between two sets of shape vectors.

    ``MAC_ij = |a_i^H M b_j|^2 / ((a_i^H M a_i) (b_j^H M b_j))``, in [0, 1];
    1 = the same shape up to scale.

    Parameters
    ----------
    first : array_like, shape (n,) or (n, ka)
    second : array_like, shape (n,) or (n, kb)
    mass : sparse matrix or array, shape (n, n), optional
        Hermitian positive (semi-)definite inner-product matrix (the mass
        matrix [kg]); ``None`` = the plain inner product.

    Returns
    -------
    numpy.ndarray, shape (ka, kb)
    """
    a, b = _as_columns(first), _as_columns(second)
    if a.shape[0] != b.shape[0]:
        raise ShapeComparisonError(f"mac_matrix: vectors of length {a.shape[0]} and "
                                 f"{b.shape[0]} cannot be compared")
    weighted_b = _weighted(b, mass)
    cross = a.conj().T @ weighted_b
    norm_a = np.real(np.einsum("ij,ij->j", a.conj(), _weighted(a, mass)))
    norm_b = np.real(np.einsum("ij,ij->j", b.conj(), weighted_b))
    with np.errstate(divide="ignore", invalid="ignore"):
        mac = np.abs(cross) ** 2 / np.outer(norm_a, norm_b)
    return np.clip(np.nan_to_num(mac, nan=0.0, posinf=0.0), 0.0, 1.0)


def _inverse_sqrt(gram: np.ndarray) -> np.ndarray:
    """``G^{-1/2}`` of a Hermitian positive semi-definite Gram matrix (null part dropped)."""
    gram = 0.5 * (gram + gram.conj().T)
    values, vectors = np.linalg.eigh(gram)
    # directions with Gram eigenvalue below 1e-12 of the largest are numerically
    # dependent (a repeated vector): they add nothing to the span
    keep = values > 1e-12 * max(values[-1], 1e-300)
    return vectors[:, keep] / np.sqrt(values[keep])


def subspace_mac_from_products(cross, gram_first, gram_second) -> float:
    """:func:`subspace_mac` from the products of two bases: ``cross = A^H M B``, the Gram
    matrices ``A^H M A`` and ``B^H M B`` (a caller comparing many subspaces of two sets forms
    the products once).  Mean squared cosine of the principal angles, over the smaller
    dimension."""
    left, right = _inverse_sqrt(gram_first), _inverse_sqrt(gram_second)
    if left.shape[1] == 0 or right.shape[1] == 0:
        return 0.0
    cosines = np.linalg.svd(left.conj().T @ cross @ right, compute_uv=False)
    dimension = min(left.shape[1], right.shape[1])
    return float(np.clip(np.sum(cosines[:dimension] ** 2) / dimension, 0.0, 1.0))


def subspace_mac(first, second, mass=None) -> float:
    """MAC of two subspaces: mean squared cosine of their principal angles.

    Invariant to the basis chosen inside each subspace (the rotation of a
    degenerate pair), 1 when the smaller subspace lies in the larger one, 0
    when they are orthogonal.  For two single vectors it is their MAC.

    Parameters
    ----------
    first : array_like, shape (n, ka)
        Basis of the first subspace (columns).
    second : array_like, shape (n, kb)
    mass : sparse matrix or array, shape (n, n), optional
        Inner-product matrix; ``None`` = plain.

    Returns
    -------
    float
        In [0, 1]; the sum of squared cosines divided by ``min(ka, kb)``.
    """
    a, b = _as_columns(first), _as_columns(second)
    if a.shape[0] != b.shape[0]:
        raise ShapeComparisonError(f"subspace_mac: vectors of length {a.shape[0]} and "
                                 f"{b.shape[0]} cannot be compared")
    weighted_b = _weighted(b, mass)
    return subspace_mac_from_products(a.conj().T @ weighted_b, a.conj().T @ _weighted(a, mass),
                                   b.conj().T @ weighted_b)


__all__ = ["ShapeComparisonError", "mac_matrix", "subspace_mac", "subspace_mac_from_products"]
