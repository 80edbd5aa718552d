"""A resolved study (:class:`Study`): read from YAML, overridden by ``--set SECTION.KEY=VALUE``
strings, validated key by key (:mod:`~copdea_fem.study.keys`) and then across keys
(:mod:`~copdea_fem.study.checks`), every default filled in, every value in SI -- all before
any meshing; written beside every result (:func:`dump_resolved`).
"""

from __future__ import annotations

import copy
import dataclasses
import logging
import warnings
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import yaml

from copdea_fem.folders import package_versions
from copdea_fem.inputs import parse_yaml, preview, read_yaml
from copdea_fem.study.checks import check_across_keys, derived_defaults, enclosure_defaults
from copdea_fem.study.imperfections import is_imperfect, perturbation_refusal
from copdea_fem.study.keys import StudyError, convert_value, refusal
from copdea_fem.study.schema import (
    AXISYMMETRIC_ENCLOSURES,
    AXISYMMETRIC_FRAMES,
    META_KEYS,
    OPTIONAL_KEYS,
    OPTIONAL_SECTIONS,
    SCHEMA,
)
from copdea_fem.study.sections import SECTION_CLASSES, plain_section, typed_section

logger = logging.getLogger(__name__)

if TYPE_CHECKING:
    from copdea_fem.study.sections import (
        AirSection,
        DiscSection,
        EffectsSection,
        ElectrodesSection,
        EigenSection,
        ExcitationSection,
        GeometrySection,
        ImperfectionsSection,
        LoadSection,
        MembraneSection,
        MeshSection,
        OutputSection,
        PrestressSection,
        ReducedSection,
        ResponseSection,
        SpringSection,
    )


def _with_sections(cls):
    """Class decorator: ``cls`` with one field per :data:`SCHEMA` section first (its
    :data:`~copdea_fem.study.sections.SECTION_CLASSES` instance, None until checked), then
    its own fields, as a frozen dataclass."""
    own = dict(cls.__dict__.get("__annotations__", {}))
    cls.__annotations__ = {**{section: SECTION_CLASSES[section] for section in SCHEMA}, **own}
    for section in SCHEMA:
        setattr(cls, section, dataclasses.field(default=None, repr=False))
    return dataclasses.dataclass(frozen=True)(cls)


