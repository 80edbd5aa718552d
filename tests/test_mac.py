"""The MAC of complex shapes (copdea_fem.mac) against values computed by hand.

A measured or damped mode's shape is complex with a phase that varies from channel to
channel; the MAC is ``|a^H b|^2 / ((a^H a)(b^H b))`` with the conjugate on the first vector.
Without it (``a^T b``) two identical shapes whose phase rotates across the channels cancel.
"""

from __future__ import annotations

import numpy as np
import pytest

from copdea_fem.mac import ShapeComparisonError, mac_matrix, subspace_mac


def test_mac_of_shapes_whose_phase_varies_across_channels_is_the_hand_value():
    # a = [1, i], b = [1, 2i]: a^H b = 1 + (-i)(2i) = 3, a^H a = 2, b^H b = 5 -> 9 / 10
    # (without the conjugate: a^T b = 1 + (i)(2i) = -1 -> 1 / 10)
    first = np.array([1.0, 1j])
    second = np.array([1.0, 2j])
    assert mac_matrix(first, second)[0, 0] == pytest.approx(0.9, abs=1e-12)
    assert mac_matrix(second, first)[0, 0] == pytest.approx(0.9, abs=1e-12)


def test_a_travelling_phase_shape_has_mac_one_with_itself_and_its_rotations():
    # the phase runs once round the channels: a^T a = sum exp(2 i phi) = 0 but a^H a = 8
    phase = np.exp(1j * np.linspace(0.0, 2 * np.pi, 8, endpoint=False))
    shape = (1.0 + 0.5 * np.arange(8)) * phase
    assert mac_matrix(shape, shape)[0, 0] == pytest.approx(1.0, abs=1e-12)
    assert mac_matrix(shape, np.exp(0.7j) * shape)[0, 0] == pytest.approx(1.0, abs=1e-12)
    # the subspace MAC of single vectors is their MAC
    assert subspace_mac(shape, np.exp(0.7j) * shape) == pytest.approx(1.0, abs=1e-12)
    # its complex conjugate (phase running the other way): |sum |a_c|^2 e^{2 i phi_c}|^2 / |a|^4
    expected = abs(np.sum(np.abs(shape) ** 2 * phase ** 2)) ** 2 / np.sum(
        np.abs(shape) ** 2) ** 2
    assert mac_matrix(shape, shape.conj())[0, 0] == pytest.approx(expected, abs=1e-12)
    assert expected < 0.1


def test_shapes_of_different_lengths_are_refused_by_name():
    with pytest.raises(ShapeComparisonError, match="vectors of length 2 and 3"):
        mac_matrix(np.ones(2), np.ones(3))
