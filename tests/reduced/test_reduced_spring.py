"""Annex I: pumping frequencies (eq. 22) and shapes (eq. 23) of the disc on a massive spring."""

import math

import numpy as np
import pytest
import scipy.linalg
from reduced_helpers import paper_study

from copdea_fem.reduced.model import build_reduced
from copdea_fem.reduced.rings import ReducedModelError
from copdea_fem.reduced.spring import (
    pumping_added_mass,
    pumping_frequencies,
    pumping_mode_shape,
    pumping_roots,
    spring_dynamic_stiffness,
)

K_DE, K_D, M_D, M_S, L_S = 424.0, 52.0, 3.0e-3, 1.8e-3, 0.030   # N/m, N/m, kg, kg, m (Table 1)


def eq22(omega, k_de=K_DE, k_d=K_D, m_d=M_D, m_s=M_S, length=L_S):
    """Eq. (22) exactly as printed, with c_s = (k_d L_s^2 / M_s)^0.5."""
    c_s = math.sqrt(k_d * length ** 2 / m_s)
    arg = omega * length / c_s
    return (-m_d * omega ** 2 * math.sin(arg) + k_d * length * omega / c_s * math.cos(arg)
            + k_de * math.sin(arg))


def chain_frequencies(elements, lowest, k_de=K_DE, k_d=K_D, m_d=M_D, m_s=M_S):
    """Independent model: the spring as a chain of N masses and springs (lumped mass).

    Fixed at X = 0; the last node carries M_d and k_DE.  Its eigenfrequencies
    are lower bounds of eq. (22)'s roots with relative error ~ (theta/N)^2 / 24.
    Returns the ``lowest`` smallest ones (symmetric tridiagonal M^-1/2 K M^-1/2).
    """
    k_e, m_e = elements * k_d, m_s / elements
    stiffness_diag = np.full(elements, 2 * k_e)
    stiffness_diag[-1] = k_e + k_de
    mass = np.full(elements, m_e)
    mass[-1] = m_e / 2 + m_d
    scale = 1 / np.sqrt(mass)
    values = scipy.linalg.eigh_tridiagonal(stiffness_diag * scale ** 2,
                                           -k_e * scale[:-1] * scale[1:], eigvals_only=True,
                                           select="i", select_range=(0, lowest - 1))
    return np.sqrt(values) / (2 * math.pi)


def test_roots_satisfy_eq22_as_printed_and_sit_one_per_pi_interval():
    freqs = pumping_frequencies(K_DE, K_D, M_D, M_S, L_S, count=6)
    theta = 2 * math.pi * freqs * math.sqrt(M_S / K_D)
    assert np.all((theta > np.arange(6) * math.pi) & (theta < np.arange(1, 7) * math.pi))
    scale = K_DE + K_D + M_D * (2 * math.pi * freqs) ** 2   # size of eq. (22)'s terms [N/m]
    residual = np.array([eq22(2 * math.pi * f) for f in freqs])
    assert np.all(np.abs(residual) < 1e-12 * scale)


def test_roots_agree_with_an_independent_count_from_a_discrete_spring():
    count, elements = 5, 400
    freqs = pumping_frequencies(K_DE, K_D, M_D, M_S, L_S, count=count + 1)
    chain = chain_frequencies(elements, count + 1)
    cut = 0.5 * (freqs[count - 1] + freqs[count])
    assert chain[count - 1] < cut < chain[count]       # same root count: none missed/invented
    theta = 2 * math.pi * freqs[:count] * math.sqrt(M_S / K_D)
    # the lumped chain is soft by ~ (theta/N)^2 / 24; allow twice that
    assert np.all(chain[:count] <= freqs[:count] * (1 + 1e-12))
    assert np.all(1 - chain[:count] / freqs[:count] <= (theta / elements) ** 2 / 12)


