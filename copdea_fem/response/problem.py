"""The prestressed problem that ``copdea-fem response`` drives (either engine).

Kept apart from :mod:`.run` so that the 3-D builder (:mod:`.quadrant`) and the
pipeline (:mod:`.run`) share it without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class OrderZero:
    """The prestressed m = 0 problem of a study, ready to be driven."""

    study: object
    state: object
    coupled: object
    forced: object
    timings: dict = field(default_factory=dict)

    @property
    def engine(self) -> str:
        """``"axisymmetric"`` (the order m = 0) or ``"3d"`` (the even-even sector)."""
        return getattr(self.state, "engine", "3d")
