"""Moving the air mesh with the prestressed membrane (ALE, Sect. 5.1).

The acoustic terms are assembled on the deformed air (eq. 8 is Eulerian), the
membrane terms on the flat reference (eq. 2 is Lagrangian).  One mesh serves
both: the air gets the mesh deformation ``D`` computed here, set with
``mesh.SetDeformation(D)`` while the air and coupling forms are assembled.

``D`` must equal the membrane displacement u0 on ``membrane``, the rigid lift
z e_z on ``disc``, and zero on ``frame``, ``aperture`` and the PML, and it
must not invert any element.  A harmonic or elastic extension of these data
inverts elements at the inner rim for z ~ 16 mm (the data have a kink there,
DESIGN.md).  The prestressed state is axisymmetric, so a transfinite
extension is available in closed form and is a bijection by construction: with
(rho, theta, zeta) cylindrical coordinates of the flat reference,

    D(rho, theta, zeta) = (u_rho(rho) e_rho + w(rho) e_z) * phi(zeta),
    phi(zeta) = (1 - |zeta| / L)^2 for |zeta| < L, 0 beyond,

where w, u_rho are the membrane's axial and radial displacement profiles
(w = z, u_rho = 0 under the disc; both 0 outside r_o).  Along every vertical
line the map zeta -> zeta + w phi(zeta) is strictly increasing when
|w| < L/2 (phi' >= -2/L), so the two air halves never overlap; the rest is a
shear (det 1) plus the small radial motion u_rho.  The decay length L
(:func:`copdea_fem.fe.airbox.ale_decay_length`) keeps D inside the air sphere, away from
the PML; phi is C1 at |zeta| = L.  D has kinks where w has: across the rims
r = r_i, r_o (slope of the membrane vs the flat disc / frame) and across the
plane; the mesh conforms to all of them (the ``ale_guide`` cylinders and the
plane faces), so no element straddles a kink and the interpolated D keeps
the positive Jacobian of the exact map.  Every element's Jacobian
determinant is checked.
"""

from __future__ import annotations

import ngsolve as ngs
import numpy as np

from copdea_fem.fe.airbox import ale_decay_length

MIN_JACOBIAN = 0.2   # det(I + Grad D) below this at any point = badly distorted element


class MeshMotionError(RuntimeError):
    """The air mesh cannot follow the membrane without inverting elements."""


def displacement_profile(state, samples: int = 200, angles: int = 16):
    """Radial profiles rho [m], u_rho [m], w [m] of the prestress, averaged over theta."""
    r_o, r_i = state.outer_radius, state.inner_radius
    radii = r_i + (r_o - r_i) * (np.arange(samples) + 0.5) / samples
    thetas = state.symmetry.angles(angles)
    rr, tt = np.meshgrid(radii, thetas, indexing="ij")
    points = state.mesh(rr.ravel() * np.cos(tt.ravel()), rr.ravel() * np.sin(tt.ravel()),
                        np.zeros(rr.size), ngs.BND)
    values = np.asarray(state.displacement(points)).reshape(samples, angles, 3)
    radial = (values[..., 0] * np.cos(tt) + values[..., 1] * np.sin(tt)).mean(axis=1)
    axial = values[..., 2].mean(axis=1)
    rho = np.concatenate([[r_i], radii, [r_o]])
    return rho, np.concatenate([[0.0], radial, [0.0]]), np.concatenate([[state.z], axial, [0.0]])


def _piecewise_linear(xs: np.ndarray, values: np.ndarray, argument, outside_low, outside_high):
    """Linear interpolation of ``values`` at ``xs`` as a CF of ``argument``, constant outside."""
    spline = ngs.BSpline(2, [float(xs[0])] + [float(v) for v in xs] + [float(xs[-1])],
                         [float(v) for v in values])
    inside = spline(argument)
    return ngs.IfPos(xs[0] - argument, outside_low,
                     ngs.IfPos(argument - xs[-1], outside_high, inside))


def checked_decay_length(state, domain_radius: float) -> float:
    """The decay length L [m] (:func:`copdea_fem.fe.airbox.ale_decay_length`); MeshMotionError
    when the
    disc lift z is too large for it (|z| < L/2 keeps the map monotone, 0.45 L a margin)."""
    length = ale_decay_length(domain_radius, state.outer_radius)
    if abs(state.z) >= 0.45 * length:
        raise MeshMotionError(
            f"load.z = {state.z * 1e3:.1f} mm is too large for the air mesh: it must stay below "
            f"0.45 L = {0.45 * length * 1e3:.1f} mm (L = the height over which the air follows "
            "the membrane, half the air radius); raise air.domain_radius")
    return length


#: Floor [m] of the decay length L in phi = (1 - |z|/L)^2: far below any mesh size, so that
#: it changes nothing but a zero depth (a bowl's rim) into a finite phi.
SHORTEST_DECAY_LENGTH = 1e-12


