"""The imperfection keys: read, refused with key, value and what is allowed, and a study
without them resolved and hashed exactly as before the keys existed."""

import hashlib
import json
from pathlib import Path

import pytest

from copdea_fem.study import StudyError, dump_resolved, engine_of, load_study, parse_study

ROOT = Path(__file__).resolve().parents[2]

#: sha256 (first 16 hex digits) of json.dumps(study.values, sort_keys=True): of the default
#: study, and chained over the 19 files studies/*.yaml in sorted order -- computed with the
#: code before the imperfection keys existed (main at 2a45bfa).
DEFAULT_DIGEST = "db12d1b9d55ad7c9"
STUDIES_DIGEST, STUDY_FILES = "a900b06645d87ec3", 19

IMPERFECT = {"geometry": {"frame": "baffle"},
             "membrane": {"prestretch_anisotropy": 0.02, "prestretch_axis": "30 deg",
                          "thickness_variation": [{"order": 2, "amplitude": 0.05}]},
             "imperfections": {"point_masses": [{"mass": "10 mg", "r": "25 mm", "theta": 45}]}}


def _digest(values) -> str:
    return hashlib.sha256(json.dumps(values, sort_keys=True).encode()).hexdigest()[:16]


def test_a_perfect_study_hashes_as_before_the_keys_existed():
    assert _digest(parse_study({}).values) == DEFAULT_DIGEST
    files = sorted((ROOT / "studies").glob("*.yaml"))
    assert len(files) == STUDY_FILES
    chained = hashlib.sha256()
    for path in files:
        chained.update(json.dumps(load_study(path).values, sort_keys=True).encode())
    assert chained.hexdigest()[:16] == STUDIES_DIGEST
    # given at their defaults, the keys change nothing either
    explicit = parse_study({"membrane": {"prestretch_anisotropy": 0, "prestretch_axis": 0,
                                         "thickness_variation": []},
                            "imperfections": {"point_masses": []}})
    assert _digest(explicit.values) == DEFAULT_DIGEST


def test_the_keys_read_in_si_and_round_trip(tmp_path):
    study = parse_study(IMPERFECT)
    assert study.membrane.prestretch_anisotropy == 0.02
    assert study.membrane.prestretch_axis == 30.0                  # degrees stay degrees
    term, = study.membrane.thickness_variation
    assert (term.order, term.amplitude, term.angle) == (2, 0.05, 0.0)
    mass, = study.imperfections.point_masses
    assert mass.mass == pytest.approx(1e-5) and mass.r == 0.025 and mass.theta == 45.0
    dump_resolved(study, tmp_path / "s.yaml")
    assert load_study(tmp_path / "s.yaml") == study
    assert engine_of(study) == "3d"                        # auto goes to the 3-D engine
    assert engine_of(parse_study({"geometry": {"frame": "baffle"}})) == "axisymmetric"


