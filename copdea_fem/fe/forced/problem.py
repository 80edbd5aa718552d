"""What an engine hands the forced response (either engine): the prestressed problem that
``copdea-fem response`` drives (:class:`OrderZero`, :class:`DrivenSector`) and the parts of a
solve that an electrode drives (:class:`DrivenPart`).

Below the engines, so that the engines' builders (:mod:`copdea_fem.fe.quadrant.forced`,
:mod:`copdea_fem.fe.axisymmetric.forced`) and the driver above them
(:mod:`copdea_fem.forced_response`) share them without an import running back up.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from copdea_fem.fe.forced.harmonic import CoupledPencil, ForcedOrder
    from copdea_fem.fe.prestress import PrestressedState
    from copdea_fem.study import Study

logger = logging.getLogger(__name__)


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
    # (problem, band result) -> (modes with their membrane fractions, pressure vectors)
    classify: Callable
    # (problem, modes, pressures, band top [Hz]) -> None: names and labels as ``solve``
    # gives them (over an enclosure: cavity orders, n from :meth:`OrderZero.dry_partners`)
    label: Callable
    observer: type                  # the membrane velocity observer at the scan radii
    angles: int                     # angles per radius the observer averages over
    sphere: type                    # the Kirchhoff sphere's pressure sampler
    shape_sector: Callable          # (membrane operators) -> the ShapeAt sector (or None)
    write_shapes: Callable          # (staging, state, coupled, shapes, pressures) -> (files, air)
    default_method: str = "modal"   # what ``response.method: auto`` means here
    modal_method: str = "modal"     # ... and where the damping is the paper's modal b/m


@dataclass
class DrivenPart:
    """One independently solved part of a solve (a symmetry sector, an order m or the whole
    mesh) with its band result: what an electrode drives
    (:meth:`copdea_fem.fe.engines.Engine.driven_parts`).

    Attributes
    ----------
    key : str
        The part's name in the solve's band results (``"all"``, a sector's, ``"m=<m>"``).
    pencil : object
        The part's coupled operators, or a :class:`copdea_fem.fe.forced.harmonic.DryPencil`
        in vacuo; ``pencil.membrane`` its membrane operators.
    band : object
        Its eigen result (eigenvalues, vectors on the pencil's unknowns).
    sector : Sector or None
        The 3-D symmetry sector (None on a whole mesh and on the axisymmetric engine).
    m : int or None
        The axisymmetric order (None on the 3-D engine).
    """

    key: str
    pencil: object
    band: object
    sector: object = None
    m: int | None = None

    @property
    def uniform(self) -> bool:
        """Whether the part holds the fields a uniform electrode drives (the part ``response``
        drives, :class:`DrivenSector`): the order m = 0, the even-even symmetry sector
        (every parity +1) or a whole mesh."""
        if self.m is not None:
            return self.m == 0
        if self.sector is None:
            return True
        from copdea_fem.fe.symmetry import QUADRANTS
        return all(self.sector.sign(qx, qy) > 0 for qx, qy in QUADRANTS)

    def families(self, electrode) -> list[tuple[str, float]]:
        """``(family, factor)`` of each field of the part that ``electrode`` (an
        :class:`copdea_fem.fe.forced.electrode.ElectrodeImperfection`) drives: an order's
        cos and sin families by the electrode's ``family_weights`` (those not zero), a 3-D
        part whole (its forcing holds the folded weight)."""
        if self.m is None:
            return [("cos", 1.0)]
        return [(family, factor) for family, factor in zip(
            ("cos", "sin"), electrode.family_weights(self.m)) if factor != 0.0]


def band_parts(eigen) -> dict:
    """The band result of each part of a solve: ``{part key: band result}`` (one part
    ``"all"`` where the solve had one band; none where its parts found no mode)."""
    by_sector = getattr(eigen, "by_sector", None)
    return {"all": eigen} if by_sector is None else by_sector


@dataclass
class OrderZero:
    """The prestressed m = 0 problem of a study, ready to be driven: the study, its
    prestressed state (either engine's), the driven part's coupled operators and their
    forced pencil.

    Over an enclosure the engine also gives what ``solve``'s labels need beyond the coupled
    band (:attr:`DrivenSector.label`): ``cavity``, its sampler of the enclosure's pressure
    (the cavity orders), and ``dry_band``, ``f_max [Hz] -> the driven part's dry modes from
    0 Hz to f_max``, classified and numbered (the dry partners that number the coupled
    modes); both None without one (no dry solve: the counted n stands).
    """

    study: Study
    state: PrestressedState
    coupled: CoupledPencil
    forced: ForcedOrder
    timings: dict = field(default_factory=dict)
    sector: DrivenSector | None = None
    cavity: object = None
    dry_band: Callable | None = None
    dry_solved: dict = field(default_factory=dict, repr=False)   # f_max [Hz] -> modes

    def dry_partners(self, f_max: float) -> list | None:
        """The driven part's dry modes from 0 Hz to ``f_max`` [Hz] (:attr:`dry_band`), solved
        once for the widest band asked and cut to ``f_max`` (so that the labels do not
        depend on which band was asked first); None without a dry band."""
        if self.dry_band is None:
            return None
        widest = max(self.dry_solved, default=0.0)
        if widest < f_max:
            start = time.perf_counter()
            self.dry_solved.clear()
            self.dry_solved[f_max] = self.dry_band(f_max)
            widest = f_max
            logger.info(f"dry partners of the {self.sector.name if self.sector else 'part'} "
                        f"(0 .. {f_max:g} Hz): {len(self.dry_solved[f_max])} modes in "
                        f"{time.perf_counter() - start:.2f} s")
        return [mode for mode in self.dry_solved[widest] if mode.freq_hz <= f_max]

    @property
    def engine(self) -> str:
        """``"axisymmetric"`` (the order m = 0) or ``"3d"`` (the even-even sector)."""
        return getattr(self.state, "engine", "3d")
