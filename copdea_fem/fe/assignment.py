"""The one-to-one assignment of largest total weight, without importing SciPy's optimize.

:func:`scipy.optimize.linear_sum_assignment` is the reference, but importing
:mod:`scipy.optimize` pulls in its whole package (linprog, the FFT, special functions,
spatial transforms: ~0.4 s of CPU in every fresh process, about a tenth of the baffled G1
command, issue 25).  The axisymmetric engine's use (:func:`copdea_fem.fe.axisymmetric.engine.
number_from_dry`) matches the out-of-plane modes of one order with their dry partners: a
few rows and columns.  For such matrices every injective map of the shorter side into the
longer one is enumerated (``P(n, k) = n! / (n - k)!`` of them, at most
:data:`MAX_ENUMERATED`) and the largest total kept; larger matrices go to SciPy.

Both give the maximum of the same objective, so they agree whenever the maximum is unique
(a tie between two assignments whose totals are equal to the last bit -- MAC values that
coincide exactly -- is the only case where they may pick different maxima).  The rows are
returned sorted, as SciPy returns them.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

#: largest number of candidate assignments enumerated before falling back to SciPy
#: (8 x 8: 40320 permutations, ~30 ms; the engine's matrices are at most ~6 x 6)
MAX_ENUMERATED = 40320


def max_weight_assignment(weights) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the one-to-one assignment of largest total ``weights``.

    Parameters
    ----------
    weights : array_like, shape (n_rows, n_columns)
        Finite weights (dimensionless, e.g. MAC values).

    Returns
    -------
    rows, columns : numpy.ndarray of int
        ``min(n_rows, n_columns)`` pairs, rows in increasing order: the same as
        ``scipy.optimize.linear_sum_assignment(weights, maximize=True)`` when the
        maximum is unique.
    """
    weights = np.asarray(weights, dtype=float)
    if weights.ndim != 2:
        raise ValueError(f"weights must be a 2-D matrix, got shape {weights.shape}")
    if not np.all(np.isfinite(weights)):
        raise ValueError("weights must be finite")
    n_rows, n_columns = weights.shape
    transposed = n_rows > n_columns
    matrix = weights.T if transposed else weights         # rows <= columns
    k, n = matrix.shape
    if k == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    if math.perm(n, k) > MAX_ENUMERATED:
        from scipy.optimize import linear_sum_assignment
        return linear_sum_assignment(weights, maximize=True)
    candidates = np.array(list(itertools.permutations(range(n), k)), dtype=int)
    totals = matrix[np.arange(k)[None, :], candidates].sum(axis=1)
    best = candidates[int(np.argmax(totals))]
    rows, columns = np.arange(k), best
    if transposed:
        rows, columns = columns, rows
        order = np.argsort(rows)
        rows, columns = rows[order], columns[order]
    return rows, columns
