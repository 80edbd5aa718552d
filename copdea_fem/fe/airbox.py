"""The air box's shared dimensions: how high the air mesh follows the membrane, and how deep
an enclosure under it is.

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
    limit = 0.45 * ale_decay_length(study.air.domain_radius,
                                    study.geometry.outer_radius)
    if study.load.z >= limit:
        raise StudyError(f"load.z = {preview(study.load.z)} is not allowed (raise "
                         f"air.domain_radius); allowed: < {limit:g} m = 0.45 L for the coupled "
                         "step, L = the height over which the air mesh follows the membrane "
                         "(copdea_fem.fe.ale)")


def bowl_sphere_radius(rim_radius: float, depth: float) -> float:
    """Radius [m] of the sphere whose cap has the rim radius ``a`` and the depth ``L`` at its
    centre: ``(a^2 + L^2) / (2 L)`` (the chord-sagitta relation a^2 = L (2 R_s - L))."""
    return (rim_radius**2 + depth**2) / (2 * depth)


def cavity_depth(enclosure: str, depth: float, rim_radius: float, radius):
    """Depth [m] of the enclosure's bottom below the plane at the radius (a float or an
    NGSolve CoefficientFunction), for a radius inside the rim: the depth of a cylinder or a
    box, the spherical cap's ``sqrt(R_s^2 - r^2) - (R_s - L)`` of a bowl."""
    if enclosure != "bowl":
        return depth
    sphere = bowl_sphere_radius(rim_radius, depth)
    if isinstance(radius, (int, float)):
        return math.sqrt(sphere**2 - radius**2) - (sphere - depth)
    from ngsolve import sqrt
    return sqrt(sphere**2 - radius * radius) - (sphere - depth)
