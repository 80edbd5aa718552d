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

ROOT = Path(__file__).resolve().parents[2]


def test_units_are_converted_to_si():
    study = parse_study({"geometry": {"outer_radius": "35.5 mm", "inner_radius": 0.012},
                         "load": {"voltage": "2 kV", "z": "1.6 cm"},
                         "membrane": {"c10": "228.5 kPa", "thickness": "100 um",
                                      "density": "1.49 g/cm^3"},
                         "disc": {"mass": "1.9 g"}})
    assert study.geometry.outer_radius == pytest.approx(0.0355)
    assert study.geometry.inner_radius == 0.012
    assert study.load.voltage == pytest.approx(2000.0)
    assert study.load.z == pytest.approx(0.016)
    assert study.membrane.c10 == pytest.approx(228.5e3)
    assert study.membrane.thickness == pytest.approx(100e-6)
    assert study.membrane.density == pytest.approx(1490.0)
    assert study.disc.mass == pytest.approx(1.9e-3)


def test_defaults_are_table_1_and_derived_defaults_follow_r_o():
    study = parse_study({"geometry": {"outer_radius": "40 mm", "inner_radius": "10 mm",
                                       "frame": "none"}})
    assert study.membrane.prestretch == 1.2
    assert study.air.domain_radius == pytest.approx(3.5 * 0.040)
    assert study.air.pml_thickness == pytest.approx(0.5 * 0.040)
    assert study.output.directory == "results/study"


def test_overrides_are_yaml_typed_and_validated():
    overrides = parse_overrides(["load.voltage=3 kV", "air.enabled=false", "mesh.order=2"])
    assert overrides == {"load.voltage": "3 kV", "air.enabled": False, "mesh.order": 2}
    study = parse_study({}, overrides=overrides)
    assert study.load.voltage == 3000.0 and study.mesh.order == 2


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


# ------------------------------------------------------------------ the typed, frozen study

def test_sections_are_typed_dataclasses_generated_from_the_schema():
    import dataclasses

    from copdea_fem.study import SECTION_CLASSES, PronyTerm
    study = load_study(ROOT / "studies" / "g1_z16_v2.yaml")
    assert [f.name for f in dataclasses.fields(study)][:len(SCHEMA)] == list(SCHEMA)
    for section, keys in SCHEMA.items():
        values = getattr(study, section)
        assert type(values) is SECTION_CLASSES[section]
        assert type(values).__name__ == section.capitalize() + "Section"
        assert [f.name for f in dataclasses.fields(values)] == list(keys)
        for key, spec in keys.items():
            assert key in type(values).__doc__ and spec.description in type(values).__doc__
    assert study.load.voltage == 2000.0 and study.load.z == pytest.approx(0.016)
    assert isinstance(study.mesh.order, int) and study.geometry.enclosure == "none"
    assert study.membrane.prony == ()
    assert study.source == ROOT / "studies" / "g1_z16_v2.yaml"
    assert parse_study({}).source is None
    prony = parse_study({"membrane": {"prony": [{"modulus_ratio": 0.5,
                                                 "relaxation_time": "1 ms"}]}}).membrane.prony
    assert prony == (PronyTerm(0.5, 1e-3),)


def test_a_study_cannot_be_changed_by_hand():
    import dataclasses
    study = load_study(ROOT / "studies" / "g1_z16_v2.yaml")
    with pytest.raises(dataclasses.FrozenInstanceError):
        study.load.voltage = 5.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        study.load = None
    with pytest.warns(DeprecationWarning, match=r"study\['load'\] is deprecated"):
        section = study["load"]
    assert section == {"z": study.load.z, "voltage": study.load.voltage}
    with pytest.raises(TypeError, match="does not support item assignment"):
        section["voltage"] = 5.0
    with pytest.raises(TypeError):
        study["load"] = {}
    values = study.values
    values["load"]["voltage"] = 5.0               # a copy
    assert study.load.voltage == 2000.0


def test_a_changed_copy_is_checked_as_a_file_is():
    """``Study.replace`` (unit strings) and ``dataclasses.replace`` (typed) both check every
    key and the keys across, keep ``source``, and leave the original as it was."""
    import dataclasses
    study = load_study(ROOT / "studies" / "g1_z16_v2.yaml")
    typed = dataclasses.replace(study, load=dataclasses.replace(study.load, voltage=1000))
    assert typed.load.voltage == 1000.0 and isinstance(typed.load.voltage, float)
    assert typed.source == study.source and study.load.voltage == 2000.0
    assert typed == study.replace({"load.voltage": "1 kV"})
    assert dataclasses.replace(study, load={"voltage": "3 kV"}).load.voltage == 3000.0
    with pytest.raises(StudyError, match=r"^load.voltage = -1 is not allowed"):
        dataclasses.replace(study, load=dataclasses.replace(study.load, voltage=-1))
    with pytest.raises(StudyError, match=r"^load.z = 0.08 is not allowed .*2 \* \(r_o - r_i\)"):
        dataclasses.replace(study, load=dataclasses.replace(study.load, z=0.08))   # across keys
    with pytest.raises(StudyError, match=r"^load = 5 is not allowed; allowed: a mapping"):
        dataclasses.replace(study, load=5)
    with pytest.raises(StudyError, match=r"^load.volts = 3 is not allowed \(unknown key\)"):
        dataclasses.replace(study, load={"volts": 3})
    assert study.replace({"load.voltage": "1 kV"}).source == study.source


