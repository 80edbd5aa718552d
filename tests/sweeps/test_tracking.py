"""Mode tracking (copdea_fem.sweeps.tracking) on constructed families with known answers.

Each family is a small pencil ``K(s) x = lam M x`` with a non-identity mass
``M`` (so the mass-weighted MAC is exercised): ``K(s) = M^1/2 A(s) M^1/2``
has the eigenvalues of the symmetric ``A(s)`` and eigenvectors
``M^-1/2 y``.  The "true" identity of a mode is known by construction:

* crossing: ``A = diag(2 + s, 2 - s, 5)`` -- two uncoupled modes (different
  m) whose eigenvalues cross at s = 0;
* veering: the same with a coupling ``c`` between them -- eigenvalues
  ``2 -+ sqrt(s^2 + c^2)`` never cross, the shapes rotate into each other
  over a width ~ c;
* pair: a doubly degenerate m = 1 eigenvalue (solver basis rotated at random
  at every point) crossed by an m = 0 mode, later split by up to 5 %.
"""

import math

import numpy as np
import pytest
import scipy.linalg

from copdea_fem.mac import mac_matrix, subspace_mac
from copdea_fem.sweeps.tracking import (
    ModeSet,
    TrackingInputError,
    TrackingSettings,
    base_label,
    group_degenerate,
    track_modes,
)

MASS = np.diag([1.0, 2.0, 1.5, 0.7])
FREQ_SCALE_HZ = 100.0   # f = 100 Hz * sqrt(lam of A)


def _pencil(matrix_a, mass):
    root = np.sqrt(mass)
    return root @ matrix_a @ root


def _mode_set(matrix_a, names, m_of_dof, mass, rng=None, pair_dofs=()):
    """Eigenpairs of K = M^1/2 A M^1/2, labelled by their dominant DOF (as a shape label)."""
    n = matrix_a.shape[0]
    mass = mass[:n, :n]
    values, vectors = scipy.linalg.eigh(_pencil(matrix_a, mass), mass)
    if rng is not None and pair_dofs:
        # an eigensolver returns any basis of a degenerate eigenspace: rotate it
        members = [k for k in range(n) if np.argmax(np.abs(np.sqrt(mass) @ vectors[:, k]))
                   in pair_dofs]
        if len(members) == 2:
            angle = rng.uniform(0, np.pi)
            rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
            vectors[:, members] = vectors[:, members] @ rotation
    energy = (np.sqrt(mass) @ vectors) ** 2
    dominant = [int(np.argmax(energy[:, k])) for k in range(n)]
    labels = [names[d] for d in dominant]
    seen = {}
    for k, label in enumerate(labels):   # a/b suffixes for repeated labels, like modes.py
        seen.setdefault(label, []).append(k)
    for label, ks in seen.items():
        if len(ks) > 1:
            for suffix, k in zip("ab", ks):
                labels[k] = label + suffix
    return ModeSet(freq_hz=FREQ_SCALE_HZ * np.sqrt(values), labels=labels,
                   kinds=["out-of-plane"] * n, m=[m_of_dof[d] for d in dominant],
                   vectors=vectors, weighted=mass @ vectors, space="same-mesh")


def _two_mode_family(s, coupling):
    return np.array([[2 + s, coupling, 0], [coupling, 2 - s, 0], [0, 0, 5.0]])


def _track_of(result, sets, label):
    """Track ids of the modes labelled ``label`` at every point."""
    return [int(result.track[p][modes.labels.index(label)]) for p, modes in enumerate(sets)]


# --------------------------------------------------------------------------- MAC


def test_mac_matrix_is_identity_on_mass_orthonormal_modes_and_scale_invariant():
    rng = np.random.default_rng(1)
    a = rng.standard_normal((4, 4))
    values, vectors = scipy.linalg.eigh(_pencil(a + a.T + 8 * np.eye(4), MASS), MASS)
    np.testing.assert_allclose(mac_matrix(vectors, vectors, MASS), np.eye(4), atol=1e-12)
    scaled = vectors * np.array([3.0, -0.2, 1e-3, 7.0])
    np.testing.assert_allclose(mac_matrix(vectors, scaled, MASS), np.eye(4), atol=1e-12)
    # without the mass matrix the modes are not orthogonal: the weighting matters
    assert mac_matrix(vectors, vectors).max(initial=0, where=~np.eye(4, dtype=bool)) > 1e-3


