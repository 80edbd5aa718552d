"""Rung 1 of the verification ladder: eq. (20) + (7) at a material point."""

import numpy as np
import pytest

from copdea_fem.fe.materials import VACUUM_PERMITTIVITY, Membrane

TABLE1 = Membrane(c10=228.5e3, c20=8.4e3, c01=-28.6e3, permittivity=2.8 * VACUUM_PERMITTIVITY,
                  thickness=100e-6, density=1490.0, prestretch=1.2)


def hand_stresses(l1, l2, voltage, mat=TABLE1):
    """Holzapfel's incompressible plane-stress result, written independently:
    sigma_i = 2 (l_i^2 - l3^2) (W1 + l_j^2 W2) - eps (V/h)^2, with
    W1 = dPsi/dI1 = c10 + 2 c20 (I1 - 3), W2 = dPsi/dI2 = c01 (I2 = I_{-1} for J = 1),
    l3 = 1/(l1 l2), h = h0 l3."""
    l3 = 1 / (l1 * l2)
    i1 = l1**2 + l2**2 + l3**2
    w1, w2 = mat.c10 + 2 * mat.c20 * (i1 - 3), mat.c01
    maxwell = mat.permittivity * (voltage / (mat.thickness * l3)) ** 2
    return (2 * (l1**2 - l3**2) * (w1 + l2**2 * w2) - maxwell,
            2 * (l2**2 - l3**2) * (w1 + l1**2 * w2) - maxwell)


@pytest.mark.parametrize("l1, l2", [(1.2, 1.2), (1.5, 1.1)])
@pytest.mark.parametrize("voltage", [0.0, 3000.0])
def test_principal_stresses_match_hand_calculation(l1, l2, voltage):
    got = TABLE1.principal_stresses(l1, l2, voltage)
    expected = hand_stresses(l1, l2, voltage)
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_equibiaxial_numbers():
    # lambda = 1.2, V = 0: I1 = 2*1.44 + 1/1.44^2, sigma = 2 (1.44 - 1/2.0736)(W1 + 1.44 c01)
    i1 = 2 * 1.44 + 1 / 1.44**2
    sigma = 2 * (1.44 - 1 / 2.0736) * (228.5e3 + 2 * 8.4e3 * (i1 - 3) + 1.44 * -28.6e3)
    assert TABLE1.equibiaxial_tension(0.0) == pytest.approx(sigma * 100e-6 / 1.44, rel=1e-12)
    # 2 kV lowers the tension by the Maxwell stress times the thickness: eps V^2 / h
    drop = TABLE1.permittivity * 2000.0**2 / (100e-6 / 1.44)
    assert TABLE1.equibiaxial_tension(0.0) - TABLE1.equibiaxial_tension(2000.0) == \
        pytest.approx(drop, rel=1e-10)


def test_energy_partials_against_finite_differences():
    tr_c, det_c, voltage = 3.1, 2.3, 2500.0
    d = TABLE1.free_energy_partials(tr_c, det_c, voltage)
    psi = lambda t, q: TABLE1.free_energy(t, q, voltage)
    step = 1e-5
    d_tr = (psi(tr_c + step, det_c) - psi(tr_c - step, det_c)) / (2 * step)
    d_det = (psi(tr_c, det_c + step) - psi(tr_c, det_c - step)) / (2 * step)
    np.testing.assert_allclose(d[:2], [d_tr, d_det], rtol=1e-7)
    second = lambda f, i: (TABLE1.free_energy_partials(*f(step), voltage)[i]
                           - TABLE1.free_energy_partials(*f(-step), voltage)[i]) / (2 * step)
    np.testing.assert_allclose(
        d[2:], [second(lambda h: (tr_c + h, det_c), 0), second(lambda h: (tr_c, det_c + h), 0),
                second(lambda h: (tr_c, det_c + h), 1)], rtol=1e-6)


def test_reference_state_is_stress_free():
    np.testing.assert_allclose(TABLE1.principal_stresses(1.0, 1.0, 0.0), (0.0, 0.0), atol=1e-9)
