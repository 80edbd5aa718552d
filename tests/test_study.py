"""Study files: units, defaults, bounds, and the messages of bad input."""

from pathlib import Path

import pytest
import yaml

from copdea_fem.study import (
    SCHEMA,
    StudyError,
    load_study,
    parse_overrides,
    parse_study,
    reference_table,
)

ROOT = Path(__file__).resolve().parent.parent


def test_units_are_converted_to_si():
    study = parse_study({"geometry": {"outer_radius": "35.5 mm", "inner_radius": 0.012},
                         "load": {"voltage": "2 kV", "z": "1.6 cm"},
                         "membrane": {"c10": "228.5 kPa", "thickness": "100 um",
                                      "density": "1.49 g/cm^3"},
                         "disc": {"mass": "1.9 g"}})
    assert study["geometry"]["outer_radius"] == pytest.approx(0.0355)
    assert study["geometry"]["inner_radius"] == 0.012
    assert study["load"]["voltage"] == pytest.approx(2000.0)
    assert study["load"]["z"] == pytest.approx(0.016)
    assert study["membrane"]["c10"] == pytest.approx(228.5e3)
    assert study["membrane"]["thickness"] == pytest.approx(100e-6)
    assert study["membrane"]["density"] == pytest.approx(1490.0)
    assert study["disc"]["mass"] == pytest.approx(1.9e-3)


def test_defaults_are_table_1_and_derived_defaults_follow_r_o():
    study = parse_study({"geometry": {"outer_radius": "40 mm", "inner_radius": "10 mm",
                                       "frame": "none"}})
    assert study["membrane"]["prestretch"] == 1.2
    assert study["air"]["domain_radius"] == pytest.approx(3.5 * 0.040)
    assert study["air"]["pml_thickness"] == pytest.approx(0.5 * 0.040)
    assert study["output"]["directory"] == "results/study"


def test_overrides_are_yaml_typed_and_validated():
    overrides = parse_overrides(["load.voltage=3 kV", "air.enabled=false", "mesh.order=2"])
    assert overrides == {"load.voltage": "3 kV", "air.enabled": False, "mesh.order": 2}
    study = parse_study({}, overrides=overrides)
    assert study["load"]["voltage"] == 3000.0 and study["mesh"]["order"] == 2


def test_resolved_study_round_trips(tmp_path):
    from copdea_fem.study import dump_resolved
    study = parse_study({"load": {"z": "16 mm", "voltage": "2 kV"}}, name="x")
    dump_resolved(study, tmp_path / "s.yaml")
    data = yaml.safe_load((tmp_path / "s.yaml").read_text())
    assert "ngsolve" in data["provenance"]
    again = load_study(tmp_path / "s.yaml")
    assert again.values == study.values


BAD = [
    ({"geometry": {"inner_radius": "40 mm"}}, "geometry.inner_radius", "below geometry.outer_radius"),
    ({"geometry": {"inner_radius": "35.5 mm"}}, "geometry.inner_radius", "[0, 0.0355)"),
    ({"geometry": {"outer_radius": "-3 mm"}}, "geometry.outer_radius", "(0, 1] m"),
    ({"membrane": {"prestretch": 1.0}}, "membrane.prestretch", "(1, 10]"),
    ({"membrane": {"prestretch": 0.9}}, "membrane.prestretch", "(1, 10]"),
    ({"membrane": {"thickness": 0}}, "membrane.thickness", "(0, 0.01] m"),
    ({"membrane": {"density": "-1490 kg/m^3"}}, "membrane.density", "(0, 100000] kg/m^3"),
    ({"load": {"voltage": "2 mm"}}, "load.voltage", "wrong unit, expected a quantity in V"),
    ({"load": {"voltage": "two kilovolts"}}, "load.voltage", "cannot read it as a quantity"),
    ({"load": {"voltage": [1, 2]}}, "load.voltage", "expected a number"),
    ({"geometry": {"frame_side": "60 mm"}}, "geometry.frame_side", "the membrane diameter"),
    ({"geometry": {"frame": "round"}}, "geometry.frame", "one of square, baffle, none"),
    ({"disc": {"motion": "free"}}, "disc.motion", "one of held, spring"),
    ({"membrane": {"thick": "1 mm"}}, "membrane.thick", "unknown key"),
    ({"meshes": {"order": 2}}, "meshes", "unknown section"),
    ({"mesh": {"order": 2.5}}, "mesh.order", "an integer"),
    ({"air": {"enabled": "yes please"}}, "air.enabled", "true or false"),
    ({"eigen": {"f_min": "500 Hz", "f_max": "400 Hz"}}, "eigen.f_max", "> eigen.f_min"),
    ({"geometry": {"inner_radius": 0}, "load": {"z": "5 mm"}}, "load.z",
     "a full membrane has no disc"),
    ({"geometry": {"inner_radius": 0}, "disc": {"motion": "spring"}}, "disc.motion",
     "held when geometry.inner_radius = 0"),
    ({"air": {"domain_radius": "50 mm"}}, "air.domain_radius", "corners must lie inside"),
    ({"load": {"z": "80 mm"}}, "load.z", "2 * (r_o - r_i)"),
    ({"mesh": {"membrane_size": "15 mm"}}, "mesh.membrane_size", "half the membrane width"),
    ({"membrane": {"c10": "nan"}}, "membrane.c10", ""),
    ({"eigen": {"backend": "mumps"}}, "eigen.backend", "umfpack, pardiso, superlu"),
    ({"mesh": {"symmetry": "half"}}, "mesh.symmetry", "quarter, none"),
    ({"eigen": {"max_damping_ratio": 0}}, "eigen.max_damping_ratio", "(0, 1]"),
]


@pytest.mark.parametrize("raw, key, fragment", BAD, ids=[b[1] + str(i) for i, b in enumerate(BAD)])
def test_bad_input_names_key_value_and_allowed(raw, key, fragment):
    with pytest.raises(StudyError) as caught:
        parse_study(raw)
    message = str(caught.value)
    assert message.startswith(key + " = "), message
    assert "allowed" in message and fragment in message, message


def test_bad_override_syntax_and_key():
    with pytest.raises(StudyError, match=r"--set 'load.voltage' is not allowed; allowed: SECTION.KEY=VALUE"):
        parse_overrides(["load.voltage"])
    with pytest.raises(StudyError, match=r"load.volts = 3 is not allowed \(unknown key\); allowed: keys load.z, load.voltage"):
        parse_study({}, overrides={"load.volts": 3})


def test_bad_files(tmp_path):
    with pytest.raises(StudyError, match="does not exist"):
        load_study(tmp_path / "missing.yaml")
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(StudyError, match="must hold a mapping"):
        load_study(tmp_path / "list.yaml")
    (tmp_path / "broken.yaml").write_text("load: {z: [\n")
    with pytest.raises(StudyError, match="not valid YAML"):
        load_study(tmp_path / "broken.yaml")


def test_every_key_has_unit_default_and_description():
    for section, keys in SCHEMA.items():
        for name, key in keys.items():
            assert key.description, f"{section}.{name}"
            assert key.default is not None or key.derived, f"{section}.{name}"


def test_readme_table_is_generated_from_the_schema():
    readme = (ROOT / "README.md").read_text()
    assert reference_table() in readme, "README study table is stale: run python -m copdea_fem.study"


@pytest.mark.parametrize("path", sorted((ROOT / "studies").glob("*.yaml")), ids=lambda p: p.name)
def test_bundled_studies_are_valid(path):
    study = load_study(path)
    assert study.name == path.stem and study.description     # results go to results/<name>
