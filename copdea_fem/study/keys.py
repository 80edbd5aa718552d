"""One study key: its type (:class:`Key`), its value read, converted to SI and checked.

Physical values accept a unit string (``"35.5 mm"``, ``"2 kV"``, ``"228.5 kPa"``) or a
plain SI number.  The common units are read from :mod:`copdea_fem.units`'s table; pint
reads the rest (compound expressions, other units, offsets).  Every refusal is a
:class:`StudyError` naming the key, the value and what is allowed (:func:`refusal`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import re
from dataclasses import dataclass
from typing import Any

from copdea_fem.inputs import preview
from copdea_fem.units import fast_to_si


class StudyError(ValueError):
    """A study key has a value outside what is allowed; the message says which.

    Raised for every bad input, before any work where it can be found then: a study file
    or key, a command's argument, an input file (the CLI's exit 2).  Subclasses:
    :class:`copdea_fem.sweeps.axes.SweepError` (a sweep file) and
    :class:`copdea_fem.measured.MeasuredDataError` (a measured data set).

    Parameters
    ----------
    message : str
        The key (or argument or file), its value and what is allowed.
    """


@dataclass(frozen=True)
class Key:
    """One study key: SI unit, default, bounds and meaning.

    ``unit`` is the SI unit the value is converted to (``None`` for a pure
    number, a switch or a choice); a list key (``kind=list``) is read item by item by its
    ``reader``.  ``default=None`` with ``derived`` set means
    the default is computed from other keys (see
    :func:`copdea_fem.study.checks.derived_defaults`).
    """

    unit: str | None
    default: Any
    description: str
    kind: type = float
    minimum: float | None = None
    maximum: float | None = None
    open_min: bool = False          # minimum excluded
    choices: tuple | None = None
    derived: str | None = None      # text of the derived default, for the docs
    reader: Any = None              # a list key's reader (key, value) -> plain SI items

    def allowed(self) -> str:
        if self.choices:
            return "one of " + ", ".join(map(str, self.choices))
        if self.kind is list:
            return "a list (see the description)"
        if self.kind is bool:
            return "true or false"
        if self.kind is str:
            return "any text"
        lo = "" if self.minimum is None else f"{self.minimum:g}"
        hi = "" if self.maximum is None else f"{self.maximum:g}"
        unit = f" {self.unit}" if self.unit else ""
        if self.minimum is not None and self.maximum is not None:
            bracket = "(" if self.open_min else "["
            return f"{bracket}{lo}, {hi}]{unit}"
        if self.minimum is not None:
            return f"{'>' if self.open_min else '>='} {lo}{unit}"
        if self.maximum is not None:
            return f"<= {hi}{unit}"
        return "any number" + unit


#: Longest text read as a quantity ("35.5 mm", "1.5e-3 kg/m^3").
MAX_QUANTITY_CHARACTERS = 100


@functools.lru_cache(maxsize=1)
def unit_registry():
    """pint's unit registry, made once (slow to build): the fallback of :func:`convert_value`
    for units :mod:`copdea_fem.units` does not know."""
    import pint
    return pint.UnitRegistry()


#: Values this many units in the last place apart count as equal where a bound is open
#: (``>``) or two keys must differ: a unit conversion rounds ("35.5 mm" is
#: 35.5 * 1e-3 = 0.035500000000000004 m, one ulp above 0.0355).
ROUND_OFF_ULPS = 4


def above(value: float, bound: float) -> bool:
    """``value > bound`` beyond round-off (:data:`ROUND_OFF_ULPS`): a value within a few
    ulps of an open bound is on it, as the number written without a unit would be."""
    return value - bound > ROUND_OFF_ULPS * math.ulp(max(abs(value), abs(bound)))


def apart(first: float, second: float) -> bool:
    """Whether two values differ beyond round-off (:func:`above` either way)."""
    return above(first, second) or above(second, first)


def refusal(key: str, value: Any, allowed: str, why: str = "") -> StudyError:
    """The :class:`StudyError` refusing ``key = value``: ``why`` (if given) and what is
    ``allowed``."""
    why = f" ({why})" if why else ""
    return StudyError(f"{key} = {preview(value)} is not allowed{why}; allowed: {allowed}")


def convert_value(key: str, spec: Key, value: Any) -> Any:
    """Turn one raw value into its SI value, checking type, unit and bounds."""
    if value is None and spec.default is None:
        return None
    if spec.kind is list:
        return (spec.reader or _LIST_KEYS[key])(key, value)
    if spec.kind is bool:
        if not isinstance(value, bool):
            raise refusal(key, value, spec.allowed())
        return value
    if spec.kind is str:
        if not isinstance(value, str) or (spec.choices and value not in spec.choices):
            raise refusal(key, value, spec.allowed())
        return value
    number = _to_si(key, spec, value)
    if not math.isfinite(number):
        raise refusal(key, value, spec.allowed(), "not a finite number")
    if spec.kind is int:
        if not float(number).is_integer():
            raise refusal(key, value, "an integer " + spec.allowed())
        number = int(number)
    number = number + 0        # -0.0 is 0
    lo, hi = spec.minimum, spec.maximum
    if (lo is not None and (number < lo or (spec.open_min and not above(number, lo)))) or (
            hi is not None and number > hi):
        shown = value if not isinstance(value, str) else f"{value} = {number:g} {spec.unit or ''}"
        raise refusal(key, shown, spec.allowed())
    return number


#: Prony series: at most this many terms (each adds a block of internal variables).
MAX_PRONY_TERMS = 8
PRONY_ALLOWED = ("a list of at most 8 mappings {modulus_ratio: number in (0, 1000], "
                 "relaxation_time: time in (0, 1000] s, e.g. '1 ms'}")


def _prony_terms(key: str, value: Any) -> list:
    """``membrane.prony`` (mappings or :class:`~copdea_fem.study.sections.PronyTerm`) ->
    ``[{"modulus_ratio": g_j, "relaxation_time": tau_j [s]}, ...]``."""
    if value is None:
        value = []
    if not isinstance(value, (list, tuple)) or len(value) > MAX_PRONY_TERMS:
        raise refusal(key, value, PRONY_ALLOWED)
    terms = []
    for index, item in enumerate(value):
        where = f"{key}[{index}]"
        if dataclasses.is_dataclass(item) and not isinstance(item, type):   # a PronyTerm
            item = dataclasses.asdict(item)
        if not isinstance(item, dict) or set(item) != {"modulus_ratio", "relaxation_time"}:
            raise refusal(where, item, PRONY_ALLOWED, "each term needs exactly the keys "
                          "modulus_ratio and relaxation_time")
        ratio = convert_value(f"{where}.modulus_ratio", Key(None, 0.0, "", minimum=0, maximum=1e3,
                                                       open_min=True), item["modulus_ratio"])
        tau = convert_value(f"{where}.relaxation_time", Key("s", 0.0, "", minimum=0, maximum=1e3,
                                                       open_min=True), item["relaxation_time"])
        terms.append({"modulus_ratio": ratio, "relaxation_time": tau})
    return terms


_LIST_KEYS = {"membrane.prony": _prony_terms}


def convert_quantity(key: str, value: Any, unit: str, minimum: float | None = None,
                     maximum: float | None = None) -> float:
    """One value of a compound key (e.g. a coordinate in a list) to SI ``unit``, bounds
    checked; a bare number is already SI.  Raises StudyError naming ``key``."""
    return convert_value(key, Key(unit, 0.0, key, minimum=minimum, maximum=maximum), value)


#: A bare number as people write it, read as a number in SI (YAML 1.1 reads ``3e-6`` and
#: ``5E5``, without a dot, as text; pint would read the ``e`` as the elementary charge).
_PLAIN_NUMBER = re.compile(r"[+-]?(?:\d(?:_?\d)*(?:\.(?:\d(?:_?\d)*)?)?|\.\d(?:_?\d)*)"
                           r"(?:[eE][+-]?\d+)?")
#: The texts of a number that is not finite (Python's and YAML's spellings).
_NOT_FINITE = re.compile(r"[+-]?\.?(?:nan|inf|infinity)", re.IGNORECASE)


def _to_si(key: str, spec: Key, value: Any) -> float:
    if isinstance(value, numbers.Real) and not isinstance(value, bool):   # numpy's too
        try:
            return float(value)
        except OverflowError:                   # an integer of more than 308 digits
            return math.inf
    if not isinstance(value, str):
        example = f" or a quantity like '1.5 {_example_unit(spec.unit)}'" if spec.unit else ""
        raise refusal(key, value, spec.allowed(), "expected a number" + example)
    if len(value) > MAX_QUANTITY_CHARACTERS:    # pint takes minutes on 100 000 digits
        raise refusal(key, value, spec.allowed(), f"longer than {MAX_QUANTITY_CHARACTERS} "
                      "characters, not a quantity")
    text = value.strip()
    if _NOT_FINITE.fullmatch(text):
        raise refusal(key, value, spec.allowed(), "not a finite number")
    if _PLAIN_NUMBER.fullmatch(text):
        return float(text)
    fast = fast_to_si(value.strip(), spec.unit)     # "16 mm" without pint's slow start
    if fast is not None:
        return fast
    import pint
    try:
        quantity = unit_registry().Quantity(value.strip())
    except Exception as exc:  # pint raises several types for unparsable text
        raise refusal(key, value, spec.allowed(), f"cannot read it as a quantity: {exc}") from None
    try:
        return float(quantity.to(spec.unit or "dimensionless").magnitude)
    except pint.DimensionalityError:
        expected = f"a quantity in {spec.unit}" if spec.unit else "a pure number"
        raise refusal(key, value, spec.allowed(), f"wrong unit, expected {expected}") from None


def _example_unit(unit: str | None) -> str:
    return {"m": "mm", "V": "kV", "Pa": "kPa", "kg": "g", "Hz": "Hz"}.get(unit, unit or "")
