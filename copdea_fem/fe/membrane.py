"""Membrane kinematics and energy on the flat pre-stretched reference (Sect. 3.1).

Pure functions that return NGSolve spaces, CoefficientFunctions and forms;
nothing here assembles or solves.

Reference configuration: the flat pre-stretched membrane in the plane z = 0
(radii r_i, r_o).  A material point is displaced by ``u`` (3 components, m)
from there.  The in-plane deformation from the *unstretched* film is
``F = lambda_p (P + Grad_s u)`` on the tangent plane, ``P = I - e_z e_z``, and
with ``C2 = F^T F`` restricted to the tangent plane

    tr_c  = lambda_p^2 (tr(Ct) - 1),     det_c = lambda_p^4 det(Ct),
    Ct    = (P + Grad_s u)^T (P + Grad_s u) + e_z e_z^T     (3x3, det Ct = det C2).

Energy (eq. 2 in variational form, eq. 7 + 20):
``E(u) = h0 / lambda_p^2 * integral over S of Psi_em(tr_c, det_c; V) dS``
(the integral is over the pre-stretched area; ``dS0 = dS / lambda_p^2``).
Its first variation is the internal-force part of eq. (2); its Hessian is the
exact tangent: material + initial-stress + electrostatic terms in one.

Imperfect films (:mod:`copdea_fem.study.imperfections`).  An anisotropic pre-stretch
maps the unstretched film onto the reference by ``F_p = lambda_p R diag(1 + e, 1 - e)
R^T`` (``R`` the rotation by the axis angle alpha), symmetric, so the deformation from the
unstretched film is ``F = (P + Grad_s u) F_p`` and

    tr_c  = tr(D^T D B_p),   det_c = det(B_p) det(Ct),   D = P + Grad_s u,
    B_p   = F_p F_p^T = lambda_p^2 R diag((1 + e)^2, (1 - e)^2) R^T   (in-plane block),

with ``det(B_p) = lambda_p^4 (1 - e^2)^2`` (e = 0: the equibiaxial formulas above).  The
rim stays the circle r_o, so u = 0 is the clamped, homogeneous, anisotropic state the
prestress starts from.  The film's volume per pre-stretched area is ``h0 / det F_p =
h0 / (lambda_p^2 (1 - e^2))``.  A thickness variation makes ``h0`` a field
``h0 t(theta)``, ``t = 1 + sum a cos k (theta - angle)``, on the reference (theta the
reference angle; the film is mapped homogeneously, so the same profile in the film's
material angle differs by O(e a), a second-order term the keys do not try to resolve):
the strain energy and the mass scale with ``t``, the co-energy per volume
``-eps/2 (V / (h0 t))^2 det_c`` with ``1/t^2``, so the energy per reference area is
``h0 t / det F_p (Psi_m - eps/2 (V/h0)^2 det_c / t^2)``.
"""

from __future__ import annotations

import math

import ngsolve as ngs

from copdea_fem.fe.materials import Membrane

NORMAL_REF = (0.0, 0.0, 1.0)  # unit normal N of the flat reference, +z side
#: The constant CoefficientFunctions 1 and 0, made once (:func:`cf_entries`).
ONE, ZERO = ngs.CF(1.0), ngs.CF(0.0)


def cf_entries(values, dims=None):
    """A vector (or, with ``dims``, matrix) CoefficientFunction of ``values``: numbers or
    CoefficientFunctions, a 0 entered as :data:`ZERO` and any other number as a product
    with :data:`ONE`.  NGSolve's CoefficientFunction constructor converts a Python number
    inside a tuple far more slowly (a fraction of a millisecond each) than it multiplies
    one; the forms built per solve (the perturbation path's, each order's) are built from
    many of these."""
    entries = tuple(value if isinstance(value, ngs.CoefficientFunction) else
                    ZERO if value == 0 else float(value) * ONE for value in values)
    return ngs.CF(entries) if dims is None else ngs.CF(entries, dims=dims)


#: P = I - e_z e_z and e_z e_z^T (3x3, module doc).
PROJECTOR = cf_entries((1, 0, 0, 0, 1, 0, 0, 0, 0), dims=(3, 3))
NORMAL_DYAD = cf_entries((0, 0, 0, 0, 0, 0, 0, 0, 1), dims=(3, 3))