def test_massless_spring_limit_is_the_rigid_disc_oscillator():
    """M_s -> 0: P1 -> sqrt((k_DE + k_d) / M_d) / 2 pi (Annex I)."""
    limit = math.sqrt((K_DE + K_D) / M_D) / (2 * math.pi)
    previous = 0.0
    for ratio in (1e-2, 1e-4, 1e-6):
        p1 = pumping_frequencies(K_DE, K_D, M_D, ratio * M_D, L_S, count=1)[0]
        # first order: the spring adds M_s / 3, shifting f by -M_s / (6 M_d); allow twice that
        assert abs(p1 / limit - 1) <= ratio / 3
        assert previous < p1 < limit
        previous = p1
    assert pumping_frequencies(K_DE, K_D, M_D, 0.0, L_S, count=2)[0] == pytest.approx(limit)
    assert math.isinf(pumping_frequencies(K_DE, K_D, M_D, 0.0, L_S, count=2)[1])


def test_small_spring_mass_follows_the_third_rule():
    """w^2 = (k_d + k_DE) / (M_d + M_s / 3) up to O((M_s / M_d)^2) (module notes)."""
    for ratio in (1e-2, 1e-3):
        p1 = pumping_frequencies(K_DE, K_D, M_D, ratio * M_D, L_S, count=1)[0]
        rule = math.sqrt((K_DE + K_D) / (M_D * (1 + ratio / 3))) / (2 * math.pi)
        # the neglected term is O(ratio^2) with a kappa-dependent coefficient (~0.1 here)
        assert abs(p1 / rule - 1) <= ratio ** 2


def test_mode_shape_eq23_meets_both_boundary_conditions():
    freq = pumping_frequencies(K_DE, K_D, M_D, M_S, L_S, count=2)[1]       # P2
    shape = lambda x: pumping_mode_shape(freq, x, K_D, M_S, L_S)           # noqa: E731
    assert shape(0.0) == 0.0
    h = 1e-7  # m; central difference of sin: relative error (beta h)^2 / 6 ~ 1e-9
    slope = (shape(L_S + h) - shape(L_S - h)) / (2 * h)
    omega = 2 * math.pi * freq
    bc = -M_D * omega ** 2 * shape(L_S) + K_D * L_S * slope + K_DE * shape(L_S)
    assert abs(bc) < 1e-6 * (M_D * omega ** 2 + K_DE)


def test_dynamic_stiffness_and_projected_added_mass():
    omega = np.array([0.0, 1.0])
    stiffness = spring_dynamic_stiffness(omega, K_D, M_S, L_S)
    assert stiffness[0] == K_D
    assert stiffness[1] == pytest.approx(K_D - M_S / 3, rel=1e-6)     # k_d - w^2 M_s / 3
    # a disc-only "mode" (m = M_d, k = k_DE + k_d, unit disc amplitude) lands on eq. (22)
    added, freq = pumping_added_mass(K_DE + K_D, M_D, 1.0, K_D, M_S, L_S)
    assert freq == pytest.approx(pumping_frequencies(K_DE, K_D, M_D, M_S, L_S, 1)[0], rel=1e-10)
    assert added > M_S / 3        # at theta ~ 2 the spring weighs more than its static third


def test_reduced_p1_with_spring_mass_sits_just_below_eq22():
    """The ring model's P1 also moves the membrane (0.32 g against 3 g of disc).

    That extra inertia can only lower P1, at most by a factor sqrt(1 + m_membrane / M_d):
    0 < 1 - f_ring / f_eq22 <= m_membrane / (2 M_d).
    """
    setup = build_reduced(paper_study())
    p1_ring = setup.reduced.frequency_hz[setup.reduced.labels.index("P1")]
    p1_annex = setup.pumping_frequency_hz[0]
    gap = 1 - p1_ring / p1_annex
    assert 0 < gap <= setup.ring_model.membrane_mass / (2 * M_D)
    expected = pumping_frequencies(setup.linearisation.axial_stiffness, K_D, M_D, M_S, L_S, 3)
    assert np.allclose(setup.pumping_frequency_hz, expected, rtol=1e-12)


def test_bad_annex_input_raises():
    with pytest.raises(ReducedModelError, match="k_DE \\+ k_d"):
        pumping_frequencies(-100.0, K_D, M_D, M_S, L_S)
    with pytest.raises(ReducedModelError, match="disc mass"):
        pumping_frequencies(K_DE, K_D, 0.0, M_S, L_S)
    with pytest.raises(ReducedModelError, match="kappa"):
        pumping_roots(1.0, -2.0, 3)
