"""What a measurement can see and how its scanned shapes pair with the model's:
``observed:`` and ``pairing:`` of ``measured.yaml`` (:mod:`copdea_fem.measured.manifest`)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from copdea_fem.measured.csv_files import MODE_LABEL
from copdea_fem.measured.errors import refusal

_FAMILY = re.compile(r"^\(\s*(m|\d+)\s*,\s*(n|[1-9]\d*)\s*\)$")
#: Kind words of ``observed``, and the model kinds each covers.  The diagnosis's model modes
#: are pumping, axisymmetric or non-axisymmetric (out-of-plane all three; its FE drops the
#: in-plane family, which an out-of-plane vibrometer hardly sees).
FAMILY_KINDS = {"out-of-plane": ("pumping", "axisymmetric", "non-axisymmetric"),
                "in-plane": ("in-plane",), "pumping": ("pumping",),
                "axisymmetric": ("axisymmetric",), "non-axisymmetric": ("non-axisymmetric",)}


@dataclass(frozen=True)
class ObservedFamilies:
    """The mode families a measurement can see (``observed:``).

    ``"(m,1)"``: every mode with one nodal circle (m any); ``"(0,n)"``: the axisymmetric
    membrane modes; ``"(2,1)"``: that mode (both members of its pair); a kind word
    (``out-of-plane``, ``in-plane``, ``pumping``, ``axisymmetric``, ``non-axisymmetric``):
    every mode of that kind.  A pumping mode ``P1, P2, ...`` is covered by ``pumping`` and
    ``out-of-plane`` only.
    """

    families: tuple

    def covers(self, label: str, kind: str) -> bool:
        """Whether a model mode (label, kind) belongs to an observed family."""
        match = MODE_LABEL.match(label or "")
        for family in self.families:
            if family in FAMILY_KINDS:
                if kind in FAMILY_KINDS[family]:
                    return True
                continue
            m_text, n_text = _FAMILY.match(family).groups()
            if match and m_text in ("m", match.group(1)) and n_text in ("n", match.group(2)):
                return True
        return False


def parse_observed(value) -> ObservedFamilies | None:
    """``observed:`` -> :class:`ObservedFamilies` (None: every mode can be seen)."""
    if value is None:
        return None
    allowed = ("a non-empty list of families: (m,n) patterns such as \"(m,1)\", \"(0,n)\", "
               "\"(2,1)\", or " + ", ".join(FAMILY_KINDS))
    if isinstance(value, str) or not isinstance(value, list) or not value:
        raise refusal("observed", value, allowed)
    families = []
    for index, item in enumerate(value):
        text = re.sub(r"\s+", "", item) if isinstance(item, str) else item
        if not isinstance(text, str) or not (text in FAMILY_KINDS or _FAMILY.match(text)):
            raise refusal(f"observed[{index}]", item, allowed)
        families.append(text)
    return ObservedFamilies(tuple(dict.fromkeys(families)))


@dataclass(frozen=True)
class PairingSettings:
    """How scanned shapes pair with the model's (:func:`copdea_fem.vibrometer.pairing.
    correlate_shapes`): relative frequency ``window`` and smallest ``mac_min`` of a pair."""

    window: float = 0.5
    mac_min: float = 0.5


PAIRING_BOUNDS = {"window": (0.01, 2.0), "mac_min": (0.05, 1.0)}


def parse_pairing(value) -> PairingSettings:
    """``pairing:`` -> :class:`PairingSettings` (defaults when absent); ``window`` takes a
    fraction (0.5) or a percentage (``50 %``)."""
    if value is None:
        return PairingSettings()
    if not isinstance(value, dict):
        raise refusal("pairing", value, "a mapping of " + ", ".join(PAIRING_BOUNDS))
    settings = {}
    for key, raw in value.items():
        if key not in PAIRING_BOUNDS:
            raise refusal(f"pairing.{key}", raw, "keys " + ", ".join(PAIRING_BOUNDS),
                          "unknown key")
        number = raw
        if isinstance(raw, str) and raw.strip().endswith("%"):
            try:
                number = float(raw.strip()[:-1]) / 100
            except ValueError:
                number = raw
        lo, hi = PAIRING_BOUNDS[key]
        if (isinstance(number, bool) or not isinstance(number, (int, float))
                or not math.isfinite(number) or not lo <= number <= hi):
            raise refusal(f"pairing.{key}", raw, f"a number in [{lo:g}, {hi:g}]"
                          + (" (or a percentage)" if key == "window" else ""))
        settings[key] = float(number)
    return PairingSettings(**settings)


IDENTIFICATION_KEYS = ("resolve_pairs",)


def parse_identification(value) -> dict:
    """``identification:`` -> the options it sets of the scans' identification
    (:func:`copdea_fem.vibrometer.identification.identify_scan`, used by identify, correlate
    and diagnose): ``resolve_pairs`` (true/false, default false: split a close pair whose
    poles the fit merged, :mod:`copdea_fem.vibrometer.close_pairs`)."""
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise refusal("identification", value, "a mapping of " + ", ".join(IDENTIFICATION_KEYS))
    for key, raw in value.items():
        if key not in IDENTIFICATION_KEYS:
            raise refusal(f"identification.{key}", raw, "keys " + ", ".join(IDENTIFICATION_KEYS),
                          "unknown key")
        if not isinstance(raw, bool):
            raise refusal(f"identification.{key}", raw, "true or false")
    return dict(value)


__all__ = ["FAMILY_KINDS", "IDENTIFICATION_KEYS", "PAIRING_BOUNDS", "ObservedFamilies", "PairingSettings",
           "parse_identification", "parse_observed", "parse_pairing"]
