"""The prestressed problem that ``copdea-fem response`` drives (either engine).

Below the engines, so that the engines' builders (:mod:`copdea_fem.fe.quadrant.forced`,
:mod:`copdea_fem.fe.axisymmetric.forced`) and the pipeline above them
(:mod:`copdea_fem.forced_response.run`) share it without an import running back up.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from copdea_fem.fe.forced.harmonic import CoupledPencil, ForcedOrder
    from copdea_fem.fe.prestress import PrestressedState
    from copdea_fem.study import Study


@dataclass(frozen=True)
class DrivenSector:
    """What the response needs to know of the part of the problem that the voltage drives:
    the order m = 0 (axisymmetric engine, :mod:`copdea_fem.fe.axisymmetric.forced`) or the
    even-even symmetry sector (3-D engine, :mod:`copdea_fem.fe.quadrant.forced`).  Built by the
    engine with its forced problem (:meth:`copdea_fem.fe.engines.Engine.forced_problem`), so
    that :mod:`copdea_fem.forced_response.run` and :mod:`copdea_fem.forced_response.files`
    never test the engine's name."""

    name: str                       # progress: "coupled modes of the <name>"
    excited: str                    # response.json "excited"
    summary: str                    # the summary's first line: "forced response (<summary>, ...)"
    classify: Callable              # (problem, band result) -> modes, membrane fractions set
    label: Callable                 # (modes) -> None: labels as ``solve`` gives them
    observer: type                  # the membrane velocity observer at the scan radii
    angles: int                     # angles per radius the observer averages over
    sphere: type                    # the Kirchhoff sphere's pressure sampler
    shape_sector: Callable          # (membrane operators) -> the ShapeAt sector (or None)
    write_shapes: Callable          # (staging, state, coupled, shapes, pressures) -> (files, air)
    default_method: str = "modal"   # what ``response.method: auto`` means here
    modal_method: str = "modal"     # ... and where the damping is the paper's modal b/m


@dataclass
class OrderZero:
    """The prestressed m = 0 problem of a study, ready to be driven: the study, its
    prestressed state (either engine's), the driven part's coupled operators and their
    forced pencil."""

    study: Study
    state: PrestressedState
    coupled: CoupledPencil
    forced: ForcedOrder
    timings: dict = field(default_factory=dict)
    sector: DrivenSector | None = None

    @property
    def engine(self) -> str:
        """``"axisymmetric"`` (the order m = 0) or ``"3d"`` (the even-even sector)."""
        return getattr(self.state, "engine", "3d")
