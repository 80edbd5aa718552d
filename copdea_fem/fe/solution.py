"""What an engine's coupled solve returns: :class:`CoupledSolution`.

Its own module below both engines and the pipeline: the engines build it, the pipeline
(:func:`copdea_fem.fe.pipeline.coupled_modes`) and its callers read it.  Annotations only
reach up to the mode, prestress and band types, so importing it loads no NGSolve.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

    from copdea_fem.fe.eigen import SectorBandResults
    from copdea_fem.fe.modes import Mode
    from copdea_fem.fe.prestress import PrestressedState


@dataclass
class CoupledSolution:
    """Coupled and dry modes on one mesh (an engine's ``coupled_modes``)."""

    state: PrestressedState
    modes: list[Mode]                   # coupled modes (structural and air), sorted by Re f
    pressures: list[np.ndarray]         # pressure vector [Pa, free DOFs] of each coupled mode
    dry_modes: list[Mode]
    dry_partner_hz: dict[int, float]    # index in modes -> dry partner frequency [Hz]
    eigen: SectorBandResults            # the band result of each sector (or order)
    operators: list                     # the engine's coupled operators of each sector
                                        # (or order), in solve order
    order_pencil: Callable | None = None    # m -> the coupled operators of any order m
                                            # (axisymmetric engine: the orders a drive
                                            # reaches beyond the solved ones); None on 3-D
    order_operators: Callable | None = None  # m -> the dry operators of any order m, from
                                             # the solve's own forms (axisymmetric engine)