def test_subspace_mac_ignores_the_basis_inside_a_pair():
    rng = np.random.default_rng(2)
    basis = rng.standard_normal((6, 2))
    angle = 0.7
    rotated = basis @ np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    assert subspace_mac(basis, rotated) == pytest.approx(1.0, abs=1e-12)
    assert subspace_mac(basis, basis[:, :1]) == pytest.approx(1.0, abs=1e-12)
    # single vectors: the plain MAC; with one direction in common out of two: 0.5
    assert subspace_mac(basis[:, :1], basis[:, 1:]) == pytest.approx(
        mac_matrix(basis[:, 0], basis[:, 1])[0, 0])
    other = np.column_stack([basis[:, 0], rng.standard_normal(6)])
    other[:, 1] -= basis @ np.linalg.lstsq(basis, other[:, 1], rcond=None)[0]
    assert subspace_mac(basis, other) == pytest.approx(0.5, abs=1e-12)


def test_units_pair_only_same_kind_same_m_within_tolerance():
    freq = [100.0, 100.05, 100.1, 150.0, 151.0]
    units = group_degenerate(freq, ["out-of-plane"] * 5, [1, 1, 0, 2, 2], pair_tolerance=0.001)
    assert units == [(0, 1), (2,), (3,), (4,)]
    assert group_degenerate(freq, ["out-of-plane"] * 5, [1, 1, 0, 2, 2], 0.01)[-1] == (3, 4)
    assert base_label("(1,1)a") == "(1,1)" and base_label("ip(2,1)c") == "ip(2,1)"
    assert base_label("P1") == "P1" and base_label("IP2") == "IP2"


# --------------------------------------------------------------------------- crossing / veering


STEPS = np.linspace(-1.0, 1.0, 21)
NAMES = {0: "(0,1)", 1: "(2,1)", 2: "(0,2)"}


def test_crossing_keeps_shape_identities_and_the_tracks_cross():
    # different m: no coupling, true crossing at s = 0
    sets = [_mode_set(_two_mode_family(s, 0.0), NAMES, {0: 0, 1: 2, 2: 0}, MASS) for s in STEPS]
    result = track_modes(sets)
    for label in NAMES.values():
        ids = _track_of(result, sets, label)
        assert len(set(ids)) == 1, (label, ids)
        assert result.labels[ids[0]] == label
    first = _track_of(result, sets, "(0,1)")[0]
    freq_first = [modes.freq_hz[list(result.track[p]).index(first)] for p, modes in enumerate(sets)]
    assert np.all(np.diff(freq_first) > 0)   # (0,1) rises through the crossing
    assert len(result.labels) == 3
    assert all(np.nanmin(mac) > 0.999 for mac in result.mac_previous[1:])


def test_crossing_is_found_by_the_shapes_alone_when_labels_say_nothing():
    # the same crossing with one uninformative label and one m: only the MAC can tell
    # which mode is which (nearest-frequency matching would swap them at s = 0)
    sets, dominant = [], []
    for s in STEPS + 0.05:
        modes = _mode_set(_two_mode_family(s, 0.0), NAMES, {0: 0, 1: 2, 2: 0}, MASS)
        dominant.append(list(np.argmax(np.abs(np.sqrt(MASS[:3, :3]) @ modes.vectors), axis=0)))
        modes.labels, modes.m = ["mode"] * 3, np.zeros(3, int)
        sets.append(modes)
    result = track_modes(sets)
    for dof in range(3):
        ids = {int(result.track[p][dominant[p].index(dof)]) for p in range(len(sets))}
        assert len(ids) == 1, (dof, ids)


