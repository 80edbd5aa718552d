"""The enclosure under the membrane (geometry.enclosure*, air.outside): study checks."""

import math

import pytest

from copdea_fem.study import ENCLOSURE_AIR_SHARE, StudyError, engine_of, parse_study

BAFFLE = {"frame": "baffle", "enclosure": "cylinder"}
BAD_ENCLOSURES = [
    ({"geometry": {**BAFFLE, "enclosure_depth": 0}}, "geometry.enclosure_depth", "(0, 10] m"),
    ({"geometry": {**BAFFLE, "enclosure_depth": "-5 mm"}}, "geometry.enclosure_depth", "(0, 10]"),
    ({"geometry": {**BAFFLE, "enclosure": "barrel"}}, "geometry.enclosure",
     "one of none, cylinder, bowl, box"),
    ({"geometry": {**BAFFLE, "enclosure_radius": "30 mm"}}, "geometry.enclosure_radius",
     ">= 0.0355 m = geometry.outer_radius"),
    ({"geometry": {"frame": "none", "enclosure": "cylinder", "enclosure_vent_radius": "40 mm",
                   "enclosure_radius": "40 mm"}},
     "geometry.enclosure_vent_radius", "narrower than the enclosure's bottom"),
    ({"geometry": {"frame": "none", "enclosure": "bowl", "enclosure_vent_radius": "35.5 mm"}},
     "geometry.enclosure_vent_radius", "[0, 0.0355) m"),
    ({"geometry": {**BAFFLE, "enclosure_vent_radius": "5 mm"}},
     "geometry.enclosure_vent_radius", "no outside air for the vent"),
    ({"geometry": {"frame": "none", "enclosure": "box"}}, "geometry.enclosure",
     "the square frame"),
    ({"geometry": {"frame": "baffle", "enclosure": "box"}}, "geometry.enclosure",
     "the square frame"),
    ({"geometry": {"enclosure": "box"}, "mesh": {"engine": "axisymmetric"}}, "mesh.engine",
     "3d or auto with geometry.frame = square"),
    ({"geometry": {"frame": "circle", "enclosure": "cylinder"}, "mesh": {"engine": "3d"}},
     "mesh.engine", "axisymmetric or auto"),
    ({"air": {"outside": False, "enabled": True}}, "air.outside",
     "true with geometry.enclosure = none"),
    ({"geometry": BAFFLE, "air": {"outside": False}}, "air.outside",
     "true when air.enabled = false"),
    ({"geometry": {"frame": "none", "enclosure": "cylinder", "enclosure_vent_radius": "5 mm"},
      "air": {"outside": False, "enabled": True}},
     "geometry.enclosure_vent_radius", "0 with air.outside = false"),
    ({"geometry": {"frame": "none", "enclosure": "cylinder", "enclosure_depth": "100 mm"}},
     "air.domain_radius", "within 0.8 of the air sphere"),
    ({"geometry": {"frame": "circle", "frame_radius": "50 mm", "enclosure": "cylinder",
                   "enclosure_radius": "60 mm"}},
     "geometry.enclosure_radius", "<= 0.05 m = geometry.frame_radius"),
    ({"geometry": {"enclosure": "cylinder", "enclosure_radius": "40 mm"}},
     "geometry.enclosure_radius", "< 0.04 m = half geometry.frame_side"),
    ({"geometry": {"enclosure": "box", "enclosure_depth": "100 mm"}},
     "air.domain_radius", "farthest point"),
    ({"geometry": {**BAFFLE, "enclosure_depth": "nan"}}, "geometry.enclosure_depth", ""),
    ({"air": {"outside": "no thanks"}}, "air.outside", "true or false"),
]


@pytest.mark.parametrize("raw, key, fragment", BAD_ENCLOSURES,
                         ids=[b[1] + str(i) for i, b in enumerate(BAD_ENCLOSURES)])
def test_bad_enclosures_are_refused_naming_key_value_and_allowed(raw, key, fragment):
    with pytest.raises(StudyError) as caught:
        parse_study(raw)
    message = str(caught.value)
    assert message.startswith(key + " = ") and fragment in message, message
    assert "\n" not in message


def test_enclosure_defaults_follow_the_outer_radius_and_pick_the_engine():
    plain = parse_study({})
    assert plain["geometry"]["enclosure"] == "none" and plain["air"]["outside"] is True
    boxed = parse_study({"geometry": {"outer_radius": "20 mm", "inner_radius": 0,
                                      "frame": "none", "enclosure": "cylinder"}})
    g = boxed["geometry"]
    assert g["enclosure_depth"] == g["enclosure_radius"] == 0.02 and g["enclosure_vent_radius"] == 0
    assert engine_of(boxed) == "axisymmetric"
    for frame, enclosure, engine in (("baffle", "bowl", "axisymmetric"),
                                     ("circle", "cylinder", "axisymmetric"),
                                     ("square", "cylinder", "3d"), ("square", "box", "3d")):
        study = parse_study({"geometry": {"frame": frame, "enclosure": enclosure}})
        assert engine_of(study) == engine, (frame, enclosure)


def test_the_enclosure_may_reach_just_inside_its_share_of_the_air_sphere():
    r_o = 0.0355
    radius = 3.5 * r_o * ENCLOSURE_AIR_SHARE                      # the default air sphere
    depth = math.sqrt(radius ** 2 - r_o ** 2)
    ok = {"frame": "none", "enclosure": "cylinder", "enclosure_depth": 0.999 * depth}
    assert parse_study({"geometry": ok})["geometry"]["enclosure_depth"] == 0.999 * depth
    with pytest.raises(StudyError, match="air.domain_radius"):
        parse_study({"geometry": {**ok, "enclosure_depth": 1.001 * depth}})
    # with a baffle the enclosure replaces the lower half-space: no outside air around it
    assert parse_study({"geometry": {**BAFFLE, "enclosure_depth": 1.0}})
