"""The axisymmetric engine's first-order perturbation path for imperfect devices
(:mod:`copdea_fem.fe.axisymmetric.perturbation`) against the 3-D engine, which solves the
imperfect device in full: the split of each pair, the shift of every mode from its own
engine's perfect device, and the orientation of the split members; its range enforced."""

import numpy as np
import pytest

from copdea_fem.fe import engine_for
from copdea_fem.fe.axisymmetric import perturbation
from copdea_fem.fe.pipeline import coupled_modes, dry_modes
from copdea_fem.study import StudyError, parse_study

#: The flat full membrane (r_o = 35.5 mm, no disc, frame none) at 1 kV, dry; 5 mm elements
#: of order 3 (tests/fe/test_imperfections.py: the 3-D engine's Bessel frequencies to ~1e-5).
FLAT = {"geometry": {"inner_radius": 0, "frame": "none"}, "load": {"voltage": "1 kV"},
        "mesh": {"membrane_size": "5 mm"}, "eigen": {"f_max": "560 Hz"}}
#: G1 at z = 16 mm, 2 kV, in a baffle, dry, on a coarse mesh (the 3-D whole device ~12 s).
G1 = {"geometry": {"inner_radius": "17 mm", "frame": "baffle"}, "disc": {"mass": "3 g"},
      "load": {"z": "16 mm", "voltage": "2 kV"}, "mesh": {"membrane_size": "6 mm", "order": 2},
      "eigen": {"f_max": "800 Hz"}}


def out_of_plane(base, engine, membrane=None, imperfections=None):
    raw = {section: dict(values) for section, values in base.items()}
    raw["mesh"]["engine"] = engine
    if membrane:
        raw["membrane"] = membrane
    if imperfections:
        raw["imperfections"] = imperfections
    study = parse_study(raw)
    _, modes, _ = dry_modes(study, engine=engine_for(study))
    return {mode.label: mode for mode in modes if mode.kind == "out-of-plane"}


def shifts(base, membrane, labels, imperfections=None):
    """{engine: {label: (relative shift from the engine's perfect device, mode)}}."""
    out = {}
    for engine in ("axisymmetric", "3d"):
        perfect = out_of_plane(base, engine)
        imperfect = out_of_plane(base, engine, membrane, imperfections)
        out[engine] = {label: (imperfect[label].freq_hz / perfect[label].freq_hz - 1,
                               imperfect[label]) for label in labels}
    return out


def check_against_3d(found, tolerance):
    for label, (shift, mode) in found["axisymmetric"].items():
        reference, partner = found["3d"][label]
        print(f"{label}: shift {shift:.4e} (3-D {reference:.4e}), orientation "
              f"{mode.orientation_deg:.2f} (3-D {partner.orientation_deg:.2f})")
        assert shift == pytest.approx(reference, abs=tolerance), label


def test_an_anisotropy_splits_and_shifts_the_modes_as_the_3d_engine_says():
    """e = 1 % along 30 deg on the flat membrane at 1 kV: the (1,n) pairs split at first
    order (1.7561 % against the 3-D engine's 1.7558 %), the (2,1) pair at second order
    through the (0,1) and (4,1) of the same block; each mode's shift from its engine's perfect device agrees with the
    3-D engine's to 2e-4 (measured <= 1.0e-4, 1.6e-4 for (1,2)b, in one block with (3,1)
    9 Hz away; unchanged with the band widened to 900 Hz: the e^2 part of the pre-stretch
    that the first order leaves out moves every mode by ~9e-5 on the 3-D engine), the
    split members point along and across the axis."""
    labels = ["(0,1)", "(1,1)a", "(1,1)b", "(2,1)a", "(2,1)b", "(0,2)", "(1,2)a", "(1,2)b"]
    found = shifts(FLAT, {"prestretch_anisotropy": 0.01, "prestretch_axis": "30 deg"}, labels)
    check_against_3d(found, 2e-4)
    axisymmetric = {label: mode for label, (_, mode) in found["axisymmetric"].items()}
    split = axisymmetric["(1,1)a"].freq_hz / axisymmetric["(1,1)b"].freq_hz - 1
    reference = found["3d"]["(1,1)a"][1].freq_hz / found["3d"]["(1,1)b"][1].freq_hz - 1
    print(f"(1,1) split {split:.4%} (3-D {reference:.4%})")
    assert split == pytest.approx(reference, rel=0.01)
    for label, angle in {"(1,1)a": 30.0, "(1,1)b": 120.0, "(1,2)a": 30.0, "(2,1)a": 75.0,
                         "(2,1)b": 30.0}.items():
        assert axisymmetric[label].orientation_deg == pytest.approx(angle, abs=0.2), label
        assert found["3d"][label][1].orientation_deg == pytest.approx(angle, abs=0.2), label


