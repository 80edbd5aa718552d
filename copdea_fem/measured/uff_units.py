"""The unit labels of a UFF export (dataset 58), in SI.

Dataset 164 gives factors that convert the file's units to SI by division
(``SI = value / factor``: length, force, temperature).  A dataset 58 says its axes'
units twice: as exponents of those base units (records 8-11) and as free-text labels
(``m/s``, ``(1/N)*(m/s²)``, ``g²/Hz``).  A label that names a unit wins (the exponents are
often left at zero); a label that names none (``NONE``, empty) falls back to 164 and the
exponents.  Labels are decoded from the file's bytes, UTF-8 and else Latin-1 (a
shaker controller's ``g²/Hz`` is the Latin-1 byte 0xB2), and read with pint, ``g``
taken as standard gravity (no mass appears on these axes); the common ones (products of
m, s, Hz, N, V, A, Pa, kg, g with a few prefixes:
:func:`copdea_fem.units.fast_label_to_si`) without it, to the same factor and
dimensions, sparing the command pint's start (~0.6 s).  An FRF's ordinate label
that already holds the denominator (``m/s/V``) is not divided by it again.
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass

from copdea_fem.units import fast_label_to_si

#: UFF specific data types of a 58 ordinate (record 9) that say what the response is.
RESPONSE_CODES = {8: "displacement", 11: "velocity", 12: "acceleration"}
#: Labels that name no unit.
_NO_UNIT = {"", "none", "unknown", "n/a", "-", "nounit", "no unit"}
#: SI dimensions (pint's) of the responses, to tell a response from its label.
_RESPONSE_DIMENSIONS = {"displacement": {"[length]": 1},
                        "velocity": {"[length]": 1, "[time]": -1},
                        "acceleration": {"[length]": 1, "[time]": -2}}
#: ... and of the excitations an FRF's ordinate label may already divide by: none, N, V.
_EXCITATION_DIMENSIONS = ({}, {"[mass]": 1, "[length]": 1, "[time]": -2},
                          {"[mass]": 1, "[length]": 2, "[time]": -3, "[current]": -1})


@dataclass(frozen=True)
class UnitLabel:
    """A unit label read: the text, the factor to SI, the SI dimensions (pint's)."""

    text: str
    factor: float
    dimensions: dict


def decode_label(raw: bytes) -> str:
    """A header field's text: UTF-8 when it is, else Latin-1 (every byte a character)."""
    try:
        return raw.decode("utf-8").strip()
    except UnicodeDecodeError:
        return raw.decode("latin-1").strip()


@functools.lru_cache(maxsize=256)
def parse_unit_label(text: str) -> UnitLabel | None:
    """A UFF unit label (``m/s``, ``(1/N)*(m/s²)``, ``g²/Hz``, ``µm/s``) in SI, or None
    when it names no unit pint can read.  ``g`` is standard gravity (9.80665 m/s^2)."""
    cleaned = text.strip()
    if cleaned.lower() in _NO_UNIT:
        return None
    cleaned = (cleaned.replace("²", "**2").replace("³", "**3").replace("µ", "u")
               .replace("μ", "u").replace("^", "**").replace("Ohm", "ohm"))
    cleaned = re.sub(r"(?<![A-Za-z_])g(?![A-Za-z_])", "g_n", cleaned)
    cleaned = re.sub(r"\brms\b|\bRMS\b|\bpk\b|\bpeak\b", "", cleaned).strip()
    fast = fast_label_to_si(cleaned)    # m/s, (m/s)/V, g_n**2/Hz without pint's slow start
    if fast is not None:
        return UnitLabel(text, *fast)
    from copdea_fem.study import unit_registry

    registry = unit_registry()
    try:
        quantity = registry.parse_expression(cleaned)
        base = (1.0 * quantity).to_base_units()
    except Exception:  # noqa: BLE001 -- pint raises many types on text it cannot read
        return None
    if not hasattr(base, "dimensionality") or not math.isfinite(float(base.magnitude)):
        return None
    return UnitLabel(text, float(base.magnitude), dict(base.dimensionality))


def exponent_factor(units: dict, record: dict, axis: str) -> float:
    """Factor to SI from dataset 164 and the axis' unit exponents (``SI = value / f``)."""
    length = record.get(f"{axis}_len_unit_exp", 0) or 0
    force = record.get(f"{axis}_force_unit_exp", 0) or 0
    return 1.0 / (units["length"] ** length * units["force"] ** force)


def response_of(dimensions: dict | None, code: int) -> str:
    """The response a label's dimensions name, alone or per newton or volt
    (``(1/N)*(m/s²)`` is an acceleration per force), else the specific data type's."""
    if dimensions is not None:
        for excitation in _EXCITATION_DIMENSIONS:
            times = {k: dimensions.get(k, 0) + excitation.get(k, 0)
                     for k in set(dimensions) | set(excitation)}
            times = {k: v for k, v in times.items() if v}
            for name, wanted in _RESPONSE_DIMENSIONS.items():
                if times == wanted:
                    return name
    return RESPONSE_CODES.get(code, "unknown")


def already_divided(outer: dict, inner: dict) -> bool:
    """Whether a label's dimensions already hold ``1 / inner`` (``m/s/V`` holds ``V``)."""
    with_inner = {k: outer.get(k, 0) + inner.get(k, 0) for k in set(outer) | set(inner)}
    size = lambda dims: sum(abs(v) for v in dims.values())
    return size(with_inner) < size(outer)


__all__ = ["RESPONSE_CODES", "UnitLabel", "already_divided", "decode_label", "exponent_factor",
           "parse_unit_label", "response_of"]
