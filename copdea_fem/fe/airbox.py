"""The air box's shared dimension: how high the air mesh follows the membrane.

Pure arithmetic without NGSolve, so that the checks before any meshing (the coupled
solve, the coupled sweeps, the forced response), the 3-D mesh
(:mod:`copdea_fem.fe.quadrant.geometry`) and the meridian mesh
(:mod:`copdea_fem.fe.axisymmetric.meridian`) share it.
"""

from __future__ import annotations

import math

from copdea_fem.inputs import preview
from copdea_fem.study import Study, StudyError


def ale_decay_length(domain_radius: float, outer_radius: float) -> float:
    """Height L [m] over which the air mesh follows the membrane (see :mod:`copdea_fem.fe.ale`).

    Half the air radius, capped so that the moved cylinder r < r_o, |z| < L
    stays well inside the air sphere (away from the PML).
    """
    return min(0.5 * domain_radius, 0.8 * math.sqrt(domain_radius**2 - outer_radius**2))


def check_air_lift(study: Study) -> None:
    """Refuse a ``load.z`` the moving air mesh cannot follow (:mod:`copdea_fem.fe.ale`).

    The coupled step moves the air over the height L of
    :func:`copdea_fem.fe.airbox.ale_decay_length`; beyond 0.45 L it would fold.
    Called before any meshing by the coupled solve and by coupled sweeps (the
    dry and reduced models do not move the air).
    """
    limit = 0.45 * ale_decay_length(study["air"]["domain_radius"],
                                    study["geometry"]["outer_radius"])
    if study["load"]["z"] >= limit:
        raise StudyError(f"load.z = {preview(study['load']['z'])} is not allowed (raise "
                         f"air.domain_radius); allowed: < {limit:g} m = 0.45 L for the coupled "
                         "step, L = the height over which the air mesh follows the membrane "
                         "(copdea_fem.fe.ale)")
