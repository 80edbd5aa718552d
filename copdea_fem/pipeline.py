"""What every engine's pipeline hands back: stage timings and the coupled solution.

Kept apart from :mod:`copdea_fem.solve` (which re-exports both) so that the engines
(:mod:`copdea_fem.engines`) use them without importing the pipeline that calls them.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field


@dataclass
class Timings:
    """Wall time per pipeline stage [s]."""

    seconds: dict = field(default_factory=dict)

    @contextlib.contextmanager
    def stage(self, name: str):
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - start


@dataclass
class CoupledSolution:
    """What :func:`copdea_fem.solve.coupled_modes` returns: coupled and dry modes on one mesh."""

    state: object
    modes: list              # coupled modes (structural and air), sorted by Re f
    pressures: list          # pressure vector [Pa, free DOFs] of each coupled mode
    dry_modes: list
    dry_partner_hz: dict     # index in modes -> dry partner frequency [Hz]
    eigen: object            # eigen.SectorBandResults: the band result of each sector
    operators: list          # coupled.CoupledOperators of each sector, in solve order


def quiet(message: str) -> None:
    """The progress callback that says nothing."""


def single_threaded_blas():
    """BLAS on one thread for the eigen stage: SuperLU's triangular solves call BLAS
    on small supernode blocks, where a second thread costs more than it brings
    (coupled sectors of G1, default mesh: 12.0 s on one BLAS thread, 17.7 s on two)."""
    from threadpoolctl import threadpool_limits
    return threadpool_limits(limits=1, user_api="blas")
