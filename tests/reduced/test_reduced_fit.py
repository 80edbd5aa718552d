"""Material fit of eq. (20) to force-displacement data (Sect. 5.1, Fig. 4b)."""

from dataclasses import replace

import numpy as np
import pytest
from reduced_helpers import ring_model

from copdea_fem.reduced.fit import fit_material
from copdea_fem.reduced.rings import ReducedModelError

TRUE = np.array([228.5e3, 8.4e3, -28.6e3])   # Pa, Sect. 5.1


def synthetic_data(prestretches, voltages=(0.0, 2000.0, 3000.0), points=40, noise=0.01, seed=7):
    """F(z) of the ring model with the paper's coefficients plus Gaussian noise of
    ``noise`` times each reading (a 1 %-of-reading force sensor)."""
    model = ring_model(rings=6)
    z = np.linspace(0.0005, 0.020, points)
    rng = np.random.default_rng(seed)
    rows = {"z": [], "force": [], "voltage": [], "prestretch": [], "std": []}
    for stretch in prestretches:
        sample = replace(model, membrane=replace(model.membrane, prestretch=stretch))
        for voltage in voltages:
            clean = sample.force_displacement(z, voltage)
            rows["z"].append(z)
            rows["force"].append(clean * (1 + noise * rng.standard_normal(z.size)))
            rows["voltage"].append(np.full(z.size, voltage))
            rows["prestretch"].append(np.full(z.size, stretch))
            rows["std"].append(noise * np.abs(clean))
    start = model.with_membrane(replace(model.membrane, c10=150e3, c20=0.0, c01=0.0))
    return start, {key: np.concatenate(value) for key, value in rows.items()}


def test_fit_recovers_the_paper_coefficients_from_noisy_data():
    """1 % noise, two samples (lambda_p 1.2 and 1.6) at 0, 2, 3 kV, 40 points each.

    This design's standard errors are <= 5 % / 3 for all three coefficients
    (checked below), so recovery within 5 % is a >= 3-sigma statement.
    """
    start, data = synthetic_data((1.2, 1.6))
    fit = fit_material(start, data["z"], data["force"], data["voltage"],
                       prestretch=data["prestretch"], force_std=data["std"])
    assert np.all(fit.standard_error / np.abs(TRUE) <= 0.05 / 3)
    assert np.all(np.abs(fit.values / TRUE - 1) <= 0.05)
    assert np.all(np.abs(fit.values - TRUE) <= 3 * fit.standard_error)


def test_one_prestretch_cannot_separate_c10_from_c01_and_the_fit_says_so():
    """sigma_1 = 2 (l1^2 - l3^2)(dPsi/dI1 + l2^2 c01) with l2 ~ lambda_p: only c10 + lp^2 c01
    is pinned.  The uncertainty estimate must show it, and still cover the truth."""
    start, data = synthetic_data((1.2,), voltages=(0.0, 3000.0), points=20)
    fit = fit_material(start, data["z"], data["force"], data["voltage"], force_std=data["std"])
    assert fit.correlation[0, 2] < -0.99
    assert fit.standard_error[2] > 0.5 * abs(TRUE[2])
    assert np.all(np.abs(fit.values - TRUE) <= 3 * fit.standard_error)
    combination = fit.values[0] + 1.2 ** 2 * fit.values[2]
    assert combination == pytest.approx(TRUE[0] + 1.2 ** 2 * TRUE[2], rel=0.05)


def test_fit_refuses_too_little_or_bad_data():
    model = ring_model()
    with pytest.raises(ReducedModelError, match="3 force-displacement points"):
        fit_material(model, [0.001, 0.002, 0.003], [0.1, 0.2, 0.3], [0.0] * 3)
    with pytest.raises(ReducedModelError, match="NaN"):
        fit_material(model, [0.001, 0.002, 0.003, np.nan], [0.1] * 4, [0.0] * 4)
