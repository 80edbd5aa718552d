"""The air box's one shared dimension: how high the air mesh follows the membrane.

Pure arithmetic, kept apart so that the study checks (:mod:`copdea_fem.study`), the
3-D mesh (:mod:`copdea_fem.geometry`, which re-exports it) and the meridian mesh
(:mod:`copdea_fem.axisymmetric.meridian`) use it without importing each other.
"""

from __future__ import annotations

import math


def ale_decay_length(domain_radius: float, outer_radius: float) -> float:
    """Height L [m] over which the air mesh follows the membrane (see :mod:`ale`).

    Half the air radius, capped so that the moved cylinder r < r_o, |z| < L
    stays well inside the air sphere (away from the PML).
    """
    return min(0.5 * domain_radius, 0.8 * math.sqrt(domain_radius**2 - outer_radius**2))