def test_a_thickness_term_splits_the_pairs_it_couples_as_the_3d_engine_says():
    """h0 (1 + 0.02 cos 2 (theta - 20 deg)) on the flat membrane at 1 kV: its in-plane
    equilibrium moves (the state's first-order correction du0 of the module doc), the
    (1,n) pairs split at first order, oriented along 20 and 110 deg; shifts as the 3-D
    engine's to 1e-4 (measured <= 4.5e-5)."""
    labels = ["(0,1)", "(1,1)a", "(1,1)b", "(2,1)a", "(2,1)b", "(1,2)a", "(1,2)b"]
    found = shifts(FLAT, {"thickness_variation": [{"order": 2, "amplitude": 0.02,
                                                   "angle": "20 deg"}]}, labels)
    check_against_3d(found, 1e-4)
    axisymmetric = {label: mode for label, (_, mode) in found["axisymmetric"].items()}
    assert axisymmetric["(1,1)a"].orientation_deg == pytest.approx(20.0, abs=0.2)
    assert axisymmetric["(1,1)b"].orientation_deg == pytest.approx(110.0, abs=0.2)


@pytest.mark.slow
def test_g1_with_an_anisotropy_shifts_as_on_the_3d_engine():
    """G1 at z = 16 mm, 2 kV, dry, e = 1 % along 30 deg: the cone's prestress moves at
    first order (du0); every out-of-plane mode below 800 Hz shifts from its engine's
    perfect device as on the 3-D engine to 3e-4 (measured <= 1.3e-4; the issue's 0.3 %
    is ten times that; the frequencies themselves differ by the two coarse meshes, up to
    0.6 %, so the shifts are compared)."""
    labels = ["(0,1)", "(1,1)a", "(1,1)b", "(2,1)a", "(2,1)b", "(3,1)a", "(4,1)a", "(5,1)a"]
    found = shifts(G1, {"prestretch_anisotropy": 0.01, "prestretch_axis": "30 deg"}, labels)
    check_against_3d(found, 3e-4)
    split = found["axisymmetric"]["(1,1)a"][1].freq_hz / \
        found["axisymmetric"]["(1,1)b"][1].freq_hz - 1
    assert split == pytest.approx(0.0132, abs=3e-4)     # the 3-D engine: 1.314 %


def test_a_small_point_mass_shifts_each_mode_as_first_order_theory_says():
    """The figures of tests/fe/test_imperfections.py's 3-D check on the axisymmetric path:
    20 ug at r = 12 mm, theta = 0 on the flat membrane at 0 V (5 mm, order 3): the cos
    member of each pair shifts as the closed form ``-dm phi(x0)^2 / (2 M_modal)`` on the
    Bessel modes (measured within 0.16 %, asserted 1 % as there: the second-order term is
    ~1e-3 of the first), the sin member (its nodal line through the mass) does not move;
    turned to 40 deg, the lowered member's antinode follows the mass."""
    from test_imperfections import FLAT as FLAT_3D
    from test_imperfections import bessel_shift
    flat = {section: dict(values) for section, values in FLAT_3D.items()}
    mass, radius = 2e-8, 0.012
    before = out_of_plane(flat, "axisymmetric")
    after = out_of_plane(flat, "axisymmetric", imperfections={"point_masses": [
        {"mass": mass, "r": radius, "theta": 0}]})
    study = parse_study(flat)
    for label, (m, n, member) in {"(0,1)": (0, 1, "cos"), "(1,1)a": (1, 1, "cos"),
                                  "(1,1)b": (1, 1, "sin"), "(2,1)a": (2, 1, "cos"),
                                  "(2,1)b": (2, 1, "sin"), "(0,2)": (0, 2, "cos"),
                                  "(1,2)a": (1, 2, "cos")}.items():
        shift = after[label].freq_hz / before[label].freq_hz - 1
        expected = bessel_shift(study, m, n, member, mass, radius, 0.0)
        print(f"point mass {label}: shift {shift:.4e}, first order {expected:.4e}")
        if member == "sin":
            assert abs(shift) < 1e-9, label
        else:
            assert abs(expected) > 1e-5
            assert shift == pytest.approx(expected, rel=0.01), label
    turned = out_of_plane(flat, "axisymmetric", imperfections={"point_masses": [
        {"mass": mass, "r": radius, "theta": 40}]})
    assert turned["(1,1)a"].orientation_deg == pytest.approx(40.0, abs=1e-6)
    assert turned["(1,1)a"].freq_hz == pytest.approx(after["(1,1)a"].freq_hz, rel=1e-12)
    # (2,1): cos 2(theta - 40 deg) is nearer sin 2 theta, so the lowered member is b
    assert turned["(2,1)b"].orientation_deg == pytest.approx(40.0, abs=1e-6)
    assert turned["(2,1)b"].freq_hz == pytest.approx(after["(2,1)a"].freq_hz, rel=1e-12)


