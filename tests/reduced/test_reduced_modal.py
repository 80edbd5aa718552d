"""Dry modes of the ring model (eqs 15-16): Bessel limit, labels, paper trends."""

import math

import numpy as np
import pytest
from reduced_helpers import G1_DISC, G1_INNER, G2_DISC, G2_INNER, OUTER, paper_study, ring_model
from scipy.optimize import brentq
from scipy.special import j0, y0

from copdea_fem.reduced.modal import modal_decomposition, mode_profile
from copdea_fem.reduced.model import dry_frequencies


def annulus_roots(inner, outer, count):
    """First roots k of J0(k a) Y0(k b) - J0(k b) Y0(k a) = 0 [1/m] (fixed-fixed annulus, m = 0).

    Consecutive roots are about pi / (b - a) apart; a grid 200 times finer
    brackets each exactly once.
    """
    f = lambda k: j0(k * inner) * y0(k * outer) - j0(k * outer) * y0(k * inner)  # noqa: E731
    grid = np.linspace(1e-6, (count + 1) * math.pi / (outer - inner), 200 * (count + 1))
    values = f(grid)
    brackets = np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))[:count]
    return np.array([brentq(f, grid[i], grid[i + 1], xtol=1e-14) for i in brackets])


def flat_frequencies(rings, voltage, labels=("(0,1)", "(0,2)", "(0,3)")):
    model = ring_model(rings=rings, disc_free=False)
    basis = modal_decomposition(model, model.operating_point(0.0, voltage))
    return np.array([basis[label].frequency_hz for label in labels]), basis


@pytest.mark.parametrize("voltage", [0.0, 2000.0])
def test_flat_annulus_frequencies_converge_to_bessel_roots(voltage):
    """Disc held, z = 0: (0,n) -> k_n c / 2 pi, c = sqrt(T / (rho0 h0 / lp^2)).

    Galerkin (exact stiffness, consistent mass) on nested meshes: upper bounds
    that fall monotonically as n doubles; < 1 % at n = 48 (DESIGN rung 2).
    """
    membrane = ring_model().membrane
    speed = math.sqrt(membrane.equibiaxial_tension(voltage) / membrane.areal_density)
    exact = annulus_roots(G1_INNER, OUTER, 3) * speed / (2 * math.pi)
    errors = np.array([flat_frequencies(n, voltage)[0] / exact - 1 for n in (6, 12, 24, 48)])
    assert np.all(errors > 0)
    assert np.all(np.diff(errors, axis=0) < 0)
    assert np.all(errors[-1] < 0.01)
    # second order: error ratio between halvings -> 4 for the well-resolved (0,1)
    assert 3.8 < errors[-2, 0] / errors[-1, 0] < 4.2


def test_flat_axial_and_radial_motions_decouple():
    _, basis = flat_frequencies(12, 2000.0)
    for mode in basis.modes:
        if mode.kind == "out-of-plane":
            assert np.max(np.abs(mode.radial)) < 1e-10 * np.max(np.abs(mode.axial))
        else:
            assert np.max(np.abs(mode.axial)) < 1e-10 * np.max(np.abs(mode.radial))


def test_modes_are_mass_normalised_and_deterministic():
    model = ring_model(rings=8)
    lin = model.operating_point(0.016, 2000.0)
    basis = modal_decomposition(model, lin)
    shapes = np.stack([mode.shape for mode in basis.modes], axis=1)
    omega2 = np.array([mode.angular_frequency ** 2 for mode in basis.modes])
    assert np.allclose(shapes.T @ lin.mass_matrix @ shapes, np.eye(len(omega2)), atol=1e-10)
    assert np.allclose(shapes.T @ lin.stiffness_matrix @ shapes, np.diag(omega2),
                       atol=1e-10 * omega2.max())
    assert np.all(np.diff(omega2) > 0)
    again = modal_decomposition(model, lin)
    assert all(np.array_equal(a.shape, b.shape) for a, b in zip(basis.modes, again.modes))


def test_labels_at_the_paper_operating_point():
    """G1, z = 16 mm, 2 kV: P1 lowest and disc-dominated; (0,n) has n - 1 nodal circles."""
    model = ring_model(rings=12)
    basis = modal_decomposition(model, model.operating_point(0.016, 2000.0))
    assert basis.modes[0].label == "P1" and basis.modes[0].disc_fraction > 0.9
    for n in (1, 2, 3):
        mode = basis[f"(0,{n})"]
        assert mode.nodal_circles == n - 1
        # the disc only answers the membrane's reaction, whose inertia is at most the
        # membrane's mass: its energy share stays below m_membrane / M_d (~0.1)
        assert mode.disc_fraction < model.membrane_mass / G1_DISC
    assert basis["(0,1)"].frequency_hz < basis["(0,2)"].frequency_hz
    profile = mode_profile(model, basis.linearisation, basis["(0,2)"])
    assert max(np.max(np.abs(profile["radial"])), np.max(np.abs(profile["axial"]))) == 1.0


def test_held_disc_has_no_pumping_mode():
    model = ring_model(rings=6, disc_free=False)
    basis = modal_decomposition(model, model.operating_point(0.016, 2000.0))
    assert "P1" not in basis.labels and len(basis.modes) == 2 * 6 - 2


def test_frequencies_fall_with_voltage_and_rise_with_z():
    """Sects 4.3, 5.2 (Fig. 11a-b), dry ring model, G1."""
    by_voltage = [dry_frequencies(paper_study(voltage=v)) for v in (1000.0, 2000.0, 3000.0)]
    by_z = [dry_frequencies(paper_study(z=z)) for z in (0.011, 0.016, 0.018)]
    for label in ("P1", "(0,1)", "(0,2)"):
        assert by_voltage[0][label] > by_voltage[1][label] > by_voltage[2][label]
        assert by_z[0][label] < by_z[1][label] < by_z[2][label]


def test_structural_frequencies_of_g1_are_above_g2():
    """Sect. 4.3, Fig. 8b: G1 above G2 at z = 16 mm, 2 kV."""
    g1 = dry_frequencies(paper_study())
    g2 = dry_frequencies(paper_study(inner=G2_INNER, disc=G2_DISC))
    assert g1["(0,1)"] > g2["(0,1)"] and g1["(0,2)"] > g2["(0,2)"]
