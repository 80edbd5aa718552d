"""The common quantities of a study, and the common unit labels of a measurement file,
read without pint, for the whole command's speed.

Reading ``"16 mm"`` with :mod:`pint` costs its import (slow: it imports dask
when dask is installed) and the build of its unit registry in every fresh
process, together more than the whole axisymmetric solve of a small study.  Almost every value
of a study is ``<number> <unit>`` with one of a few units: :func:`fast_to_si` reads
those from the table below, and :mod:`copdea_fem.study` falls back to pint for
everything else (compound expressions, other units, offsets such as degC), so no
input pint reads is refused.

The factors are exact products of the SI prefixes and definitions (BIPM SI
brochure, 9th ed., Tables 4 and 7; gram = 1e-3 kg, litre-free), and the result is
``magnitude * factor`` -- the same arithmetic as pint's ``Quantity.to`` for a
multiplicative unit, so the SI value is bitwise pint's
(``tests/study/test_units.py`` checks every entry against pint).
"""

from __future__ import annotations

import math
import re

#: SI prefixes (BIPM SI brochure, Table 7) written as pint reads them
_PREFIXES = {"": 1.0, "n": 1e-9, "u": 1e-6, "µ": 1e-6, "m": 1e-3, "c": 1e-2, "k": 1e3,
             "M": 1e6, "G": 1e9}
#: base symbol -> (SI unit of the study schema, factor of the unprefixed symbol)
_BASES = {"m": ("m", 1.0), "V": ("V", 1.0), "Pa": ("Pa", 1.0), "Hz": ("Hz", 1.0),
          "s": ("s", 1.0), "g": ("kg", 1e-3), "N/m": ("N/m", 1.0)}
#: which prefixes each base takes here (others go to pint)
_ALLOWED = {"m": "num cµuk", "V": "mkM", "Pa": "mkMG", "Hz": "mkMG", "s": "nuµm",
            "g": "umk", "N/m": "mk"}
#: compound units written out (factor to the SI unit of the schema)
_COMPOUND = {"kg/m^3": ("kg/m^3", 1.0), "kg/m**3": ("kg/m^3", 1.0),
             "m/s": ("m/s", 1.0), "1/s": ("1/s", 1.0)}


def _table() -> dict[str, tuple[str, float]]:
    table = dict(_COMPOUND)
    for base, (unit, factor) in _BASES.items():
        for prefix in _ALLOWED[base].replace(" ", ""):
            table[prefix + base] = (unit, _PREFIXES[prefix] * factor)
        table[base] = (unit, factor)
    return table


#: unit text -> (SI unit it converts to, factor)
UNITS = _table()
_QUANTITY = re.compile(r"\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*(\S+)\s*")


def fast_to_si(text: str, unit: str | None) -> float | None:
    """``text`` ("16 mm") in SI ``unit`` ("m"); ``None`` when the table cannot say (an
    unknown unit, an expression, another dimension: pint decides and words the error)."""
    if unit is None:
        return None
    found = _QUANTITY.fullmatch(text)
    if found is None:
        return None
    number, symbol = found.groups()
    entry = UNITS.get(symbol)
    if entry is None or entry[0] != unit:
        return None
    # pint reads an integer magnitude as int and multiplies: int * float rounds the
    # int to the nearest float first, as float() of its text does
    magnitude = int(number) if re.fullmatch(r"[+-]?\d+", number) else float(number)
    if isinstance(magnitude, int) and abs(magnitude) > 2 ** 53:
        return None
    value = magnitude * entry[1]
    return value if math.isfinite(value) else None


# --- unit labels of measurement files (UFF dataset 58's axis labels) ---------------------