@_with_sections
class Study:
    """A validated study: one frozen section per :data:`SCHEMA` section, every value in SI.

    Read attributes: ``study.load.voltage`` [V], ``study.geometry.enclosure``; each section
    is a frozen dataclass generated from the schema (:mod:`copdea_fem.study.sections`).  A
    study is checked where it is made (:func:`load_study`, :func:`parse_study`, or this
    constructor) and cannot change afterwards: make a changed copy with
    :meth:`replace` (``{"section.key": value}``, values with units as in a file) or
    :func:`dataclasses.replace`, typed::

        dataclasses.replace(study, load=dataclasses.replace(study.load, voltage=2e3))

    Both check the new study as a file is checked: every key (a value with a unit is
    converted to SI, one out of range refused), the derived defaults of keys given as None,
    and the checks across keys (:func:`~copdea_fem.study.checks.check_across_keys`); both
    keep ``source``.  Derived defaults already filled in stay as they are (a new
    ``geometry.outer_radius`` does not move ``air.domain_radius``).

    Parameters
    ----------
    geometry, membrane, ... : section dataclass, mapping or None
        One per :data:`SCHEMA` section: its dataclass, or a mapping ``{key: value}`` (values
        with units allowed, missing keys take their default), or None (every default).
    name : str
        The study's name (the file's ``name``, else the file name without suffix).
    description : str
        Free text.
    source : Path or None
        The file the study was read from; None when parsed from a mapping.  Not compared.

    Raises
    ------
    StudyError
        A section that is no mapping, an unknown key, a value out of range or in a wrong
        unit, keys that do not fit together.
    """

    if TYPE_CHECKING:      # the fields _with_sections adds, one per SCHEMA section
        geometry: GeometrySection
        membrane: MembraneSection
        disc: DiscSection
        spring: SpringSection
        load: LoadSection
        air: AirSection
        mesh: MeshSection
        prestress: PrestressSection
        eigen: EigenSection
        output: OutputSection
        reduced: ReducedSection
        excitation: ExcitationSection
        response: ResponseSection
        effects: EffectsSection
        electrodes: ElectrodesSection
        imperfections: ImperfectionsSection

    name: str = "study"
    description: str = ""
    source: Path | None = dataclasses.field(default=None, compare=False)

    def __post_init__(self):
        values: dict[str, dict[str, Any]] = {}
        for section, keys in SCHEMA.items():
            given = getattr(self, section)
            if given is None:
                given = {}
            elif isinstance(given, SECTION_CLASSES[section]):
                given = plain_section(given)
            elif not isinstance(given, Mapping):
                raise refusal(section, given, "a mapping of keys: " + ", ".join(keys))
            for key, value in given.items():
                if key not in keys:
                    raise _unknown_key(f"{section}.{key}", value)
            values[section] = {key: convert_value(f"{section}.{key}", spec,
                                                  given[key] if key in given else spec.default)
                               for key, spec in keys.items()}
        if not isinstance(self.name, str):
            raise refusal("name", self.name, "a text")
        if not isinstance(self.description, str):
            raise refusal("description", self.description, "a text")
        derived_defaults(values, self.name)
        check_across_keys(values)
        for section in SCHEMA:
            object.__setattr__(self, section, typed_section(section, values[section]))
        if self.source is not None:
            object.__setattr__(self, "source", Path(self.source))

    @property
    def values(self) -> dict[str, dict[str, Any]]:
        """The sections as plain mappings ``{section: {key: SI value}}`` (a copy; the form
        the resolved study file writes and the cache keys hash; an optional section,
        :data:`~copdea_fem.study.schema.OPTIONAL_SECTIONS`, only when a key differs from
        its default; an optional key, :data:`~copdea_fem.study.schema.OPTIONAL_KEYS`, only
        when it differs from its default)."""
        values = {section: plain_section(getattr(self, section)) for section in SCHEMA}
        for section in OPTIONAL_SECTIONS:      # written only when not all at the default
            if all(value == SCHEMA[section][key].default
                   for key, value in values[section].items()):
                del values[section]
        for section, keys in OPTIONAL_KEYS.items():     # each only when not at its default
            for key in keys:
                if values[section][key] == SCHEMA[section][key].default:
                    del values[section][key]
        return values

    def __getitem__(self, section: str) -> Mapping[str, Any]:
        """``study["load"]``: a read-only mapping of the section (deprecated: read
        ``study.load``)."""
        warnings.warn(f"study[{section!r}] is deprecated; read the attribute study.{section}",
                      DeprecationWarning, stacklevel=2)
        if section not in SCHEMA:
            raise KeyError(section)
        return MappingProxyType(plain_section(getattr(self, section)))

    def get(self, dotted: str) -> Any:
        """The value of the key ``"section.key"`` (a key named at run time; a fixed key is
        an attribute: ``study.load.voltage``)."""
        section, _, key = dotted.partition(".")
        if section not in SCHEMA or key not in SCHEMA[section]:
            raise _unknown_key(dotted, "...")
        return getattr(getattr(self, section), key)

    def replace(self, overrides: dict[str, Any], name: str | None = None) -> Study:
        """A new study with ``{"section.key": value}`` overrides (values with units
        allowed), checked as a file is; ``description`` and ``source`` kept, ``name`` too
        unless a new one is given."""
        return parse_study(self.values, overrides=overrides,
                           name=self.name if name is None else name,
                           description=self.description, source=self.source)

    def checked(self) -> Study:
        """This study (deprecated: a study is checked when it is made and cannot change)."""
        warnings.warn("Study.checked() is deprecated: a Study is checked when it is made and "
                      "cannot be changed", DeprecationWarning, stacklevel=2)
        return self

    def as_dict(self) -> dict[str, Any]:
        """``{"name", "description", section: {key: SI value}, ...}``: what
        :func:`dump_resolved` writes, in its order."""
        return {"name": self.name, "description": self.description, **self.values}


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
    study = parse_study(raw, overrides=overrides, name=str(name),
                        description=str(raw.get("description", "")), source=path)
    given = set(raw.get("geometry") or {}) if isinstance(raw.get("geometry"), dict) else set()
    given |= {dotted.partition(".")[2] for dotted in (overrides or {})
              if dotted.startswith("geometry.")}
    for warning in unused_enclosure_keys(study, given):
        logger.warning(warning)
    return study


