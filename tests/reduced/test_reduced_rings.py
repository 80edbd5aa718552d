"""Ring model (Sect. 3.2.1): energies, derivatives, statics, eq. (14)."""

import math

import numpy as np
import pytest
from reduced_helpers import G1_DISC, G1_INNER, G2_DISC, G2_INNER, OUTER, paper_study, ring_model

from copdea_fem.reduced.rings import ReducedModelError, RingModel
from copdea_fem.study import StudyError

PAPER_POINTS = [(inner, disc, z, voltage)
                for inner, disc in ((G1_INNER, G1_DISC), (G2_INNER, G2_DISC))
                for z in (0.011, 0.016, 0.018) for voltage in (1000.0, 2000.0, 3000.0)]


def perturbed_state(model, z=0.012, voltage=2500.0, size=1e-4, seed=0):
    """An off-equilibrium state near the cone (so the check sees every term)."""
    eq = model.equilibrium(z, voltage)
    rng = np.random.default_rng(seed)
    return (eq.radii + rng.normal(0, size, eq.radii.size),
            eq.heights + rng.normal(0, size, eq.heights.size))


def test_gradient_and_hessian_match_finite_differences_of_the_energy():
    model = ring_model(rings=5)
    radii, heights = perturbed_state(model)
    N, voltage = model.node_count, 2500.0
    state = np.concatenate([radii, heights])
    grad, hess = model.potential_derivatives(radii, heights, voltage)
    step = 1e-7  # m; central differences: truncation ~ step^2 |Pi'''| ~ 1e-10 relative
    eye = np.eye(2 * N)
    energy = lambda x: model.potential(x[:N], x[N:], voltage)  # noqa: E731
    gradient = lambda x: model.potential_derivatives(x[:N], x[N:], voltage, False)[0]  # noqa: E731
    grad_fd = np.array([(energy(state + step * e) - energy(state - step * e)) / (2 * step)
                        for e in eye])
    hess_fd = np.array([(gradient(state + step * e) - gradient(state - step * e)) / (2 * step)
                        for e in eye])
    # round-off of the energy differences: 1e-16 |Pi| / step ~ 1e-9 of |grad|
    assert np.max(np.abs(grad - grad_fd)) <= 1e-7 * np.max(np.abs(grad))
    assert np.max(np.abs(hess - hess_fd)) <= 1e-7 * np.max(np.abs(hess))
    assert np.allclose(hess, hess.T, rtol=0, atol=1e-12 * np.max(np.abs(hess)))


def test_capacitance_co_energy_equals_eq7_over_the_rings():
    """-V^2/2 C (eq. 11, corrected) = sum Omega_k * (-eps/2 (V/h0)^2 det_c) (eq. 7)."""
    model = ring_model(rings=7)
    radii, heights = perturbed_state(model, size=3e-4)
    voltage = 2000.0
    x, y = model.stretches_squared(radii, heights)
    from_eq7 = np.sum(model.ring_volumes * model.membrane.electrostatic_coenergy(x * y, voltage))
    assert -0.5 * voltage ** 2 * model.capacitance(radii, heights) == pytest.approx(from_eq7,
                                                                                   rel=1e-13)
    # the frustum's lateral area is Omega lambda_1 lambda_2 / h0
    area = math.pi * (radii[:-1] + radii[1:]) * np.hypot(np.diff(radii), np.diff(heights))
    assert np.allclose(area, model.ring_volumes * np.sqrt(x * y) / model.membrane.thickness,
                       rtol=1e-13)


def test_mass_matrix_carries_the_membrane_and_disc_mass():
    model = ring_model(rings=9)
    nodes = model.node_mass_matrix()
    # a uniform velocity field moves all the membrane: 1^T M 1 = rho0 h0/lp^2 pi (ro^2 - ri^2)
    assert nodes.sum() == pytest.approx(model.membrane_mass, rel=1e-13)
    # a velocity linear in R: 2 pi mu int R^2 ... exact for linear interpolation
    R = model.reference_radii
    exact = 2 * math.pi * model.membrane.areal_density * (R[0] ** 4 - R[-1] ** 4) / 4
    assert R @ nodes @ R == pytest.approx(exact, rel=1e-13)
    full = model.full_mass_matrix()
    assert full[model.disc_dof, model.disc_dof] == pytest.approx(nodes[-1, -1] + G1_DISC)


@pytest.mark.parametrize("voltage", [0.0, 3000.0])
def test_flat_membrane_is_an_equilibrium_with_no_disc_force(voltage):
    model = ring_model(rings=8)
    grad, _ = model.potential_derivatives(*model.flat_state(), voltage, hessian=False)
    assert np.max(np.abs(grad[model.interior_dofs])) < 1e-12 * model._force_scale()
    assert model.equilibrium(0.0, voltage).disc_force == pytest.approx(0, abs=1e-12)


def test_axial_stiffness_at_small_z_converges_to_the_annulus_closed_form():
    """k_DE -> 2 pi T / ln(ro/ri) with T = Membrane.equibiaxial_tension(V) (DESIGN rung 3).

    The flat axial problem (r w')' = 0 is solved by Galerkin linear elements with
    the exact stiffness integral, so k_DE is an upper bound converging as h^2:
    error ratios between halvings -> 4.
    """
    voltage = 2000.0
    errors = []
    for rings in (6, 12, 24, 48):
        model = ring_model(rings=rings)
        tension = model.membrane.equibiaxial_tension(voltage)
        exact = 2 * math.pi * tension / math.log(OUTER / G1_INNER)
        # z = 1 um: the force is linear in z to (z / width)^2 ~ 3e-9
        k = model.linearise(model.equilibrium(1e-6, voltage)).axial_stiffness
        errors.append(k / exact - 1)
    assert all(e > 0 for e in errors)
    orders = [math.log2(errors[i] / errors[i + 1]) for i in range(3)]
    assert all(1.9 < p < 2.1 for p in orders), orders
    assert errors[-1] < 1e-4


