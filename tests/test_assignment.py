"""copdea_fem.fe.assignment: the largest-total one-to-one assignment equals SciPy's."""

import math

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment

from copdea_fem.fe.assignment import MAX_ENUMERATED, max_weight_assignment


@pytest.mark.parametrize("shape", [(1, 1), (1, 4), (4, 1), (3, 3), (3, 5), (5, 3), (6, 6),
                                   (2, 7), (8, 8)])
def test_equals_scipy_maximum(shape):
    rng = np.random.default_rng(sum(shape))
    for _ in range(20):
        weights = rng.uniform(0.0, 1.0, shape)     # MAC-like, ties have probability 0
        rows, columns = max_weight_assignment(weights)
        expected_rows, expected_columns = linear_sum_assignment(weights, maximize=True)
        np.testing.assert_array_equal(rows, expected_rows)
        np.testing.assert_array_equal(columns, expected_columns)


def test_large_matrix_goes_to_scipy():
    rng = np.random.default_rng(3)
    weights = rng.uniform(0.0, 1.0, (9, 9))        # 9! > MAX_ENUMERATED
    assert math.factorial(9) > MAX_ENUMERATED
    rows, columns = max_weight_assignment(weights)
    np.testing.assert_array_equal(columns, linear_sum_assignment(-weights)[1])


def test_empty_and_bad_input():
    rows, columns = max_weight_assignment(np.zeros((0, 3)))
    assert rows.size == columns.size == 0
    with pytest.raises(ValueError, match="2-D"):
        max_weight_assignment(np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        max_weight_assignment([[1.0, np.nan]])


def test_solve_path_does_not_import_scipy_optimize():
    """The axisymmetric engine (the baffled G1 command) numbers its modes without
    scipy.optimize (~0.4 s of CPU per process, issue 25)."""
    import subprocess
    import sys
    code = ("import sys, copdea_fem.fe.axisymmetric.engine, copdea_fem.fe.pipeline, copdea_fem.api; "
            "print('scipy.optimize' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "False"