def displacement_space(mesh, order: int, has_disc: bool, complex_: bool = False):
    """Vector H1 field on the ``membrane`` faces, zero on the rims (Dirichlet, eq. 3).

    The rims are Dirichlet edges; the disc motion enters through their values
    (prestress) or through a rigid-body lift (disc on the spring).
    """
    rims = "outer_rim|inner_rim" if has_disc else "outer_rim"
    space = ngs.VectorH1(mesh, order=order, definedon=mesh.Boundaries("membrane"),
                         dirichlet_bbnd=rims, complex=complex_)
    return ngs.Compress(space)


def membrane_measure(mesh, order: int, curve_order: int):
    """ds on the membrane faces, with enough quadrature for curved elements.

    The default rule (2 * order) integrates the gradients of a degree-``order``
    field exactly only on straight elements; on elements curved to degree
    ``curve_order`` > ``order`` the flat, uniformly stretched state is then not
    an exact discrete equilibrium (residual ~5e-4 of the rim reactions for
    order 2 on a curve-3 mesh).  Raising the rule by 2 (curve_order - order)
    restores it to round-off (checked in the tests).
    """
    return ngs.ds(definedon=mesh.Boundaries("membrane"),
                  bonus_intorder=2 * max(0, curve_order - order))


def tangent_gradient(u):
    """Surface gradient Grad_s u (3x3) on the flat reference."""
    return ngs.Grad(u).Trace()


def invariants(u, prestretch: float, gradient=None, anisotropy: float = 0.0,
               axis: float = 0.0):
    """(tr_c, det_c) of the in-plane Cauchy-Green tensor from the unstretched film.

    ``gradient`` (Grad_s u) may be given instead of ``u``, for sums of fields
    (``u0 + u`` in the coupled step) whose gradient NGSolve cannot take.  ``anisotropy``
    e and ``axis`` alpha [rad]: the anisotropic pre-stretch of the module notes.
    """
    deformation = PROJECTOR + (tangent_gradient(u) if gradient is None else gradient)
    ct = deformation.trans * deformation + NORMAL_DYAD
    return _invariants_of(ct, prestretch, anisotropy, axis)


def _invariants_of(ct, prestretch: float, anisotropy: float, axis: float):
    """(tr_c, det_c) of ``Ct = D^T D + e_z e_z`` (module notes)."""
    if anisotropy == 0:
        return prestretch**2 * (ngs.Trace(ct) - 1), prestretch**4 * ngs.Det(ct)
    along, across = (prestretch * (1 + anisotropy))**2, (prestretch * (1 - anisotropy))**2
    c, s = math.cos(axis), math.sin(axis)
    b_xx, b_yy = c * c * along + s * s * across, s * s * along + c * c * across
    b_xy = c * s * (along - across)
    stretch_dyad = cf_entries((b_xx, b_xy, 0, b_xy, b_yy, 0, 0, 0, 0), dims=(3, 3))
    # tr(Ct B_p) = Ct : B_p (B_p symmetric): nine products, not a 3x3 matrix product's 27
    return ngs.InnerProduct(ct, stretch_dyad), along * across * ngs.Det(ct)


def thickness_factor(material: Membrane):
    """t(theta) = 1 + sum a cos k (theta - angle) on the reference [-] (module notes), a
    CoefficientFunction; 1.0 (a number) for a film of even thickness."""
    if not material.thickness_variation:
        return 1.0
    theta = ngs.atan2(ngs.y, ngs.x)
    return 1 + sum(amplitude * ngs.cos(order * (theta - angle))
                   for order, amplitude, angle in material.thickness_variation)


def areal_density(material: Membrane):
    """Mass per reference area rho0 h0 t / (lambda_p^2 (1 - e^2)) [kg/m^2] (module notes):
    ``material.areal_density`` (a number) for a film of even thickness, else a
    CoefficientFunction."""
    factor = thickness_factor(material)
    return material.areal_density if isinstance(factor, float) else \
        material.areal_density * factor


def energy_density(u, material: Membrane, voltage, gradient=None):
    """Membrane energy per pre-stretched area h0/lambda_p^2 Psi_em [J/m^2] (eq. 7, 20);
    for an imperfect film h0 t / (lambda_p^2 (1 - e^2)) (Psi_m + Psi_e / t^2) (module
    notes).

    ``voltage`` may be a number or an NGSolve Parameter [V]; ``gradient`` as
    in :func:`invariants`.
    """
    tr_c, det_c = invariants(u, material.prestretch, gradient, material.anisotropy,
                             material.anisotropy_axis)
    if material.uniform:
        return material.thickness / material.prestretch**2 * material.free_energy(
            tr_c, det_c, voltage)
    factor = thickness_factor(material)
    return material.prestretched_thickness * factor * (
        material.strain_energy(tr_c, det_c)
        + material.electrostatic_coenergy(det_c, voltage) / factor**2)