#: The keys that shape an enclosure (docs/enclosures.md).
ENCLOSURE_KEYS = ("enclosure_depth", "enclosure_radius", "enclosure_vent_radius")


def unused_enclosure_keys(study: Study, given) -> list[str]:
    """Warnings for enclosure keys that change nothing (the file's and the overrides'
    ``geometry`` keys ``given``): a depth, radius or vent without an enclosure, a radius on
    a box (whose sides are the square frame's), an enclosure without air (it acts through
    the air it traps).  Said when a file is read, not for each study made from it."""
    g = study.geometry
    warnings_ = []
    # a key at its default (a resolved study written by a run lists them all) says nothing
    given = {key for key, default in enclosure_defaults(g).items()
             if key in given and getattr(g, key) != default} | (set(given) - set(ENCLOSURE_KEYS))
    if g.enclosure == "none":
        warnings_ += [f"geometry.{key} is ignored: geometry.enclosure = none"
                      for key in ENCLOSURE_KEYS if key in given]
    elif g.enclosure == "box" and "enclosure_radius" in given:
        warnings_.append("geometry.enclosure_radius is ignored with geometry.enclosure = box "
                         "(its sides are geometry.frame_side)")
    if g.enclosure != "none" and not study.air.enabled:
        warnings_.append(f"geometry.enclosure = {g.enclosure} changes nothing with air.enabled "
                         "= false (an enclosure acts through the air it traps)")
    return warnings_


def parse_study(raw: dict[str, Any], overrides: dict[str, Any] | None = None,
                name: str = "study", description: str = "",
                source: str | Path | None = None) -> Study:
    """Validate a raw nested mapping (plus dotted overrides) into a :class:`Study`
    (``source``: the file it was read from, if any)."""
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

    sections = {section: raw.get(section) or {} for section in SCHEMA}
    return Study(**sections, name=name, description=description, source=source)


def _unknown_key(dotted: str, value: Any) -> StudyError:
    section = dotted.partition(".")[0]
    known = SCHEMA.get(section)
    allowed = ("keys " + ", ".join(f"{section}.{k}" for k in known)) if known else (
        "sections " + ", ".join(SCHEMA))
    return refusal(dotted, value, allowed, "unknown key")


def engine_of(study: Study, forced_response: bool = False) -> str:
    """The FE engine a study runs on: ``"axisymmetric"`` or ``"3d"`` (key mesh.engine).

    ``auto`` picks the axisymmetric engine for a device with a frame none, baffle or circle
    and no enclosure, a cylinder or a bowl that is perfect (no key of
    :data:`~copdea_fem.study.imperfections.IMPERFECTION_KEYS` set) or whose imperfection
    its first-order perturbation path takes
    (:func:`~copdea_fem.study.imperfections.perturbation_refusal` allows it: dry or in
    air, within its range) where the caller asks for modes only; else the 3-D engine.
    ``forced_response``: the caller drives the device (response, excite, synthetic
    scans), which the perturbation path does not make: an imperfect device then keeps the
    3-D engine.  ``axisymmetric`` and ``3d`` are taken as given (the study's checks refuse
    an imperfection beyond the perturbation path on ``axisymmetric``).
    """
    engine = study.mesh.engine
    if engine == "auto":
        g = study.geometry
        round_device = (g.frame in AXISYMMETRIC_FRAMES
                        and g.enclosure in AXISYMMETRIC_ENCLOSURES)
        if round_device and is_imperfect(study.membrane, study.imperfections):
            round_device = not forced_response and perturbation_refusal(
                study.membrane, study.imperfections, study.geometry) is None
        return "axisymmetric" if round_device else "3d"
    return engine


def dump_resolved(study: Study, path: str | Path) -> None:
    """Write the resolved study (SI, defaults filled in) plus package versions."""
    data = study.as_dict()
    data["provenance"] = package_versions()
    Path(path).write_text(yaml.safe_dump(data, sort_keys=False))