def test_static_stiffness_matches_finite_difference_of_the_force():
    """k_DE = dF/dz from eq. (14) against central differences of the static F(z)."""
    model = ring_model(rings=6)
    z, voltage, dz = 0.016, 2000.0, 1e-5
    k = model.linearise(model.equilibrium(z, voltage)).axial_stiffness
    f_plus, f_minus = model.force_displacement([z + dz, z - dz], voltage)
    # truncation (dz/z)^2 ~ 4e-7; equilibrium tolerance 1e-10 * 5 N / 2 dz ~ 2.5e-5 N/m
    assert k == pytest.approx((f_plus - f_minus) / (2 * dz), rel=1e-5)


def test_stiffness_matrix_matches_finite_difference_of_the_generalised_force():
    """K_s (with the spring and V_b^2/2 d2C) against differences of the static force vector."""
    model = ring_model(rings=6)
    lin = model.operating_point(0.016, 2000.0)
    eq, free, N = lin.equilibrium, model.free_dofs, model.node_count

    def force(q):
        full = np.concatenate([eq.radii, eq.heights])
        full[free] = q
        g, _ = model.potential_derivatives(full[:N], full[N:], eq.voltage, hessian=False)
        g[model.disc_dof] -= model.spring_stiffness * (lin.spring_preload - full[model.disc_dof])
        return g[free]

    q0 = np.concatenate([eq.radii, eq.heights])[free]
    assert np.max(np.abs(force(q0))) < 1e-9 * model._force_scale()   # the preload balances z
    step = 1e-7
    columns = [(force(q0 + step * e) - force(q0 - step * e)) / (2 * step)
               for e in np.eye(q0.size)]
    assert np.allclose(np.array(columns).T, lin.stiffness_matrix, rtol=0,
                       atol=1e-6 * np.max(np.abs(lin.stiffness_matrix)))


@pytest.mark.parametrize("inner, disc, z, voltage", PAPER_POINTS)
def test_mass_and_stiffness_are_symmetric_positive_definite(inner, disc, z, voltage):
    model = ring_model(rings=6, inner=inner, disc=disc)
    lin = model.operating_point(z, voltage)
    for matrix in (lin.mass_matrix, lin.stiffness_matrix):
        assert np.array_equal(matrix, matrix.T)
        assert np.linalg.eigvalsh(matrix)[0] > 0
    assert lin.mass_matrix.shape == (2 * 6 - 1,) * 2


def test_forcing_is_vb_times_dc_dq_not_twice():
    """Eq. (14) corrected: a small voltage step moves q by K^-1 V_b dC/dq dV.

    Disc held, so the interior coordinates answer the step statically.  The
    second-order remainder is ~ dV / (2 V_b) = 2.5e-3 relative; the paper's
    2 V_b would be off by 100 %.
    """
    model = ring_model(rings=6, disc_free=False)
    z, voltage, dv = 0.016, 2000.0, 10.0
    lin = model.linearise(model.equilibrium(z, voltage))
    before = model.equilibrium(z, voltage)
    after = model.equilibrium(z, voltage + dv, start=(before.radii, before.heights))
    free = model.free_dofs
    moved = (np.concatenate([after.radii, after.heights])
             - np.concatenate([before.radii, before.heights]))[free]
    predicted = np.linalg.solve(lin.stiffness_matrix, lin.forcing_per_volt * dv)
    assert np.linalg.norm(moved - predicted) <= 1e-2 * np.linalg.norm(moved)


def test_force_displacement_trends_of_fig_4b():
    """F rises with z; voltage lowers force and slope; G1 is stiffer than G2 (Sect. 4.1)."""
    z = np.linspace(0.002, 0.018, 5)
    g1, g2 = ring_model(inner=G1_INNER), ring_model(inner=G2_INNER, disc=G2_DISC)
    f1_0, f1_3 = g1.force_displacement(z, 0.0), g1.force_displacement(z, 3000.0)
    f2_0 = g2.force_displacement(z, 0.0)
    assert np.all(np.diff(f1_0) > 0) and np.all(f1_3 < f1_0)
    assert np.all(np.diff(f1_3) < np.diff(f1_0))
    assert np.all(f1_0 > f2_0)


def test_lost_tension_and_bad_input_raise_with_the_key():
    model = ring_model(rings=6)
    with pytest.raises(ReducedModelError, match="load.voltage = 9000 V.*loses tension"):
        model.equilibrium(0.016, 9000.0)
    with pytest.raises(ReducedModelError, match="ring_count = 1"):
        RingModel(model.membrane, OUTER, G1_INNER, 1, G1_DISC)
    with pytest.raises(StudyError, match="geometry.inner_radius = 0"):
        RingModel.from_study(paper_study(inner=0.0, z=0.0, motion="held"))
    free_disc = ring_model(rings=6, spring=0.0)
    with pytest.raises(ReducedModelError, match="spring.stiffness = 0"):
        free_disc.operating_point(0.016, 2000.0)