def material_energy_density(base_gradient, increment_gradient, material: Membrane):
    """Strain energy per pre-stretched area whose Hessian at a zero increment is the
    MATERIAL part of the tangent only [J/m^2] (for the Prony branches,
    :mod:`copdea_fem.fe.linearise`).

    The whole tangent is ``d2/du2 Psi(C(u0 + u))`` = ``Psi'' : dC : dC`` (material) +
    ``Psi' : d2C`` (initial stress) + the electrostatic terms.  With ``Ct`` replaced by
    its linearisation about the prestress, ``Ct0 + D0^T g + g^T D0`` (``D0 = P +
    Grad_s u0``, ``g = Grad_s u``, affine in ``u``: ``d2C = 0``), the Hessian of the strain
    energy alone (eq. 20, no co-energy) is exactly ``Psi'' : dC : dC``.  A flat membrane
    (``Grad_s u0`` in-plane) has ``dC = 0`` for an out-of-plane ``u``: its out-of-plane
    rows vanish (docs/damping.md).
    """
    base = PROJECTOR + base_gradient
    ct = (base.trans * base + base.trans * increment_gradient + increment_gradient.trans * base
          + NORMAL_DYAD)
    stretch = material.prestretch
    if material.uniform:
        tr_c, det_c = stretch**2 * (ngs.Trace(ct) - 1), stretch**4 * ngs.Det(ct)
        return material.thickness / stretch**2 * material.strain_energy(tr_c, det_c)
    tr_c, det_c = _invariants_of(ct, stretch, material.anisotropy, material.anisotropy_axis)
    return material.prestretched_thickness * thickness_factor(material) * \
        material.strain_energy(tr_c, det_c)


def deformed_normal(u):
    """Unit normal of the deformed surface, n = (F e_x x F e_y)/|.| (points to +z at z = 0)."""
    deformation = PROJECTOR + tangent_gradient(u)
    t1 = deformation * ngs.CF((1, 0, 0))
    t2 = deformation * ngs.CF((0, 1, 0))
    normal = ngs.Cross(t1, t2)
    return normal / ngs.Norm(normal)


def principal_stretches(u, prestretch: float, anisotropy: float = 0.0, axis: float = 0.0):
    """In-plane principal stretches (larger, smaller) from the unstretched film [-]
    (``anisotropy``, ``axis``: as in :func:`invariants`)."""
    tr_c, det_c = invariants(u, prestretch, None, anisotropy, axis)
    disc = ngs.sqrt(ngs.IfPos(tr_c**2 - 4 * det_c, tr_c**2 - 4 * det_c, 0))
    return ngs.sqrt((tr_c + disc) / 2), ngs.sqrt((tr_c - disc) / 2)


def field_coefficients(u, material: Membrane, voltage: float) -> dict:
    """Post-processing fields of the prestressed state (SI units) as CFs; with a thickness
    variation t the thickness, the field and the principal stresses' Maxwell part
    -eps (V / (h0 t lambda_3))^2 are the local ones (module notes)."""
    lam1, lam2 = principal_stretches(u, material.prestretch, material.anisotropy,
                                     material.anisotropy_axis)
    _, det_c = invariants(u, material.prestretch, None, material.anisotropy,
                          material.anisotropy_axis)
    local_voltage = voltage / thickness_factor(material)    # V / t: the field V / (h0 t)
    d_tr, d_det, *_ = material.free_energy_partials(lam1**2 + lam2**2, lam1**2 * lam2**2,
                                                    local_voltage)
    sigma1 = 2 * lam1**2 * (d_tr + lam2**2 * d_det)    # materials.Membrane.principal_stresses
    sigma2 = 2 * lam2**2 * (d_tr + lam1**2 * d_det)
    return {
        "displacement": u,
        "stretch_1": lam1,
        "stretch_2": lam2,
        "stress_1": sigma1,
        "stress_2": sigma2,
        "thickness": material.thickness_at(det_c) * thickness_factor(material),
        "e_field": material.electric_field(det_c, voltage) / thickness_factor(material),
        "normal": deformed_normal(u),
    }