def test_a_mass_on_the_disc_is_a_heavier_disc_to_first_order():
    """G1 with the disc on the spring (coarse, axisymmetric): 0.2 mg on the disc (r = 8 mm,
    r_i = 17 mm) against a disc 0.2 mg heavier solved in full: the same modes, the shift
    (P1: -2.7244e-5 vs -2.7243e-5) within 1 % (the second-order term is ~dm/M_d =
    7e-5 of it)."""
    common = {"geometry": {"frame": "baffle"}, "disc": {"motion": "spring"},
              "mesh": {"membrane_size": "6 mm", "order": 2, "engine": "axisymmetric"},
              "eigen": {"f_max": "300 Hz"}}
    perfect, loaded, heavier = (
        dry_modes(study, engine=engine_for(study))[1] for study in (
            parse_study(common),
            parse_study({**common, "imperfections": {"point_masses": [
                {"mass": "0.2 mg", "r": "8 mm", "theta": 70}]}}),
            parse_study({**common, "disc": {"motion": "spring", "mass": "3.0002 g"}})))
    assert [m.label for m in loaded] == [m.label for m in heavier]
    for before, first, full in zip(perfect, loaded, heavier):
        exact = full.freq_hz / before.freq_hz - 1
        print(f"{first.label}: shift {first.freq_hz / before.freq_hz - 1:.4e}, "
              f"heavier disc {exact:.4e}")
        assert first.freq_hz / before.freq_hz - 1 == pytest.approx(exact, rel=0.01, abs=1e-9)
    assert loaded[0].label == "P1" and abs(heavier[0].freq_hz / perfect[0].freq_hz - 1) > 1e-6


def pair_matrix(perfect, modes, pair, m):
    """The pair's 2x2 matrix of relative squared-frequency shifts in the basis (cos m theta,
    sin m theta): sum over its members of (f^2 / f0^2 - 1) v v^T, v = (cos m phi, sin m phi)
    at the member's orientation phi, f0 the mean of the perfect device's members."""
    f0 = np.mean([perfect[pair + member].freq_hz for member in "ab"])
    matrix = np.zeros((2, 2))
    for member in "ab":
        mode = modes[pair + member]
        angle = np.radians(mode.orientation_deg) * m
        v = np.array([np.cos(angle), np.sin(angle)])
        matrix += (mode.freq_hz ** 2 / f0 ** 2 - 1) * np.outer(v, v)
    return matrix


def orientations(matrix, m):
    """The members' orientations [deg], modulo 180 / m, of a pair's 2x2 matrix."""
    _, vectors = np.linalg.eigh(matrix)
    return sorted(np.degrees(np.arctan2(vectors[1, k], vectors[0, k])) / m % (180 / m)
                  for k in range(2))


