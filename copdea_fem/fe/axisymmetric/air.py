r"""Air of order m on the meridian: the forms of :mod:`copdea_fem.fe.acoustics` in (r, z).

Pure functions returning NGSolve integrands (see :mod:`.operators` for the
equations).  Regions, screens, pressure-jump space ``(p, q)`` and the
unbounded PML profile are those of the 3-D engine; here the PML stretch is
written into the integrands (the hoop stretch ``s`` has no place in NGSolve's
2-D PML), so no ``SetPML`` is needed.  The air forms are integrated on the
deformed meridian (``deformation=D``, :func:`meridian_motion`), in which
``ngsolve.x`` is the deformed radius.
"""

from __future__ import annotations

import ngsolve as ngs
import numpy as np

from copdea_fem.fe.acoustics import PML_STRENGTH, radial_stretch
from copdea_fem.fe.axisymmetric.meridian import theta_integral


def pml_stretch(domain_radius: float, pml_thickness: float, strength: float = PML_STRENGTH):
    """(s, dr~/dr, e) of the unbounded radial profile (copdea_fem.fe.acoustics.radial_pml) in
    the meridian.

    ``r~ = rho + i b t ln(t / (R + t - rho))`` with rho the spherical radius;
    ``s = r~/rho``, ``e = (r, z)/rho``: :func:`copdea_fem.fe.acoustics.radial_stretch`, the
    profile of the 3-D engine's PML.
    """
    return radial_stretch((ngs.x, ngs.y), domain_radius, pml_thickness, strength)


def _off_axis(region: str, deformation):
    """dx for integrands with 1/r: a raised rule (NGSolve's order-2 triangle rule has its
    points on the edge midpoints (checked), on the axis r = 0 for an element touching it)."""
    return ngs.dx(region, deformation=deformation, bonus_intorder=2)


def _sides(pressure, pressure_test):
    """``(air volumes, PML volumes, pressure, test pressure)`` of each side of the screens:
    ``p`` on one, ``p + q`` on the other (the lower half, or the cavity of an enclosure:
    :func:`copdea_fem.fe.acoustics.pressure_regions`)."""
    from copdea_fem.fe.acoustics import pressure_regions

    (p, q), (p_test, q_test) = pressure, pressure_test
    for air, pml, with_q in pressure_regions(p.space.mesh):
        yield (air, pml, p + q, p_test + q_test) if with_q else (air, pml, p, p_test)


def air_form_parts(pressure, pressure_test, density: float, sound_speed: float,
                   domain_radius: float, pml_thickness: float, deformation=None):
    """Integrands (k0, k1, m_a) over air and PML with k_a(m) = Theta_m (k0 + m^2 k1),
    m_a(m) = Theta_m m_a (module doc of :mod:`.operators`): one assembly serves every order."""
    r = ngs.x
    compressibility = 1.0 / (density * sound_speed**2)
    s, derivative, e = pml_stretch(domain_radius, pml_thickness)
    radial = ngs.OuterProduct(e, e)
    j_inverse = (1 / s) * (ngs.Id(2) - radial) + (1 / derivative) * radial
    volume = s * (s * derivative) * r                    # s det(J2) r
    gradient_part = hoop_part = mass = 0
    for air_regions, pml_regions, p, p_test in _sides(pressure, pressure_test):
        if air_regions:
            air = ngs.dx(air_regions, deformation=deformation)
            gradient_part = gradient_part + ngs.grad(p) * ngs.grad(p_test) * r / density * air
            hoop_part = hoop_part + p * p_test / r / density * _off_axis(air_regions,
                                                                         deformation)
            mass = mass + compressibility * p * p_test * r * air
        if pml_regions:
            pml = ngs.dx(pml_regions, bonus_intorder=2)
            gradient_part = gradient_part + (j_inverse * ngs.grad(p)) * (
                j_inverse * ngs.grad(p_test)) * volume / density * pml
            hoop_part = hoop_part + p * p_test / (s * r) ** 2 * volume / density * pml
            mass = mass + compressibility * p * p_test * volume * pml
    return gradient_part, hoop_part, mass


