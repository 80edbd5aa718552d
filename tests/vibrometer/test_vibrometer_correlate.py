"""Pairing measured shapes with the model's by shape (copdea_fem.vibrometer.pairing).

The "measurement" here is made without the FE: an analytic circular membrane, whose modes
are ``J_m(j_mn r / a) cos(m theta + phi)`` with frequencies proportional to ``j_mn`` (the
zeros of J_m), sampled on a PSV-like grid.  The model is the same membrane with its pairs
in the nominal orientation (phi = 0 and a quarter wave) and its m = 0 modes where the
measurement's are not: the measured m = 0 modes are moved up by 20 % (an effect the model
lacks) so that they cross m >= 1 modes, where nearest-frequency pairing goes wrong.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from analytic_membrane import (
    channels,
    measured_modes,
    membrane_shape,
    model_modes,
    psv_grid,
)

from copdea_fem.mac import subspace_mac
from copdea_fem.vibrometer.pairing import (
    CorrelationError,
    correlate_shapes,
    pair_by_frequency,
    unit_key,
)


def _bases(labels):
    return [unit_key(label) for label in labels]


def test_unit_keys_group_what_a_mode_is():
    assert unit_key("(2,1)a") == unit_key("(2,1)b") == "(2,1)"
    assert unit_key("(0,1)") == "(0,1)" and unit_key("P1") == "P1"
    assert unit_key("ip(1,1)a") == unit_key("ip(1,1)b") != unit_key("ip(1,1)c")
    assert unit_key("ip(0,1)a") != unit_key("ip(0,1)b")        # torsion and radial: two modes
    # a pair turned half-way between the axes ties its letters: (1,1)a and (1,1)a-2
    assert unit_key("(1,1)a-2") == unit_key("(1,1)a") == "(1,1)"
    assert unit_key("(0,1)-2") == "(0,1)-2" != unit_key("(0,1)")   # a second (0,1): its own


@pytest.mark.parametrize("seed", range(5))
def test_shape_pairing_labels_every_mode_where_frequency_order_does_not(seed):
    rng = np.random.default_rng(seed)
    positions = psv_grid()
    point, direction = channels(positions)
    model = model_modes(positions, point, direction)
    truth, freq, shapes = measured_modes(rng, positions, point, direction)
    result = correlate_shapes(freq, shapes, model)
    by_shape = [pair.label for pair in result.pairs]
    assert _bases(by_shape) == truth
    assert all(pair.mac > 0.99 for pair in result.pairs)       # 60 dB: MAC ~ 1 - 1e-6
    # the split pairs take both members, one each
    for base in {b for b in truth if not b.startswith("(0,")}:
        members = sorted(label for label in by_shape if unit_key(label) == base)
        assert members == [base + "a", base + "b"]
    by_frequency = pair_by_frequency(freq, model.freq_hz, model.labels)
    assert _bases(by_frequency) != truth          # the crossings fool the frequency order
    wrong = sum(a != b for a, b in zip(_bases(by_frequency), truth))
    assert wrong >= 2


def test_a_single_member_of_a_pair_has_no_meaningful_mac_but_its_subspace_has():
    """The reason pairs are units: a measured member turned by 45 degrees has a single MAC of
    1/2 with each FE member and a subspace MAC of 1."""
    positions = psv_grid()
    point, direction = channels(positions, (2,))
    cos_member = membrane_shape(2, 1, 0.0, positions, point, direction)
    sin_member = membrane_shape(2, 1, -math.pi / 2, positions, point, direction)
    turned = membrane_shape(2, 1, math.pi / 4, positions, point, direction)  # 45 deg in span
    basis = np.column_stack([cos_member, sin_member])
    assert subspace_mac(turned, basis) == pytest.approx(1.0, abs=1e-12)
    single = [subspace_mac(turned, basis[:, k]) for k in range(2)]
    assert single == pytest.approx([0.5, 0.5], abs=0.02)   # 16 angles: grid-exact to ~1e-2


@pytest.mark.parametrize("case", ["rotated", "laser_1d", "points_missing", "all"])
def test_pairing_survives_rotation_1d_laser_missing_points_and_noise(case):
    """(d) A grid turned by an unknown angle, a 1-D laser (z only), 10 % of the points
    missing, 60 dB noise: every mode still gets its label."""
    rng = np.random.default_rng(7)
    positions = psv_grid()
    components = (2,) if case in ("laser_1d", "all") else (0, 1, 2)
    if case in ("points_missing", "all"):
        keep = np.sort(rng.choice(len(positions), size=int(0.9 * len(positions)),
                                  replace=False))
        positions = positions[keep]
    point, direction = channels(positions, components)
    model = model_modes(positions, point, direction)
    measured_positions = positions
    if case in ("rotated", "all"):
        # the export's frame is turned by an angle nobody told the tool: the measurement is
        # made on the turned grid, the model sampled where the file says the points are
        angle = rng.uniform(0, 2 * math.pi)
        turn = np.array([[math.cos(angle), -math.sin(angle), 0],
                         [math.sin(angle), math.cos(angle), 0], [0, 0, 1]])
        measured_positions = positions @ turn.T
    truth, freq, shapes = measured_modes(rng, measured_positions, point, direction, 60.0)
    result = correlate_shapes(freq, shapes, model)
    assert _bases([pair.label for pair in result.pairs]) == truth
    assert min(pair.mac for pair in result.pairs) > 0.95


def test_a_mode_the_model_lacks_is_unpaired_and_columns_are_filled():
    rng = np.random.default_rng(3)
    positions = psv_grid()
    point, direction = channels(positions)
    model = model_modes(positions, point, direction)
    _, freq, shapes = measured_modes(rng, positions, point, direction)
    # a spurious test mode: a random shape at 300 Hz
    spurious = rng.standard_normal(len(point)) + 1j * rng.standard_normal(len(point))
    freq = np.append(freq, 300.0)
    shapes = np.column_stack([shapes, spurious])
    result = correlate_shapes(freq, shapes, model, test_damping_ratio=np.full(len(freq), 0.02),
                              condition="c1")
    last = result.pairs[-1]
    assert last.label == "" and math.isnan(last.mac) and math.isnan(last.fe_freq_hz)
    first = result.pairs[0]
    assert first.freq_error == pytest.approx(first.fe_freq_hz / first.test_freq_hz - 1)
    assert result.mac.shape == (len(freq), len(model.labels))
    # COMAC: the pairs are near exact, so every channel that moves has COMAC ~ 1
    moving = np.abs(model.shapes).max(axis=1) > 1e-3
    assert np.nanmin(result.comac[moving]) > 0.9


def test_a_narrow_window_leaves_the_moved_modes_unpaired():
    """The window is a real limit: at 10 % the m = 0 modes, moved by 20 %, find no partner."""
    rng = np.random.default_rng(1)
    positions = psv_grid()
    point, direction = channels(positions)
    model = model_modes(positions, point, direction)
    truth, freq, shapes = measured_modes(rng, positions, point, direction)
    result = correlate_shapes(freq, shapes, model, window=0.10)
    for label, pair in zip(truth, result.pairs):
        assert (pair.label == "") == label.startswith("(0,")


@pytest.mark.parametrize("kwargs, match", [
    ({"window": 0}, "window = 0 is not allowed"),
    ({"window": float("nan")}, "window = nan is not allowed"),
    ({"mac_min": 1.5}, r"mac_min = 1.5 is not allowed; allowed: a number in \(0, 1\]"),
    ({"window": True}, "window = True is not allowed"),
])
def test_bad_settings_are_refused(kwargs, match):
    positions = psv_grid()
    point, direction = channels(positions)
    model = model_modes(positions, point, direction)
    with pytest.raises(CorrelationError, match=match):
        correlate_shapes([100.0], model.shapes[:, :1], model, **kwargs)


def test_shapes_on_other_channels_are_refused():
    positions = psv_grid()
    point, direction = channels(positions)
    model = model_modes(positions, point, direction)
    with pytest.raises(CorrelationError, match="test shapes on 10 channels, FE shapes on 252"):
        correlate_shapes([100.0], np.ones((10, 1)), model)
    with pytest.raises(CorrelationError, match="NaN"):
        correlate_shapes([100.0], np.full((252, 1), np.nan), model)


def test_one_scan_point_cannot_tell_the_shapes_apart_and_says_so(caplog):
    """On one point every out-of-plane shape is a single number along z: any two FE modes
    have MAC 1 there (|a b*|^2 / (|a|^2 |b|^2) = 1 for scalars), so a pairing "by shape" is
    a choice among equals; each pair says so (fe_auto_mac 1 >= mac_min) and the caller
    warns.  On the PSV grid the same modes are told apart (auto-MAC well below mac_min)."""
    from copdea_fem.vibrometer.model_shapes import correlate_identified

    rng = np.random.default_rng(2)
    grid = psv_grid()
    point, direction = channels(grid)
    full = correlate_shapes(*measured_modes(rng, grid, point, direction)[1:],
                            model_modes(grid, point, direction))
    assert not full.indistinct_pairs()
    assert max(pair.fe_auto_mac for pair in full.pairs if pair.label) < 0.5

    one = grid[[3]]                                   # one point on the outer ring
    point, direction = channels(one)
    model = model_modes(one, point, direction)
    _, freq, shapes = measured_modes(rng, one, point, direction)
    single = correlate_shapes(freq, shapes, model)
    paired = [pair for pair in single.pairs if pair.label]
    assert paired and single.indistinct_pairs() == tuple(paired)
    for pair in paired:
        assert pair.fe_auto_mac == pytest.approx(1.0, abs=1e-9) and pair.fe_rival
    from copdea_fem.vibrometer.identified import IdentifiedMode
    modes = [IdentifiedMode(k + 1, float(f), 0.01, shapes[:, k], 1.0)
             for k, f in enumerate(freq)]
    with caplog.at_level("WARNING", logger="copdea_fem"):
        correlate_identified("one_point", modes, model)
    assert "one_point: the measured channels cannot tell the FE's shapes apart" in caplog.text
    assert "measure more points" in caplog.text