@pytest.mark.parametrize("given, key, allowed", [
    ({"membrane": {"prestretch_anisotropy": 0.6}}, "membrane.prestretch_anisotropy",
     "[0, 0.5]"),
    ({"membrane": {"prestretch_anisotropy": -0.1}}, "membrane.prestretch_anisotropy",
     "[0, 0.5]"),
    ({"membrane": {"prestretch_axis": "1 m"}}, "membrane.prestretch_axis", "deg"),
    ({"membrane": {"thickness_variation": [{"order": 0, "amplitude": 0.1}]}},
     "membrane.thickness_variation[0].order", "[1, 64]"),
    ({"membrane": {"thickness_variation": [{"order": 1.5, "amplitude": 0.1}]}},
     "membrane.thickness_variation[0].order", "an integer"),
    ({"membrane": {"thickness_variation": [{"order": 2, "amplitude": 1.0}]}},
     "membrane.thickness_variation[0].amplitude", "|a| < 1"),
    ({"membrane": {"thickness_variation": [{"order": 2, "amplitude": 0.6},
                                           {"order": 3, "amplitude": -0.5}]}},
     "membrane.thickness_variation", "sum |a| < 1"),
    ({"membrane": {"thickness_variation": [{"order": 2, "size": 0.1}]}},
     "membrane.thickness_variation[0]", "order"),
    ({"membrane": {"thickness_variation": "cos"}}, "membrane.thickness_variation", "a list"),
    ({"imperfections": {"point_masses": [{"mass": 0, "r": 0.02}]}},
     "imperfections.point_masses[0].mass", "> 0 kg"),
    ({"imperfections": {"point_masses": [{"mass": "1 mm", "r": 0.02}]}},
     "imperfections.point_masses[0].mass", "kg"),
    ({"imperfections": {"point_masses": [{"mass": 1e-4, "r": "35.5 mm"}]}},
     "imperfections.point_masses[0].r", "[0, 0.0355) m"),
    ({"imperfections": {"point_masses": [{"mass": 1e-4, "r": -0.01}]}},
     "imperfections.point_masses[0].r", "m"),
    ({"imperfections": {"point_masses": [{"mass": 1e-4}]}},
     "imperfections.point_masses[0]", "mass and r"),
    ({"imperfections": {"mass": 1e-4}}, "imperfections.mass", "point_masses"),
    # the axisymmetric engine's perturbation path: small, dry or in air (G1's film: 0.3157 g)
    ({"geometry": {"frame": "baffle"}, "mesh": {"engine": "axisymmetric"},
      "membrane": {"prestretch_anisotropy": 0.05}}, "membrane.prestretch_anisotropy",
     "e + sum |a| <= 0.03"),
    ({"geometry": {"frame": "baffle"}, "mesh": {"engine": "axisymmetric"},
      "membrane": {"prestretch_anisotropy": 0.02, "thickness_variation": [
          {"order": 2, "amplitude": -0.02}]}},
     "membrane.prestretch_anisotropy + membrane.thickness_variation", "mesh.engine: 3d"),
    ({"geometry": {"frame": "baffle"}, "mesh": {"engine": "axisymmetric"},
      "air": {"enabled": True}, "membrane": {"prestretch_anisotropy": 0.04}},
     "membrane.prestretch_anisotropy", "e + sum |a| <= 0.03"),
    ({"geometry": {"frame": "baffle"}, "mesh": {"engine": "axisymmetric"},
      "imperfections": {"point_masses": [{"mass": 6e-7, "r": 0.02},
                                         {"mass": 4e-7, "r": 0.01, "theta": 90}]}},
     "imperfections.point_masses = [6e-07, 4e-07]",
     "summing to <= 0.003 of the film's mass = 9.472e-07 kg"),
    ({"geometry": {"frame": "circle"}, "imperfections": {"point_masses": [
        {"mass": 1e-4, "r": 0.02}]}}, "geometry.frame", "square, baffle or none"),
])
def test_bad_values_are_refused_naming_key_value_and_allowed(given, key, allowed):
    with pytest.raises(StudyError) as refused:
        parse_study(given)
    message = str(refused.value)
    assert message.startswith(key if " = " in key else key + " = ")
    assert "allowed" in message and allowed in message


def test_the_fe_cache_key_sees_every_imperfection():
    """The diagnosis's FE cache key hashes the imperfections (a point mass lives in its own
    section), so an imperfect device never reuses a perfect device's cached modes."""
    from copdea_fem.diagnosis.fe import fe_key
    base = {"geometry": {"frame": "baffle"}}
    keys = {fe_key(parse_study({**base, **extra})) for extra in (
        {}, {"membrane": {"prestretch_anisotropy": 0.01}},
        {"membrane": {"prestretch_anisotropy": 0.01, "prestretch_axis": 10}},
        {"membrane": {"thickness_variation": [{"order": 2, "amplitude": 0.01}]}},
        {"imperfections": {"point_masses": [{"mass": 1e-5, "r": 0.02}]}},
        {"imperfections": {"point_masses": [{"mass": 1e-5, "r": 0.02, "theta": 5}]}})}
    assert len(keys) == 6


def test_the_axisymmetric_ring_model_refuses_an_imperfect_device():
    """The reduced model (rings, Sect. 3.2.1) is round: it names the keys rather than
    return the numbers of a device it does not model."""
    from copdea_fem.reduced.rings import RingModel
    RingModel.from_study(parse_study({}))
    with pytest.raises(StudyError, match=r"membrane.prestretch_anisotropy = 0.01 is not "
                                         r"allowed for the reduced model; allowed: a perfect"):
        RingModel.from_study(parse_study({"membrane": {"prestretch_anisotropy": 0.01}}))