def air_forms(m: int, pressure, pressure_test, density: float, sound_speed: float,
              domain_radius: float, pml_thickness: float, deformation=None):
    """(stiffness, mass) integrands k_a, m_a of order m over air and PML; per unit test
    pressure a volume acceleration / a volume."""
    gradient_part, hoop_part, mass = air_form_parts(pressure, pressure_test, density,
                                                    sound_speed, domain_radius, pml_thickness,
                                                    deformation)
    theta = theta_integral(m)
    return theta * (gradient_part + m**2 * hoop_part), theta * mass


def air_kinetic_parts(pressure, pressure_test, density: float, deformation=None):
    """(1/rho_a) int_air grad p . grad p' r dA and (1/rho_a) int_air p p' / r dA: the physical
    air's kinetic-energy norm of order m is Theta_m (first + m^2 second) (no PML)."""
    gradient_part = hoop_part = 0
    for air_regions, _, p, p_test in _sides(pressure, pressure_test):
        if air_regions:
            air = ngs.dx(air_regions, deformation=deformation)
            gradient_part = gradient_part + ngs.grad(p) * ngs.grad(p_test) * ngs.x / density * air
            hoop_part = hoop_part + p * p_test / ngs.x / density * _off_axis(air_regions,
                                                                             deformation)
    return gradient_part, hoop_part


def screen_normal():
    """Unit normal (n_r, n_z) of the deformed screens pointing to the + (upper) side."""
    normal = ngs.specialcf.normal(2)
    return ngs.IfPos(normal[1], 1.0, -1.0) * normal


def screen_coupling(m: int, pressure, normal_displacement, screens: str, deformation=None):
    """Theta_m int_screens [p] (u . n) r ds on the deformed screens ([p] = -q)."""
    return (theta_integral(m) * (-pressure[1]) * normal_displacement * ngs.x
            * ngs.ds(screens, deformation=deformation))


def meridian_motion(state, mesh, domain_radius: float, order: int = 2, cavity=None):
    r"""Mesh deformation D of the meridian for the prestress (transfinite, as in
    :mod:`copdea_fem.fe.ale`).

    ``D(r, z) = (u_r(r), w(r)) phi(z)``, ``phi = (1 - |z|/L)^2`` for |z| < L,
    with the prestress profiles on the membrane, ``w = z_disc`` under the disc
    and 0 beyond r_o; the mesh conforms to the kinks (``ale_guide`` lines), and
    the membrane line carries the FE prestress itself.  With an enclosure (``cavity``, a
    :class:`.meridian.Cavity`) L below the plane is the cavity's depth at r, so the walls
    stay put (phi = 0 on the bottom, w = u_r = 0 beyond r_o; their DOFs set to 0).
    """
    from copdea_fem.fe.ale import checked_decay_length, follow_membrane, transfinite_factors

    length = checked_decay_length(state, domain_radius)
    r_i, r_o = state.inner_radius, state.outer_radius
    radii = r_i + (r_o - r_i) * (np.arange(400) + 0.5) / 400
    profile = state.profile(radii)
    rho = np.concatenate([[r_i], radii, [r_o]])
    radial = np.concatenate([[0.0], profile[:, 0], [0.0]])
    axial = np.concatenate([[state.z], profile[:, 1], [0.0]])
    if cavity is not None:
        column = ngs.IfPos(ngs.x - cavity.radius, cavity.radius, ngs.x)
        length = ngs.IfPos(ngs.y, length, -cavity.bottom(column, sqrt=ngs.sqrt))
    u_r, w, phi = transfinite_factors(rho, radial, axial, state.z, ngs.x, ngs.y, length)
    motion = follow_membrane(mesh, state, ngs.CF((u_r, w)) * phi, order)
    if cavity is not None:       # the walls exactly in place (Set projects, ~1e-3 of w off)
        walls = np.array(motion.space.GetDofs(mesh.Boundaries("enclosure|vent")))
        motion.vec.FV().NumPy()[walls] = 0.0
    return motion