def test_resolved_veering_follows_the_branches_and_keeps_their_ids():
    # same m, coupling 0.2: the veering spans ~0.4 in s, resolved by steps of 0.1
    coupling = 0.2
    sets = [_mode_set(_two_mode_family(s, coupling), {0: "(0,1)", 1: "(0,2)", 2: "(0,3)"},
                      {0: 0, 1: 0, 2: 0}, MASS) for s in STEPS]
    result = track_modes(sets)
    lower = [int(result.track[p][np.argmin(modes.freq_hz)]) for p, modes in enumerate(sets)]
    upper = [int(result.track[p][np.argsort(modes.freq_hz)[1]]) for p, modes in enumerate(sets)]
    assert len(set(lower)) == 1 and len(set(upper)) == 1 and lower[0] != upper[0]
    # the branches exchange their shapes: the lower track starts as (0,1), ends as (0,2)
    assert sets[0].labels[int(np.argmin(sets[0].freq_hz))] == "(0,1)"
    assert sets[-1].labels[int(np.argmin(sets[-1].freq_hz))] == "(0,2)"
    assert result.labels[lower[0]] == "(0,1)->(0,2)"
    # the exact branch rotation per step, cos^2 of the angle change, is the worst MAC seen
    angle = 0.5 * np.arctan2(coupling, STEPS)
    worst_expected = np.min(np.cos(np.diff(angle)) ** 2)
    worst_seen = min(np.nanmin(mac) for mac in result.mac_previous[1:])
    assert worst_seen == pytest.approx(worst_expected, rel=1e-6)


def test_veering_narrower_than_the_step_is_followed_by_shape():
    # coupling 1e-3 << step 0.1: at this sampling it is a crossing (documented behaviour);
    # the points straddle s = 0, where the shapes are fully mixed, by half a step
    sets = [_mode_set(_two_mode_family(s, 1e-3), {0: "(0,1)", 1: "(0,2)", 2: "(0,3)"},
                      {0: 0, 1: 0, 2: 0}, MASS) for s in STEPS + 0.05]
    result = track_modes(sets)
    assert len(set(_track_of(result, sets, "(0,1)"))) == 1
    assert len(set(_track_of(result, sets, "(0,2)"))) == 1


# --------------------------------------------------------------------------- pairs


def test_degenerate_pair_stays_a_pair_through_a_crossing_and_a_split():
    rng = np.random.default_rng(3)
    names = {0: "(1,1)", 1: "(1,1)", 2: "(0,1)", 3: "(0,2)"}
    m_of_dof = {0: 1, 1: 1, 2: 0, 3: 0}
    sets = []
    # (0,1) rises through the pair at s = 0.5 (never sampled exactly), then the pair splits
    for s in np.linspace(0.0, 1.0, 10):
        split = max(0.0, s - 0.6) / 0.4 * 0.05          # 0 .. 5 % beyond s = 0.6
        matrix_a = np.diag([2.0, 2.0 * (1 + split) ** 2, 1.0 + 2.0 * s, 5.0])
        sets.append(_mode_set(matrix_a, names, m_of_dof, MASS, rng=rng, pair_dofs=(0, 1)))
    settings = TrackingSettings(pair_tolerance=0.01)   # the 5 % split is beyond it
    result = track_modes(sets, settings)
    pair_tracks = set()
    for p, modes in enumerate(sets):
        members = [k for k, label in enumerate(modes.labels) if label.startswith("(1,1)")]
        assert len(members) == 2
        ids = {int(result.track[p][k]) for k in members}
        assert len(ids) == 1, (p, ids)                  # both members on one track
        assert sorted(result.member[p][members]) == [0, 1]
        assert set(result.unit_size[p][members]) == {2}
        pair_tracks |= ids
    assert len(pair_tracks) == 1
    assert len(set(_track_of(result, sets, "(0,1)"))) == 1
    assert len(set(_track_of(result, sets, "(0,2)"))) == 1
    assert len(result.labels) == 3
    # the pair's subspace MAC stays 1 although its basis is random at every point
    pair_id = pair_tracks.pop()
    for p in range(1, len(sets)):
        macs = result.mac_previous[p][result.track[p] == pair_id]
        assert np.all(macs > 1 - 1e-9)