_LENGTH, _TIME, _MASS, _CURRENT = "[length]", "[time]", "[mass]", "[current]"
#: symbol -> (factor to SI, SI dimensions as pint names them): the units a vibration
#: export's axis labels use (BIPM SI brochure, Tables 2 and 4; ``g_n`` standard gravity,
#: 9.80665 m/s^2 exactly, CGPM 1901)
_LABEL_BASES = {"m": (1.0, {_LENGTH: 1}), "s": (1.0, {_TIME: 1}), "Hz": (1.0, {_TIME: -1}),
                "N": (1.0, {_MASS: 1, _LENGTH: 1, _TIME: -2}),
                "V": (1.0, {_MASS: 1, _LENGTH: 2, _TIME: -3, _CURRENT: -1}),
                "A": (1.0, {_CURRENT: 1}), "Pa": (1.0, {_MASS: 1, _LENGTH: -1, _TIME: -2}),
                "kg": (1.0, {_MASS: 1}), "g_n": (9.80665, {_LENGTH: 1, _TIME: -2})}
#: which prefixes each label symbol takes here (others go to pint)
_LABEL_ALLOWED = {"m": "numck", "s": "num", "Hz": "k", "N": "mk", "V": "umk", "A": "um",
                  "Pa": "kM", "kg": "", "g_n": ""}


def _label_table() -> dict[str, tuple[float, dict]]:
    table = {}
    for base, (factor, dimensions) in _LABEL_BASES.items():
        table[base] = (factor, dimensions)
        for prefix in _LABEL_ALLOWED[base]:
            table[prefix + base] = (_PREFIXES[prefix] * factor, dimensions)
    return table


#: label symbol -> (factor to SI, SI dimensions)
LABEL_UNITS = _label_table()
_LABEL_TOKEN = re.compile(r"\s*(\*\*|[*/()]|[+-]?\d+|[A-Za-z_]+)")


def _label_tokens(text: str) -> list[str] | None:
    tokens, position = [], 0
    while position < len(text):
        found = _LABEL_TOKEN.match(text, position)
        if found is None:
            return None
        tokens.append(found.group(1))
        position = found.end()
        while position < len(text) and text[position].isspace():
            position += 1
    return tokens


def fast_label_to_si(text: str) -> tuple[float, dict] | None:
    """A unit label's factor to SI and SI dimensions (``{"[length]": 1, "[time]": -1}``,
    pint's names) when it is a product of the symbols of :data:`LABEL_UNITS` (``*``,
    ``/`` left to right, parentheses, integer powers ``**n``, ``1``): ``m/s``,
    ``(m/s)/V``, ``g_n**2/Hz``, ``(1/N)*(m/s**2)``; ``None`` otherwise (another unit, a
    number, implicit products: pint decides).  The factor is the product of the symbols'
    exact factors, as pint's ``to_base_units`` multiplies them."""
    tokens = _label_tokens(text)
    if not tokens:
        return None
    position = 0

    def combine(left, right, sign):
        factor = left[0] * right[0] if sign > 0 else left[0] / right[0]
        dimensions = dict(left[1])
        for key, power in right[1].items():
            dimensions[key] = dimensions.get(key, 0) + sign * power
        return factor, {key: power for key, power in dimensions.items() if power}

    def atom():
        nonlocal position
        if position >= len(tokens):
            raise ValueError(text)
        token = tokens[position]
        position += 1
        if token == "(":
            value = product()
            if position >= len(tokens) or tokens[position] != ")":
                raise ValueError(text)
            position += 1
        elif token == "1":
            value = (1.0, {})
        elif token in LABEL_UNITS:
            value = LABEL_UNITS[token]
        else:
            raise ValueError(text)
        if position < len(tokens) and tokens[position] == "**":
            if position + 1 >= len(tokens) or not re.fullmatch(r"[+-]?\d+", tokens[position + 1]):
                raise ValueError(text)
            power = int(tokens[position + 1])
            if abs(power) > 4:
                raise ValueError(text)
            position += 2
            factor, dimensions = value
            value = (factor ** power, {key: exponent * power
                                       for key, exponent in dimensions.items()})
        return value

    def product():
        nonlocal position
        value = atom()
        while position < len(tokens) and tokens[position] in "*/":
            sign = 1 if tokens[position] == "*" else -1
            position += 1
            value = combine(value, atom(), sign)
        return value

    try:
        factor, dimensions = product()
    except ValueError:
        return None
    if position != len(tokens) or not dimensions or not math.isfinite(factor) or factor == 0:
        return None                 # a pure number ("1", "m/m"): pint says what it is
    return factor, dimensions