@pytest.mark.slow
def test_g1_with_a_point_mass_shifts_as_on_the_3d_engine():
    """G1 at z = 16 mm, 2 kV, dry, 0.5 mg (1.6e-3 of the film) at r = 25 mm, theta = 30 deg:
    every out-of-plane mode below 800 Hz, both members of each pair, shifts from its
    engine's perfect device as on the 3-D engine to 3e-4 (the e = 1 % pin's tolerance;
    measured <= 1.4e-4, (4,1)b; shifts -1e-4 to -2.9e-3), the lowered member of each pair
    with its antinode at the mass.  The 3-D engine's whole-device mesh is mirrored from an
    octant: it splits the perfect even-m pairs by itself ((2,1) by 1.5e-4 along 0 / 45 deg,
    (4,1) by 4.8e-4 along 0 / 22.5 deg), which turns its members away from the mass by up
    to 1.2 deg; with that split added to the axisymmetric engine's 2x2 matrix of the pair
    the orientations agree within 0.2 deg (measured 0.04 deg)."""
    labels = ["(0,1)", "(1,1)a", "(1,1)b", "(2,1)a", "(2,1)b", "(3,1)a", "(3,1)b",
              "(4,1)a", "(4,1)b", "(5,1)a", "(5,1)b"]
    imperfections = {"point_masses": [{"mass": "0.5 mg", "r": "25 mm", "theta": 30}]}
    found = shifts(G1, None, labels, imperfections)
    check_against_3d(found, 3e-4)
    assert max(abs(shift) for shift, _ in found["3d"].values()) > 1e-3
    perfect = {engine: out_of_plane(G1, engine) for engine in ("axisymmetric", "3d")}
    modes = {engine: {label: mode for label, (_, mode) in found[engine].items()}
             for engine in found}
    for m in range(1, 6):
        pair = f"({m},1)"
        mesh_split = pair_matrix(perfect["3d"], perfect["3d"], pair, m)
        expected = orientations(pair_matrix(perfect["axisymmetric"], modes["axisymmetric"],
                                            pair, m) + mesh_split, m)
        measured = sorted(modes["3d"][pair + member].orientation_deg % (180 / m)
                          for member in "ab")
        print(f"{pair}: 3-D orientations {measured}, expected {expected}")
        period = 180 / m
        for angle in measured:
            assert min(abs((angle - reference + period / 2) % period - period / 2)
                       for reference in expected) < 0.2, pair
        _, lowered = min(found["axisymmetric"][pair + member] for member in "ab")
        assert lowered.orientation_deg == pytest.approx(30.0, abs=1e-6), pair


#: G1 quick (studies/g1_z16_v2_quick.yaml: z = 16 mm, 2 kV, 6 mm order 2, pressure order 1,
#: 35.5 mm air) in a baffle, coupled with the air, below 1.05 kHz.
G1_AIR = {"geometry": {"inner_radius": "17 mm", "frame": "baffle"}, "disc": {"mass": "3 g"},
          "load": {"z": "16 mm", "voltage": "2 kV"}, "air": {"enabled": True},
          "mesh": {"membrane_size": "6 mm", "order": 2, "pressure_order": 1,
                   "air_size": "35.5 mm"},
          "eigen": {"f_max": "1050 Hz"}}


def coupled_out_of_plane(base, engine, membrane=None):
    raw = {section: dict(values) for section, values in base.items()}
    raw["mesh"]["engine"] = engine
    if membrane:
        raw["membrane"] = membrane
    study = parse_study(raw)
    solution = coupled_modes(study, engine=engine_for(study))
    return {mode.label: mode for mode in solution.modes if mode.kind == "out-of-plane"}