def transfinite_factors(rho, radial, axial, z_disc: float, radius, height, length: float):
    """(u_rho, w, phi) of the transfinite map (module doc) as CoefficientFunctions.

    ``rho, radial, axial``: the prestress profiles [m] on r_i..r_o; w = z under the disc
    and 0 beyond r_o, u_rho = 0 outside; ``radius``, ``height``: the CFs of the
    cylindrical radius and the height above the plane.  ``length`` (a float or a CF [m])
    is taken as at least :data:`SHORTEST_DECAY_LENGTH`: an enclosure's depth falls to 0 at
    the rim of a bowl (exactly 0 on a hemisphere, and beyond its rim), where u_rho = w = 0
    and phi only has to stay finite (0 / 0 would make the whole motion NaN).
    """
    w = _piecewise_linear(rho, axial, radius, z_disc, 0.0)
    u_rho = _piecewise_linear(rho, radial, radius, 0.0, 0.0)
    if isinstance(length, (int, float)):
        length = max(length, SHORTEST_DECAY_LENGTH)
    else:
        length = ngs.IfPos(length - SHORTEST_DECAY_LENGTH, length, SHORTEST_DECAY_LENGTH)
    inside = 1 - ngs.sqrt(height**2) / length
    return u_rho, w, ngs.IfPos(inside, inside**2, 0.0)


def follow_membrane(mesh, state, extension, order: int = 2):
    """Mesh deformation D of ``extension`` on a 3-D or meridian mesh, the membrane carrying
    the FE prestress itself (not its interpolated profile); Jacobians checked."""
    space = ngs.VectorH1(mesh, order=order)
    motion = ngs.GridFunction(space, name="air_mesh_displacement")
    motion.Set(extension)
    on_membrane = ngs.GridFunction(space)
    on_membrane.Set(state.displacement, ngs.BND, definedon=mesh.Boundaries("membrane"))
    dofs = np.array(space.GetDofs(mesh.Boundaries("membrane")))
    motion.vec.FV().NumPy()[dofs] = on_membrane.vec.FV().NumPy()[dofs]
    check_jacobian(mesh, motion)
    return motion


def air_mesh_displacement(state, mesh, domain_radius: float, order: int = 2,
                          cavity_depth=None):
    """Mesh deformation D (VectorH1 on the whole mesh) for the prestressed state [m].

    ``cavity_depth``: over an enclosure, its depth below the plane as a function of the
    cylindrical radius (``radius -> CoefficientFunction`` [m], for radii up to r_o): below
    the plane L is that depth, so the motion stops at the cavity's bottom (the transfinite
    map stays monotone while |w| < L/2 there, which the caller checks); the outside air
    below lies beyond the bottom or beyond r_o and stays put, and the enclosure's walls are
    set exactly to 0."""
    length = checked_decay_length(state, domain_radius)
    rho_cf = ngs.sqrt(ngs.x**2 + ngs.y**2 + 1e-30)
    rho, radial, axial = displacement_profile(state) if state.has_disc or state.z else (
        np.array([0.0, state.outer_radius]), np.zeros(2), np.zeros(2))
    if cavity_depth is not None:
        column = ngs.IfPos(rho_cf - state.outer_radius, state.outer_radius, rho_cf)
        length = ngs.IfPos(ngs.z, length, cavity_depth(column))
    u_rho, w, phi = transfinite_factors(rho, radial, axial, state.z, rho_cf, ngs.z, length)
    motion = follow_membrane(mesh, state, ngs.CF((u_rho * ngs.x / rho_cf,
                                                  u_rho * ngs.y / rho_cf, w)) * phi, order)
    if cavity_depth is not None:     # the walls exactly in place (Set projects)
        walls = np.array(motion.space.GetDofs(mesh.Boundaries("enclosure|vent")))
        motion.vec.FV().NumPy()[walls] = 0.0
    return motion


def check_jacobian(mesh, motion) -> float:
    """Smallest det(I + Grad D) over the air elements (3-D or meridian mesh); raises
    MeshMotionError if too small."""
    rule = ngs.IntegrationRule(ngs.TET if mesh.dim == 3 else ngs.TRIG, 4)
    points = mesh.MapToAllElements(rule, ngs.VOL)
    jacobian = ngs.Det(ngs.Id(mesh.dim) + ngs.Grad(motion))
    values = np.asarray(jacobian(points)).ravel()
    smallest = float(values.min())
    if smallest < MIN_JACOBIAN:
        where = np.asarray(ngs.CF((ngs.x, ngs.y, ngs.z) if mesh.dim == 3 else (ngs.x, ngs.y))(
            points))[int(values.argmin())]
        place = ", ".join(f"{value * 1e3:.1f}" for value in where)
        raise MeshMotionError(
            f"the air mesh following the membrane is {'inverted' if smallest <= 0 else 'badly distorted'} "
            f"(det(I + Grad D) = {smallest:.3g} < {MIN_JACOBIAN} near "
            f"{'x' if mesh.dim == 3 else '(r, z)'} = ({place}) mm); refine the membrane "
            "(mesh.membrane_size) or lower load.z")
    return smallest
