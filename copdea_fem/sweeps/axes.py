"""The sweep's grid vocabulary: swept axes, grid points, the sweep's error.

Kept apart from :mod:`.spec` (the sweep file parser, which re-exports them) so that
the grid (:mod:`.grid`) builds on them without importing the parser that calls it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from copdea_fem.inputs import preview
from copdea_fem.study import Study, StudyError

# Sections whose keys change neither the mesh nor the membrane solver: points that
# differ only there can continue from each other.
LOAD_LIKE_SECTIONS = ("load", "eigen", "disc", "spring", "reduced", "excitation", "effects",
                      "output")

MAX_POINTS = 10_000


class SweepError(StudyError):
    """A sweep file value is outside what is allowed; the message names key, value, allowed."""


def sweep_error(key: str, value: Any, allowed: str, why: str = "") -> SweepError:
    why = f" ({why})" if why else ""
    return SweepError(f"{key} = {preview(value)} is not allowed{why}; allowed: {allowed}")


@dataclass(frozen=True)
class Axis:
    """One swept study key.

    Attributes
    ----------
    key : str
        ``section.key`` of the study schema.
    values : tuple
        SI values in sweep order (numbers; text or bool for choice keys).
    unit : str or None
        SI unit of the values (from the schema).
    display_unit : str or None
        Unit the sweep file used (``kV``, ``mm``), for plots.
    """

    key: str
    values: tuple
    unit: str | None
    display_unit: str | None

    @property
    def changes_context(self) -> bool:
        return self.key.split(".", 1)[0] not in LOAD_LIKE_SECTIONS

    def column(self) -> str:
        """CSV column name: key plus its SI unit, e.g. ``load.voltage_v``."""
        if not self.unit:
            return self.key
        return f"{self.key}_{self.unit.lower().replace('/', '_').replace('^', '')}"

    def display(self, value) -> float:
        """An SI value in the display unit."""
        if not isinstance(value, (int, float)) or not self.display_unit or \
                self.display_unit == self.unit:
            return value
        from copdea_fem.study import unit_registry
        return float(unit_registry().Quantity(value, self.unit).to(self.display_unit).magnitude)

    def format(self, value) -> str:
        """A value as text in the display unit: ``2 kV``, ``12 mm``, ``square``."""
        shown = self.display(value)
        if isinstance(shown, bool) or not isinstance(shown, (int, float)):
            return str(shown)
        unit = self.display_unit or self.unit or ""
        return f"{shown:g} {unit}".rstrip()

    def label(self) -> str:
        unit = self.display_unit or self.unit
        return f"{self.key} [{unit}]" if unit else self.key


@dataclass(frozen=True)
class SweepPoint:
    """One grid point: its id, grid index, overrides and validated study; ``engine``: the
    FE engine of its study (:func:`copdea_fem.fe.engine_for`, resolved once; None for the
    ring model)."""

    point_id: str
    index: tuple
    overrides: dict
    study: Study
    context_key: str
    space_key: str
    study_hash: str
    engine: object = None