@pytest.mark.slow
def test_g1_in_air_with_an_anisotropy_shifts_as_on_the_3d_engine():
    """G1 quick in a baffle, coupled with the air, e = 1 % along x (the 3-D engine meshes a
    quadrant): both members of (1,1), (2,1), (1,2) and the (0,1), (0,2) shift from their
    engine's perfect device as on the 3-D engine.  The n = 1 modes to the dry pin's 3e-4
    (measured <= 2.4e-4, (1,1)a; (1,1) split 1.368 % vs 1.430 %, of which the 3-D mesh
    splits the perfect pair by 0.040 %); the n = 2 modes near 1 kHz to 3e-3 (measured
    7.4e-4 (0,2), 2.2e-3 (1,2)b): there the 3-D engine's own coarse air moves its shifts by
    up to 2e-3 (at pressure order 2 (1,2)a/b are 1.3e-3 and 3.1e-4 off; the axisymmetric
    engine's shifts move by 1e-4; docs/imperfections.md)."""
    anisotropy = {"prestretch_anisotropy": 0.01, "prestretch_axis": "0 deg"}
    found = {}
    for engine in ("axisymmetric", "3d"):
        perfect = coupled_out_of_plane(G1_AIR, engine)
        imperfect = coupled_out_of_plane(G1_AIR, engine, anisotropy)
        found[engine] = {label: (imperfect[label].freq_hz / perfect[label].freq_hz - 1,
                                 imperfect[label]) for label in
                         ("(0,1)", "(1,1)a", "(1,1)b", "(2,1)a", "(2,1)b", "(0,2)",
                          "(1,2)a", "(1,2)b")}
    for label, (shift, mode) in found["axisymmetric"].items():
        reference, partner = found["3d"][label]
        print(f"{label}: shift {shift:.4e} (3-D {reference:.4e}), damping "
              f"{mode.freq_im_hz:.4f} Hz (3-D {partner.freq_im_hz:.4f} Hz)")
        assert shift == pytest.approx(reference, abs=3e-4 if label[3] == "1" else 3e-3), label
        if mode.m:
            assert mode.orientation_deg == pytest.approx(partner.orientation_deg, abs=0.5)
    split = found["axisymmetric"]["(1,1)a"][1].freq_hz / \
        found["axisymmetric"]["(1,1)b"][1].freq_hz - 1
    assert split > 0.013 and found["axisymmetric"]["(1,1)b"][0] < -6e-3


def test_in_air_a_mass_on_the_disc_is_a_heavier_disc_to_first_order():
    """G1 quick in a baffle, coupled with the air, the disc on its spring: 0.2 mg on the
    disc against a disc 0.2 mg heavier solved in full: each coupled mode's complex
    frequency moves the same (first order, through the left eigenvector's norm ``lambda
    u^T M u - p^T C u + p^T Q p``, the air's share included), real and imaginary parts."""
    common = {**{section: dict(values) for section, values in G1_AIR.items()},
              "disc": {"motion": "spring", "mass": "3 g"}}
    common["mesh"]["engine"] = "axisymmetric"
    common["eigen"] = {"f_max": "500 Hz"}
    perfect, loaded, heavier = (
        coupled_modes(study, engine=engine_for(study)).modes for study in (
            parse_study(common),
            parse_study({**common, "imperfections": {"point_masses": [
                {"mass": "0.2 mg", "r": "8 mm", "theta": 70}]}}),
            parse_study({**common, "disc": {"motion": "spring", "mass": "3.0002 g"}})))
    assert [m.label for m in loaded] == [m.label for m in heavier]
    moved = 0
    for before, first, full in zip(perfect, loaded, heavier):
        if first.kind == "air":
            continue
        ours = complex(first.freq_hz - before.freq_hz, first.freq_im_hz - before.freq_im_hz)
        exact = complex(full.freq_hz - before.freq_hz, full.freq_im_hz - before.freq_im_hz)
        print(f"{first.label}: shift {ours:.4e} Hz, heavier disc {exact:.4e} Hz")
        assert abs(ours - exact) <= 0.01 * abs(exact) + 1e-7 * before.freq_hz, first.label
        moved += abs(exact) > 1e-5 * before.freq_hz
    assert moved >= 1


def test_beyond_its_tolerance_the_path_refuses_naming_key_value_and_limit(monkeypatch):
    """The neglected higher-order shift is checked after the solve: with the tolerance
    set below it, the same study is refused, naming the key, its value and the limit."""
    monkeypatch.setattr(perturbation, "TOLERANCE", 1e-12)
    raw = {section: dict(values) for section, values in FLAT.items()}
    raw["mesh"]["engine"] = "axisymmetric"
    raw["membrane"] = {"prestretch_anisotropy": 0.01}
    study = parse_study(raw)
    with pytest.raises(perturbation.PerturbationRangeError) as refused:
        dry_modes(study, engine=engine_for(study))
    message = str(refused.value)
    assert "membrane.prestretch_anisotropy = 0.01" in message
    assert "limit 1e-12" in message and "mesh.engine: 3d" in message