def test_a_study_and_its_sections_pickle_and_hash():
    import pickle
    study = parse_study({"membrane": {"prony": [{"modulus_ratio": 0.5,
                                                 "relaxation_time": 1e-3}]}}, name="p")
    again = pickle.loads(pickle.dumps(study))
    assert again == study and again.values == study.values and again.name == "p"
    assert type(again.membrane) is type(study.membrane)
    assert hash(again) == hash(study)
    assert {study: 1}[again] == 1


def test_a_study_crosses_a_process_boundary():
    """Sweeps, Dask and the diagnosis's workers send studies to other processes."""
    import concurrent.futures
    import multiprocessing

    study = load_study(ROOT / "studies" / "g1_z16_v2.yaml")
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=context) as pool:
        assert pool.submit(_voltage_of, study).result() == 2000.0


def _voltage_of(study):
    return study.load.voltage


def test_as_dict_writes_the_resolved_study_in_schema_order(tmp_path):
    from copdea_fem.study import dump_resolved
    study = parse_study({"membrane": {"prony": [{"modulus_ratio": 0.5,
                                                 "relaxation_time": 1e-3}]}}, name="x")
    data = study.as_dict()
    from copdea_fem.study import OPTIONAL_KEYS, OPTIONAL_SECTIONS
    written = [section for section in SCHEMA if section not in OPTIONAL_SECTIONS]
    assert list(data) == ["name", "description", *written]     # optional ones at default left out
    assert all(list(data[section]) == [key for key in SCHEMA[section]
                                       if key not in OPTIONAL_KEYS.get(section, ())]
               for section in written)
    assert data["membrane"]["prony"] == [{"modulus_ratio": 0.5, "relaxation_time": 1e-3}]
    dump_resolved(study, tmp_path / "s.yaml")
    assert load_study(tmp_path / "s.yaml") == study


def test_the_enclosure_is_a_string_with_a_typed_shape():
    """``geometry.enclosure`` stays the key's text (``"none"`` included, as the resolved
    study writes it); ``enclosure_shape`` is None for an open back, else typed."""
    from copdea_fem.study import Enclosure
    assert parse_study({}).geometry.enclosure_shape is None
    closed = parse_study({"geometry": {"frame": "baffle", "enclosure": "cylinder",
                                       "enclosure_depth": "20 mm"}})
    assert closed.geometry.enclosure_shape == Enclosure("cylinder", 0.02, 0.0355, 0.0)


#: How a study was read by key before it was typed: ``study["load"]``,
#: ``self.study['eigen']``, ``study.get("load.voltage")``, ``base["air"]["enabled"]``.
_DICT_READS = (r"study\[", r"study\.get\(\s*[\"'][a-z_]+\.[a-z_]+[\"']\s*\)",
               r"(?<![\]\w])\w+\[[\"'](" + "|".join(SCHEMA) + r")[\"']\]\[[\"']\w+[\"']\]")


def test_the_package_reads_the_study_by_attribute():
    """Outside the study package (whose loader reads the raw mapping), a study is read by
    attribute: ``study.load.voltage``, ``study.get(key)`` only for a key named at run time."""
    import re
    package = ROOT / "copdea_fem"
    found = []
    for path in sorted(package.rglob("*.py")):
        if path.parent.name == "study":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if any(re.search(pattern, line) for pattern in _DICT_READS):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "read the study's attributes (study.load.voltage):\n" + "\n".join(found)


def test_the_sections_stub_is_made_from_the_schema():
    """Type checkers read ``sections.pyi`` (the classes are generated at run time): it is
    the text :func:`stub_text` makes from ``SCHEMA`` now, it parses, and ``Study`` declares
    for them one field per section (``if TYPE_CHECKING`` in resolved.py)."""
    import ast
    import re

    from copdea_fem.study import sections
    stub = Path(sections.__file__).with_name("sections.pyi")
    assert stub.read_text() == sections.stub_text(), \
        "sections.pyi is stale: python -m copdea_fem.study --stubs"
    tree = ast.parse(stub.read_text())
    classes = {node.name for node in tree.body if isinstance(node, ast.ClassDef)}
    assert {cls.__name__ for cls in sections.SECTION_CLASSES.values()} <= classes
    source = (Path(sections.__file__).with_name("resolved.py")).read_text()
    declared = re.findall(r"^        (\w+): (\w+)Section$", source, re.MULTILINE)
    assert [name for name, _ in declared] == list(SCHEMA)
    assert all(cls == name.capitalize() for name, cls in declared)
