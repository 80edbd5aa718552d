"""The study file: its typed schema, its values in SI, its checks, the resolved study.

A study is read from YAML, overridden by ``--set SECTION.KEY=VALUE`` strings,
validated key by key and then across keys, and resolved to SI numbers with
every default filled in -- all before any meshing.  Physical values accept a
unit string (``"35.5 mm"``, ``"2 kV"``, ``"228.5 kPa"``) or a plain SI number.

The modules, in the order a study is read: :mod:`~copdea_fem.study.keys` (one key: its
type, its value converted to SI and checked, :class:`StudyError`),
:mod:`~copdea_fem.study.schema` (every key of every section, :data:`SCHEMA`),
:mod:`~copdea_fem.study.checks` (the checks across keys),
:mod:`~copdea_fem.study.sections` (the typed sections, frozen dataclasses generated from
:data:`SCHEMA`) and :mod:`~copdea_fem.study.resolved` (:class:`Study`, :func:`load_study`,
:func:`parse_study`).  Their public names are imported from here.

Run ``python -m copdea_fem.study`` to print the reference table of the README.
"""

from copdea_fem.study.checks import (
    DEFAULT_MICROPHONE,
    MICROPHONES_ALLOWED,
    listed_microphones,
    reduced_mode_labels,
)
from copdea_fem.study.keys import (
    MAX_PRONY_TERMS,
    MAX_QUANTITY_CHARACTERS,
    PRONY_ALLOWED,
    ROUND_OFF_ULPS,
    Key,
    StudyError,
    above,
    apart,
    convert_quantity,
    convert_value,
    unit_registry,
)
from copdea_fem.study.resolved import (
    OVERRIDES_ALLOWED,
    Study,
    dump_resolved,
    engine_of,
    load_study,
    parse_overrides,
    parse_study,
)
from copdea_fem.study.schema import (
    AXISYMMETRIC_ENCLOSURES,
    AXISYMMETRIC_FRAMES,
    ENCLOSURE_AIR_SHARE,
    ENCLOSURE_MIN_DEPTH,
    ENCLOSURE_MIN_GAP,
    ENCLOSURES,
    ENGINES,
    G1,
    MAX_ELEMENTS_ACROSS,
    META_KEYS,
    OPTIONAL_KEYS,
    OPTIONAL_SECTIONS,
    SCHEMA,
    reference_table,
)
from copdea_fem.study.sections import (
    SECTION_CLASSES,
    ElectrodeSegment,
    Enclosure,
    PointMass,
    PronyTerm,
    SegmentDrive,
    ThicknessTerm,
)

__all__ = ["AXISYMMETRIC_ENCLOSURES", "AXISYMMETRIC_FRAMES", "DEFAULT_MICROPHONE", "ENCLOSURES",
           "ENCLOSURE_AIR_SHARE", "ENCLOSURE_MIN_DEPTH", "ENCLOSURE_MIN_GAP", "ENGINES", "G1",
           "MAX_ELEMENTS_ACROSS", "MAX_PRONY_TERMS", "MAX_QUANTITY_CHARACTERS", "META_KEYS",
           "MICROPHONES_ALLOWED", "OVERRIDES_ALLOWED", "PRONY_ALLOWED", "ROUND_OFF_ULPS",
           "OPTIONAL_KEYS", "OPTIONAL_SECTIONS", "SCHEMA", "SECTION_CLASSES", "ElectrodeSegment", "Enclosure",
           "Key", "PointMass", "PronyTerm", "SegmentDrive", "Study", "StudyError", "ThicknessTerm",
           "above", "apart", "convert_quantity", "convert_value", "dump_resolved", "engine_of",
           "listed_microphones", "load_study", "parse_overrides", "parse_study",
           "reduced_mode_labels", "reference_table", "unit_registry"]
