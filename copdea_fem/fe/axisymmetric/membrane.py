r"""The membrane on the meridian: one energy, written for one circumferential order m.

Reference: the flat pre-stretched annulus ``r_i < R < r_o`` (the line z = 0 of
the meridian mesh, :mod:`.meridian`), polar angle Theta.  A displacement
``U = U_r e_r + U_theta e_theta + U_z e_z`` (functions of R, Theta; spatial
basis at the reference angle) moves ``x = R e_r + U``, so in the orthonormal
bases (e_R, e_Theta) of the reference and (e_r, e_theta, e_z) of space::

    F = P + G,    G = [[U_r,R,  (U_r,Theta - U_theta)/R,  0],
                       [U_theta,R, (U_r + U_theta,Theta)/R, 0],
                       [U_z,R,  U_z,Theta / R,           0]]

with P = diag(1, 1, 0): the same 3x3 "surface gradient" the 3-D engine takes
from ``Grad(u).Trace()`` (:func:`copdea_fem.fe.membrane.invariants`), so the
energy density is :func:`copdea_fem.fe.membrane.energy_density` itself -- no second
constitutive implementation.

Prestress (axisymmetric, no torsion): ``U = u_r(R) e_r + u_z(R) e_z``,
``G0 = [[u_r', 0, 0], [0, u_r/R, 0], [u_z', 0, 0]]``; energy
``2 pi int W(G0) R dR``.

Order m >= 1 (the cos family; the sin family is the same pencil rotated by
pi/(2m)): ``U = (a cos m Theta, b sin m Theta, c cos m Theta)`` gives
``G = G_c cos m Theta + G_s sin m Theta``::

    G_c = [[a', 0, 0], [0, (a + m b)/R, 0], [c', 0, 0]]
    G_s = [[0, -(m a + b)/R, 0], [b', 0, 0], [0, -m c/R, 0]]

The Hessian of the energy about the axisymmetric state is a quadratic form in
G; integrated over Theta the cross terms cos sin vanish and
``int cos^2 = int sin^2 = pi``, so the order-m stiffness is the Hessian at 0 of

    pi int [W(G0 + G_c) + W(G0 + G_s)] R dR         (m >= 1)
    2 pi int W(G0 + G_c + G_s) R dR  (m = 0, b = torsion U_theta = b(R))

(G_c, G_s are linear in (a, b, c): the Hessian of W(G0 + G_c) is
G_c : W'' : G_c).  Mass ``Theta_m rho_s int (a^2 + b^2 + c^2) R dR``,
``Theta_m = 2 pi`` (m = 0) or pi.  Masses and energies are those of the whole
device for the cos-family field.

Axis (full membrane, r_i = 0): a field is single-valued at R = 0 when
m = 0: a = b = 0;  m = 1: c = 0 and a + b = 0 (the displacement is a constant
vector there);  m >= 2: a = b = c = 0.  For m = 1 the unknown is
``beta = a + b`` instead of b, fixed at the centre.
"""

from __future__ import annotations

import ngsolve as ngs

from copdea_fem.fe.axisymmetric.meridian import theta_integral
from copdea_fem.fe.membrane import cf_entries, energy_density, material_energy_density


def radius():
    """Reference radius R [m]: the meridian's x coordinate."""
    return ngs.x


def d_dr(u):
    """dU/dR of a scalar field along the membrane line z = 0 of the meridian."""
    return ngs.grad(u).Trace()[0]


def prestress_gradient(u):
    """G0 of the axisymmetric prestress (3x3, module doc); ``u`` = (u_r, u_z) on the line."""
    derivative = ngs.Grad(u).Trace()            # 2x2: d/dx (= d/dR) in column 0
    return cf_entries((derivative[0, 0], 0, 0, 0, u[0] / radius(), 0, derivative[1, 0], 0, 0),
                      dims=(3, 3))


def harmonic_gradients(m: int, a, b, c, da, db, dc):
    """(G_c, G_s) of the order-m cos family (module doc); values and R-derivatives."""
    R = radius()
    cos_part = cf_entries((da, 0, 0, 0, (a + m * b) / R, 0, dc, 0, 0), dims=(3, 3))
    sin_part = cf_entries((0, -(m * a + b) / R, 0, db, 0, 0, 0, -m * c / R, 0), dims=(3, 3))
    return cos_part, sin_part


def prestress_energy(u, material, voltage):
    """Energy density 2 pi R W(G0) per unit reference radius [J/m] (integrate ds)."""
    return 2 * ngs.pi * radius() * energy_density(None, material, voltage,
                                                   gradient=prestress_gradient(u))


def order_energy(m, base, amplitudes, material, voltage, theta=None, material_only=False):
    """Energy whose Hessian at 0 is the order-m stiffness (module doc) [J/m].

    ``m``: the order, an int or an NGSolve Parameter (then m >= 1); ``theta``
    replaces Theta_m (e.g. 1 when the caller scales); ``material_only``: the energy whose
    Hessian is the material part of the tangent alone
    (:func:`copdea_fem.fe.membrane.material_energy_density`, no voltage).
    ``base``: the prestress (u_r, u_z) (GridFunction on the membrane line),
    ``amplitudes`` = ((a, da), (b, db), (c, dc)) of the order-m field.
    """
    (a, da), (b, db), (c, dc) = amplitudes
    g0 = prestress_gradient(base)
    g_c, g_s = harmonic_gradients(m, a, b, c, da, db, dc)
    weight = (theta_integral(m) if theta is None else theta) * radius()

    def w(gradient):
        if material_only:       # Hessian at 0 = the material part only (Prony branches)
            return material_energy_density(g0, gradient - g0, material)
        return energy_density(None, material, voltage, gradient=gradient)

    if isinstance(m, int) and m == 0:
        return weight * w(g0 + g_c + g_s)
    return weight * (w(g0 + g_c) + w(g0 + g_s))
