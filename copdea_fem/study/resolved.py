"""A resolved study (:class:`Study`): read from YAML, overridden by ``--set SECTION.KEY=VALUE``
strings, validated key by key (:mod:`~copdea_fem.study.keys`) and then across keys
(:mod:`~copdea_fem.study.checks`), every default filled in, every value in SI -- all before
any meshing; written beside every result (:func:`dump_resolved`).
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml

from copdea_fem.folders import package_versions
from copdea_fem.inputs import parse_yaml, preview, read_yaml
from copdea_fem.study.checks import check_across_keys, derived_defaults
from copdea_fem.study.keys import StudyError, convert_value, refusal
from copdea_fem.study.schema import (
    AXISYMMETRIC_ENCLOSURES,
    AXISYMMETRIC_FRAMES,
    META_KEYS,
    SCHEMA,
)


class Study:
    """A validated study: nested ``{section: {key: SI value}}`` plus its name.

    Index like a dict: ``study["load"]["voltage"]`` [V].
    """

    def __init__(self, values: dict[str, dict[str, Any]], name: str, description: str = ""):
        self.values = values
        self.name = name
        self.description = description

    def __getitem__(self, section: str) -> dict[str, Any]:
        return self.values[section]

    def get(self, dotted: str) -> Any:
        section, key = dotted.split(".", 1)
        return self.values[section][key]

    def replace(self, overrides: dict[str, Any]) -> Study:
        """A new, re-validated study with ``{"section.key": value}`` overrides."""
        raw = copy.deepcopy(self.values)
        return parse_study(raw, overrides=overrides, name=self.name,
                           description=self.description)

    def checked(self) -> Study:
        """This study validated again, as a file would be: a study changed by hand after
        :func:`load_study` (``study["load"]["voltage"] = "2 kV"``, a key added, deleted or
        misspelled, a section replaced) comes back resolved to SI, or a :class:`StudyError`
        names the key.  Values already in SI are kept as they are."""
        if not isinstance(self.values, dict):
            raise refusal("study", self.values, "a mapping of sections")
        raw = {section: dict(keys) if isinstance(keys, dict) else keys
               for section, keys in self.values.items()}
        return parse_study(raw, name=self.name, description=self.description)

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, "description": self.description,
                **copy.deepcopy(self.values)}


#: What study overrides may be, for the messages.
OVERRIDES_ALLOWED = ('a mapping {"SECTION.KEY": value} (e.g. {"load.voltage": "1 kV"}) or a '
                     'list of "SECTION.KEY=VALUE" texts')


def parse_overrides(items: list[str] | None) -> dict[str, Any]:
    """``["load.voltage=3 kV", ...]`` -> ``{"load.voltage": "3 kV"}`` (YAML-typed values)."""
    overrides: dict[str, Any] = {}
    if items is not None and not isinstance(items, (list, tuple)):
        raise refusal("overrides", items, OVERRIDES_ALLOWED)
    for item in items or []:
        if not isinstance(item, str):
            raise refusal("overrides", item, OVERRIDES_ALLOWED)
        if "=" not in item:
            raise StudyError(f"--set {preview(item)} is not allowed; allowed: SECTION.KEY=VALUE, "
                             "e.g. --set load.voltage='3 kV'")
        key, text = item.split("=", 1)
        try:
            value = parse_yaml(text, f"--set {key.strip()}", StudyError)
        except StudyError:
            value = text
        overrides[key.strip()] = text if value is None and text.strip() else value
    return overrides


def load_study(path: str | Path, overrides: dict[str, Any] | None = None) -> Study:
    """Read, override, validate and resolve a study file."""
    path = Path(path)
    raw = read_yaml(path, "study file", StudyError)
    name = raw.get("name") or path.stem
    return parse_study(raw, overrides=overrides, name=str(name),
                       description=str(raw.get("description", "")))


def parse_study(raw: dict[str, Any], overrides: dict[str, Any] | None = None,
                name: str = "study", description: str = "") -> Study:
    """Validate a raw nested mapping (plus dotted overrides) into a :class:`Study`."""
    raw = copy.deepcopy(raw)
    for key in raw:
        if key not in SCHEMA and key not in META_KEYS:
            raise refusal(key, "...", "sections " + ", ".join(SCHEMA) + " (and name, description)",
                          "unknown section")
    if overrides is not None and not isinstance(overrides, dict):
        raise refusal("overrides", overrides, OVERRIDES_ALLOWED)
    for dotted, value in (overrides or {}).items():
        if not isinstance(dotted, str):
            raise refusal(f"overrides key {dotted!r}", value, OVERRIDES_ALLOWED)
        section, _, key = dotted.partition(".")
        if section not in SCHEMA or key not in SCHEMA[section]:
            raise _unknown_key(dotted, value)
        if not isinstance(raw.get(section) or {}, dict):
            raise refusal(section, raw[section], "a mapping of keys")
        raw.setdefault(section, {})
        raw[section] = raw[section] or {}
        raw[section][key] = value

    values: dict[str, dict[str, Any]] = {}
    for section, keys in SCHEMA.items():
        given = raw.get(section) or {}
        if not isinstance(given, dict):
            raise refusal(section, given, "a mapping of keys: " + ", ".join(keys))
        for key, value in given.items():
            if key not in keys:
                raise _unknown_key(f"{section}.{key}", value)
        values[section] = {key: convert_value(f"{section}.{key}", spec,
                                         given[key] if key in given else spec.default)
                           for key, spec in keys.items()}
    derived_defaults(values, name)
    check_across_keys(values)
    return Study(values, name=name, description=description)


def _unknown_key(dotted: str, value: Any) -> StudyError:
    section = dotted.partition(".")[0]
    known = SCHEMA.get(section)
    allowed = ("keys " + ", ".join(f"{section}.{k}" for k in known)) if known else (
        "sections " + ", ".join(SCHEMA))
    return refusal(dotted, value, allowed, "unknown key")


def engine_of(study) -> str:
    """The FE engine a study runs on: ``"axisymmetric"`` or ``"3d"`` (key mesh.engine).

    ``auto`` picks the axisymmetric engine for a frame none, baffle or circle with no
    enclosure, a cylinder or a bowl; else the 3-D engine.
    """
    engine = study["mesh"]["engine"]
    if engine == "auto":
        g = study["geometry"]
        axisymmetric = (g["frame"] in AXISYMMETRIC_FRAMES
                        and g.get("enclosure", "none") in AXISYMMETRIC_ENCLOSURES)
        return "axisymmetric" if axisymmetric else "3d"
    return engine


def dump_resolved(study: Study, path: str | Path) -> None:
    """Write the resolved study (SI, defaults filled in) plus package versions."""
    data = study.as_dict()
    data["provenance"] = package_versions()
    Path(path).write_text(yaml.safe_dump(data, sort_keys=False))