def test_a_split_pair_keeps_each_member_on_its_shape_when_their_order_turns_over():
    """An imperfection growing along the sweep (an anisotropic pre-stretch): at s = 0 the
    pair is split by a mesh's 1e-4 with the DOF-0 member on top; from s = 0.25 the
    imperfection puts it below, 4 % apart at s = 1 (beyond the pair tolerance).  Each
    member keeps its index (and so its place in the table) along its own shape, although
    the frequency order of the two turns over; the pair stays one track."""
    names = {0: "(1,1)", 1: "(1,1)", 2: "(0,1)"}
    m_of_dof = {0: 1, 1: 1, 2: 0}
    sets = [_mode_set(np.diag([2.0 * (1 + 1e-4 - 0.04 * s), 2.0 * (1 + 0.04 * s), 1.0]),
                      names, m_of_dof, MASS) for s in np.linspace(0.0, 1.0, 5)]
    result = track_modes(sets, TrackingSettings(pair_tolerance=0.01))
    members_of_dof0, order_of_dof0 = [], []
    for p, modes in enumerate(sets):
        shapes = (np.sqrt(MASS[:3, :3]) @ modes.vectors) ** 2
        pair = [k for k in range(3) if modes.m[k] == 1]
        dof0 = max(pair, key=lambda k: shapes[0, k])
        members_of_dof0.append(int(result.member[p][dof0]))
        order_of_dof0.append(int(modes.freq_hz[dof0] > min(modes.freq_hz[pair])))
        assert len({int(result.track[p][k]) for k in pair}) == 1
    assert order_of_dof0 == [1, 0, 0, 0, 0]              # the order turns over ...
    assert members_of_dof0 == [1, 1, 1, 1, 1]            # ... the member does not


def test_modes_leaving_and_entering_the_band_open_and_close_tracks():
    full = _mode_set(_two_mode_family(0.5, 0.0), NAMES, {0: 0, 1: 2, 2: 0}, MASS)
    keep = [0, 1]     # the highest mode leaves the band at the middle point
    partial = ModeSet(full.freq_hz[keep], [full.labels[k] for k in keep],
                      [full.kinds[k] for k in keep], full.m[keep], full.vectors[:, keep],
                      full.weighted[:, keep], space=full.space)
    empty = ModeSet(np.zeros(0), [], [], np.zeros(0, int))          # a failed point
    result = track_modes([full, partial, empty, full])
    assert list(result.track[1]) == list(result.track[0][keep])
    assert result.track[2].size == 0
    assert result.track[3][2] not in result.track[0]              # re-entering: a new track
    assert list(result.track[3][keep]) == list(result.track[0][keep])   # bridged over the gap


def test_without_comparable_shapes_only_equal_labels_continue():
    first = ModeSet([100.0, 200.0], ["(0,1)", "(1,1)"], ["out-of-plane"] * 2, [0, 1])
    second = ModeSet([120.0, 210.0], ["(0,1)", "(2,1)"], ["out-of-plane"] * 2, [0, 2])
    result = track_modes([first, second])
    assert result.track[1][0] == result.track[0][0] and math.isnan(result.mac_previous[1][0])
    assert result.track[1][1] not in result.track[0]


def test_sampled_shapes_compare_across_different_meshes():
    rng = np.random.default_rng(4)
    samples = rng.standard_normal((2, 50))
    first = ModeSet([100.0, 130.0], ["(0,1)", "(0,2)"], ["out-of-plane"] * 2, [0, 0],
                    vectors=rng.standard_normal((7, 2)), space="mesh A", sampled=samples)
    # a finer mesh: other vectors, the same sampled shapes, frequencies crossed over
    second = ModeSet([125.0, 120.0], ["(0,1)", "(0,2)"], ["out-of-plane"] * 2, [0, 0],
                     vectors=rng.standard_normal((11, 2)), space="mesh B",
                     sampled=samples * np.array([[2.0], [-1.0]]))
    result = track_modes([first, second])
    assert list(result.track[1]) == list(result.track[0])
    np.testing.assert_allclose(result.mac_previous[1], 1.0)


@pytest.mark.parametrize("name, value", [("mac_min", 1.5), ("pair_tolerance", -0.1),
                                         ("label_weight", "high")])
def test_bad_settings_name_key_and_range(name, value):
    with pytest.raises(TrackingInputError, match=f"tracking.{name} = .* is not allowed; allowed"):
        TrackingSettings(**{name: value})