def test_auto_routes_an_imperfect_device_by_the_paths_range_and_says_why(caplog):
    """``auto`` sends an imperfect device within the perturbation path's range, dry or in
    air, to the axisymmetric engine, and to the 3-D engine: beyond the range, for a forced
    response (in air too), on a square frame; each logged with its reason.  On ``axisymmetric`` the
    forced response (which the perturbation path does not make) is refused naming the
    engine."""
    def routed(forced_response=False, **sections):
        raw = {section: dict(values) for section, values in FLAT.items()}
        raw["membrane"] = {"prestretch_anisotropy": 0.01}
        for section, values in sections.items():
            raw.setdefault(section, {}).update(values)
        caplog.clear()
        with caplog.at_level("INFO", logger="copdea_fem.fe.engines"):
            name = engine_for(parse_study(raw), forced_response=forced_response).name
        return name, caplog.text

    name, log = routed()
    assert name == "axisymmetric"
    assert "mesh.engine = auto: the axisymmetric engine for membrane.prestretch_anisotropy " \
        "(within the range" in log
    name, log = routed(air={"enabled": True})
    assert name == "axisymmetric" and "(within the range of its first-order perturbation " \
        "path (coupled modes))" in log
    name, log = routed(air={"enabled": True}, membrane={"prestretch_anisotropy": 0.04})
    assert name != "axisymmetric" and "e + sum |a| <= 0.03" in log and "= 0.04" in log
    name, log = routed(forced_response=True, air={"enabled": True})
    assert name != "axisymmetric" and "a forced response" in log
    name, log = routed(membrane={"prestretch_anisotropy": 0.02, "thickness_variation": [
        {"order": 2, "amplitude": 0.02}]})
    assert name != "axisymmetric" and "e + sum |a| <= 0.03" in log and "= 0.04" in log
    name, log = routed(imperfections={"point_masses": [{"mass": "1 ug", "r": "20 mm"}]})
    assert name == "axisymmetric" and "membrane.prestretch_anisotropy, " \
        "imperfections.point_masses (within the range" in log
    name, log = routed(imperfections={"point_masses": [{"mass": "2 mg", "r": "20 mm"}]})
    assert name != "axisymmetric" and "imperfections.point_masses = [2e-06]" in log \
        and "of the film's mass" in log
    name, log = routed(forced_response=True)
    assert name != "axisymmetric" and "a forced response" in log
    name, log = routed(geometry={"frame": "square"})
    assert name != "axisymmetric" and "geometry.frame = 'square'" in log
    raw = {section: dict(values) for section, values in FLAT.items()}
    raw["membrane"] = {"prestretch_anisotropy": 0.01}
    raw["mesh"]["engine"] = "axisymmetric"
    study = parse_study(raw)
    with pytest.raises(StudyError, match="mesh.engine = 'axisymmetric' is not allowed for a "
                                         "forced response.*allowed: mesh.engine: 3d"):
        engine_for(study).forced_problem(study)


def test_the_shape_of_a_split_member_is_turned_to_its_orientation():
    """The sampled shape (sweeps' tracking, ParaView) of a split member is
    ``cos m (theta - orientation)``: its largest normal displacement round a circle lies at
    the orientation."""
    from copdea_fem.fe.axisymmetric.modes import sampled_shapes
    raw = {section: dict(values) for section, values in FLAT.items()}
    raw["mesh"]["engine"] = "axisymmetric"
    raw["membrane"] = {"prestretch_anisotropy": 0.01, "prestretch_axis": "30 deg"}
    study = parse_study(raw)
    state, modes, _ = dry_modes(study, engine=engine_for(study))
    member = next(mode for mode in modes if mode.label == "(1,1)b")
    normal = sampled_shapes(state, [member])[0][:40 * 64].reshape(40, 64)
    angles = 360.0 * np.arange(64) / 64
    peak = angles[int(np.argmax(np.abs(normal).sum(axis=0)))]
    assert min(abs(peak - 120.0), abs(peak - 300.0)) <= 360 / 64
