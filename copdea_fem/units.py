"""The common quantities of a study read without pint, for the whole command's speed.

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
