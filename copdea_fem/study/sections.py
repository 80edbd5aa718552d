"""The typed sections of a study: one frozen dataclass per section of :data:`SCHEMA`,
generated from it, so the schema stays the one source of keys, units, defaults and docs.

``study.load`` is a :class:`LoadSection` (``study.load.voltage`` [V]), ``study.geometry`` a
:class:`GeometrySection`, and so on: the class of section ``name`` is
``name.capitalize() + "Section"`` (:data:`SECTION_CLASSES`).  Each field holds the key's
value in SI, its type the key's kind (``float``, ``int``, ``str``, ``bool``; ``None`` where
the key has no default and none was given, e.g. ``reduced.modes_json``), except the list
key ``membrane.prony``: a tuple of :class:`PronyTerm`, ``electrodes.segments``: a tuple
of :class:`ElectrodeSegment`, ``membrane.thickness_variation``: a tuple of
:class:`ThicknessTerm` and ``imperfections.point_masses``: a tuple of :class:`PointMass`.  A section alone is not checked; a
:class:`~copdea_fem.study.resolved.Study` checks its sections when it is made.

The classes are module-level names of this module, so sections (and studies) pickle for
worker processes.  Type checkers and editors cannot run the generation: they read the stub
``sections.pyi`` beside this file, made from the same schema by :func:`stub_text` (a test
holds it to the schema; remake it with ``python -m copdea_fem.study --stubs``).  :func:`plain_section` and :func:`typed_section` turn a section into the
plain mapping the resolved study file writes (``membrane.prony`` a list of mappings) and
back.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Optional

from copdea_fem.study.schema import SCHEMA


@dataclasses.dataclass(frozen=True)
class PronyTerm:
    """One term of the generalised Maxwell (Prony) series ``membrane.prony``.

    Attributes
    ----------
    modulus_ratio : float
        g_j, the term's modulus over the long-term modulus of eq. (20) [-].
    relaxation_time : float
        tau_j [s].
    """

    modulus_ratio: float
    relaxation_time: float


@dataclasses.dataclass(frozen=True)
class Enclosure:
    """The rigid closed back under the membrane (``geometry.enclosure*``), typed.

    Attributes
    ----------
    kind : str
        ``"cylinder"``, ``"bowl"`` or ``"box"``.
    depth : float
        Depth L below the membrane plane [m] (a bowl's at its centre).
    radius : float
        Radius of the cylinder, or of the bowl's rim [m] (a box's side is
        ``geometry.frame_side``).
    vent_radius : float
        Radius of the vent in its bottom [m]; 0 = sealed.
    """

    kind: str
    depth: float
    radius: float
    vent_radius: float


@dataclasses.dataclass(frozen=True)
class SegmentDrive:
    """The AC drive of an electrode segment (``electrodes.segments[k].drive``).

    Attributes
    ----------
    amplitude : float
        AC volts on the segment per volt of the input [V/V].
    phase : float
        Phase of the segment's AC voltage [deg] (its complex drive
        ``amplitude e^{i phase}``).
    """

    amplitude: float = 1.0
    phase: float = 0.0


@dataclasses.dataclass(frozen=True)
class ElectrodeSegment:
    """One segment of ``electrodes.segments`` (:mod:`copdea_fem.study.segments`).

    Attributes
    ----------
    name : str
        The segment's name (modal_forcing.csv's ``segment``).
    theta : tuple of float
        ``(from, to)`` [deg], counter-clockwise from the x axis (wrapping through 0 where
        ``to < from``).
    r : tuple of float or None
        ``(from, to)`` [m] on the flat pre-stretched membrane; None = the whole annulus.
    drive : SegmentDrive
        Its AC drive.
    """

    name: str
    theta: tuple
    r: tuple | None = None
    drive: SegmentDrive = SegmentDrive()

    def __post_init__(self):
        object.__setattr__(self, "theta", tuple(self.theta))
        if self.r is not None:
            object.__setattr__(self, "r", tuple(self.r))
        if isinstance(self.drive, dict):
            object.__setattr__(self, "drive", SegmentDrive(**self.drive))

    def plain(self) -> dict[str, Any]:
        """The plain mapping of the resolved study file (lists, a drive mapping)."""
        return {"name": self.name, "theta": list(self.theta),
                "r": None if self.r is None else list(self.r),
                "drive": {"amplitude": self.drive.amplitude, "phase": self.drive.phase}}


@dataclasses.dataclass(frozen=True)
class ThicknessTerm:
    """One term of ``membrane.thickness_variation`` (:mod:`copdea_fem.study.imperfections`):
    the film's thickness ``h0 (1 + amplitude cos order (theta - angle))``.

    Attributes
    ----------
    order : int
        Circumferential order k >= 1 [-].
    amplitude : float
        Relative amplitude a, |a| < 1 [-].
    angle : float
        Angle of the thickest line [deg], counter-clockwise from the x axis.
    """

    order: int
    amplitude: float
    angle: float = 0.0

    def plain(self) -> dict[str, Any]:
        """The plain mapping of the resolved study file."""
        return {"order": self.order, "amplitude": self.amplitude, "angle": self.angle}


@dataclasses.dataclass(frozen=True)
class PointMass:
    """One lumped mass of ``imperfections.point_masses``
    (:mod:`copdea_fem.study.imperfections`).

    Attributes
    ----------
    mass : float
        The mass [kg].
    r : float
        Its radius on the flat pre-stretched device [m] (at most ``geometry.inner_radius``:
        on the rigid disc).
    theta : float
        Its angle [deg], counter-clockwise from the x axis.
    """

    mass: float
    r: float
    theta: float = 0.0

    def plain(self) -> dict[str, Any]:
        """The plain mapping of the resolved study file."""
        return {"mass": self.mass, "r": self.r, "theta": self.theta}


#: The typed form of a list key's items (the plain form: a mapping per item).
LIST_ITEM_CLASSES = {("membrane", "prony"): PronyTerm,
                     ("electrodes", "segments"): ElectrodeSegment,
                     ("membrane", "thickness_variation"): ThicknessTerm,
                     ("imperfections", "point_masses"): PointMass}


def _field_type(section: str, key: str) -> Any:
    spec = SCHEMA[section][key]
    if spec.kind is list:
        return tuple[LIST_ITEM_CLASSES[section, key], ...]
    return spec.kind if spec.default is not None else Optional[spec.kind]  # noqa: UP045


def _field_default(section: str, key: str) -> Any:
    default = SCHEMA[section][key].default
    return tuple(default) if isinstance(default, list) else default


def _docstring(section: str) -> str:
    lines = [f"The ``{section}`` section of a study (generated from ``SCHEMA[{section!r}]``).",
             "", "Attributes", "----------"]
    for key, spec in SCHEMA[section].items():
        kind = (f"tuple of {LIST_ITEM_CLASSES[section, key].__name__}" if spec.kind is list
                else spec.kind.__name__)
        unit = f" [{spec.unit}]" if spec.unit else ""
        lines += [f"{key} : {kind}", f"    {spec.description}{unit}."]
    return "\n".join(lines)


def _section_class(section: str) -> type:
    name = section.capitalize() + "Section"
    cls = dataclasses.make_dataclass(
        name, [(key, _field_type(section, key), dataclasses.field(
            default=_field_default(section, key))) for key in SCHEMA[section]],
        namespace={"__doc__": _docstring(section), "__module__": __name__}, frozen=True)
    cls.__qualname__ = name
    return cls


#: Section name -> its generated frozen dataclass.
SECTION_CLASSES: dict[str, type] = {section: _section_class(section) for section in SCHEMA}
globals().update({cls.__name__: cls for cls in SECTION_CLASSES.values()})


def enclosure_shape(geometry) -> Enclosure | None:
    """The geometry's enclosure typed: None for ``geometry.enclosure = none`` (an open
    back), else an :class:`Enclosure` (``GeometrySection.enclosure_shape``)."""
    if geometry.enclosure == "none":
        return None
    return Enclosure(geometry.enclosure, geometry.enclosure_depth, geometry.enclosure_radius,
                     geometry.enclosure_vent_radius)


SECTION_CLASSES["geometry"].enclosure_shape = property(enclosure_shape)


def plain_section(section) -> dict[str, Any]:
    """A section's values as the plain mapping ``{key: SI value}`` of the resolved study
    (``membrane.prony`` a list of ``{modulus_ratio, relaxation_time}`` mappings)."""
    values = {}
    for field in dataclasses.fields(section):
        value = getattr(section, field.name)
        if isinstance(value, tuple):
            value = [item.plain() if hasattr(item, "plain") else
                     dataclasses.asdict(item) if dataclasses.is_dataclass(item) else item
                     for item in value]
        values[field.name] = value
    return values


def typed_section(section: str, values: dict[str, Any]):
    """The :data:`SECTION_CLASSES` instance of ``section`` holding ``values`` (plain SI
    values, checked: :func:`copdea_fem.study.keys.convert_value`)."""
    typed = {}
    for key, value in values.items():
        item_class = LIST_ITEM_CLASSES.get((section, key))
        typed[key] = tuple(item_class(**item) for item in value) if item_class else value
    return SECTION_CLASSES[section](**typed)


def _annotation(section: str, key: str) -> str:
    spec = SCHEMA[section][key]
    if spec.kind is list:
        return f"tuple[{LIST_ITEM_CLASSES[section, key].__name__}, ...]"
    return spec.kind.__name__ + ("" if spec.default is not None else " | None")


def stub_text() -> str:
    """The text of ``sections.pyi``: every generated section class with its fields typed,
    for type checkers and editors (which do not run the generation)."""
    lines = ['"""Type stub of :mod:`copdea_fem.study.sections`, made from ``SCHEMA`` by',
             '``python -m copdea_fem.study --stubs`` (do not edit by hand)."""',
             "", "from typing import Any", "",
             "class PronyTerm:", "    modulus_ratio: float", "    relaxation_time: float",
             "    def __init__(self, modulus_ratio: float, relaxation_time: float) -> None: ...",
             "", "class Enclosure:", "    kind: str", "    depth: float", "    radius: float",
             "    vent_radius: float",
             "    def __init__(self, kind: str, depth: float, radius: float, "
             "vent_radius: float) -> None: ...", "",
             "class SegmentDrive:", "    amplitude: float", "    phase: float",
             "    def __init__(self, amplitude: float = ..., phase: float = ...) -> None: ...",
             "", "class ElectrodeSegment:", "    name: str", "    theta: tuple[float, float]",
             "    r: tuple[float, float] | None", "    drive: SegmentDrive",
             "    def __init__(self, name: str, theta: Any, r: Any = ..., drive: Any = ...) "
             "-> None: ...", "    def plain(self) -> dict[str, Any]: ...", "",
             "class ThicknessTerm:", "    order: int", "    amplitude: float",
             "    angle: float",
             "    def __init__(self, order: int, amplitude: float, angle: float = ...) "
             "-> None: ...", "    def plain(self) -> dict[str, Any]: ...", "",
             "class PointMass:", "    mass: float", "    r: float", "    theta: float",
             "    def __init__(self, mass: float, r: float, theta: float = ...) -> None: ...",
             "    def plain(self) -> dict[str, Any]: ...", ""]
    for section, cls in SECTION_CLASSES.items():
        lines.append(f"class {cls.__name__}:")
        lines += [f"    {key}: {_annotation(section, key)}" for key in SCHEMA[section]]
        if section == "geometry":
            lines += ["    @property", "    def enclosure_shape(self) -> Enclosure | None: ..."]
        lines += ["    def __init__(self, **values: Any) -> None: ...", ""]
    lines += ["LIST_ITEM_CLASSES: dict[tuple[str, str], type]",
              "SECTION_CLASSES: dict[str, type]", "",
              "def enclosure_shape(geometry: GeometrySection) -> Enclosure | None: ...",
              "def plain_section(section: Any) -> dict[str, Any]: ...",
              "def typed_section(section: str, values: dict[str, Any]) -> Any: ...",
              "def stub_text() -> str: ..."]
    return "\n".join(lines) + "\n"
