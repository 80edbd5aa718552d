r"""Order-m operators of the axisymmetric engine: dry (K_s, M_s) and coupled pencils.

Membrane unknowns of order m: the amplitudes (a, b, c) of
``(u_r, u_theta, u_z) = (a cos m theta, b sin m theta, c cos m theta)`` on the
membrane line (:mod:`.membrane`); for m = 0 also the rigid disc displacement
``w_d`` [m] when the disc rides on the spring (``u_z = c + w_d lift`` on the
inner rim; mass ``M_d + M_s/3`` and stiffness ``k_d``, as in
:mod:`copdea_fem.linearise`).  The disc moves axially only, so for m >= 1 the
inner rim is clamped.  ``K_s`` is the Hessian of the order-m energy of
:func:`.membrane.order_energy` at the prestress, ``M_s`` the consistent mass;
both refer to the whole device (the theta integral is done).

Coupled (eq. A3 of :mod:`copdea_fem.acoustics`, in cylindrical coordinates,
the pressure ``p(r, z) cos m theta``)::

    k_a = Theta_m int (1/rho_a) (grad p . grad p' + m^2/r^2 p p') r dA
    m_a = Theta_m int 1/(rho_a c_a^2) p p' r dA
    c   = Theta_m int_screens [p'] (a n_r + c n_z) r ds

on the deformed meridian (ALE, :func:`meridian_motion`), ``Theta_m = 2 pi``
(m = 0) or pi.  In the PML shell the 3-D stretch ``x~ = x r~/r`` (spherical
``r``) acts in the meridian as ``J2 = s I + (r~' - s) e e^T`` (``s = r~/r``,
``e`` the unit radial vector of the (r, z) plane) and stretches the hoop
direction by ``s``, so ``dV~ = s det J2 r dA dtheta`` and ``1/r~ = 1/(s r)``::

    k_a,pml = Theta_m int (1/rho_a) (J2^-1 grad p . J2^-1 grad p' + m^2/(s r)^2 p p') s det(J2) r dA
    m_a,pml = Theta_m int 1/(rho_a c_a^2) p p' s det(J2) r dA

with the unbounded profile of :func:`copdea_fem.acoustics.radial_pml`.  On the
axis r = 0 the pressure of an order m >= 1 vanishes.
"""

from __future__ import annotations

from dataclasses import dataclass

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp

from ..linearise import to_scipy
from .membrane import d_dr, order_energy, radius
from .meridian import theta_integral


@dataclass
class OrderOperators:
    """K_s [N/m] and M_s [kg] of one circumferential order on the free DOFs.

    ``free_dofs``: positions in ``space`` of the unknowns (then ``w_d`` last
    when ``disc_dof``); ``space`` is the product (a, b, c) space of the order.
    """

    m: int
    stiffness: sp.csr_matrix
    mass: sp.csr_matrix
    space: object
    free_dofs: np.ndarray
    disc_dof: bool
    lift: object                 # GridFunction of ``space``: unit u_z on the inner rim (or None)
    axis_m1: bool                # m = 1 on a full membrane: component 1 is beta = a + b
    state: object
    mass_full: sp.csr_matrix = None       # M_s on all DOFs of ``space`` (for MAC) [kg]

    @property
    def size(self) -> int:
        return self.stiffness.shape[0]

    def to_full(self, vectors: np.ndarray) -> np.ndarray:
        """Reduced vectors (size x k) -> coefficient vectors of ``space`` (incl. the disc lift)."""
        vectors = np.atleast_2d(vectors.T).T
        full = np.zeros((self.space.ndof, vectors.shape[1]), dtype=vectors.dtype)
        full[self.free_dofs] = vectors[: len(self.free_dofs)]
        if self.disc_dof:
            full += np.outer(self.lift.vec.FV().NumPy(), vectors[-1])
        return full

    def amplitudes(self, gf):
        """(a, b, c) CoefficientFunctions of a GridFunction of ``space``."""
        a, second, c = gf.components
        return a, (second - a if self.axis_m1 else second), c


def order_space(mesh, order: int, m: int, has_disc: bool, complex_: bool = False):
    """Product H1 space (a, b, c) on the membrane line for order m, rims clamped.

    A full membrane (no disc) is also fixed at the centre as single-valuedness
    demands (:mod:`.membrane`): m = 0 a, b; m = 1 beta = a + b and c; m >= 2 all.
    """
    rims = "outer_rim|inner_rim" if has_disc else "outer_rim"
    at_centre = (set() if has_disc else
                 {0: {0, 1}, 1: {1, 2}}.get(m, {0, 1, 2}))
    components = [ngs.Compress(ngs.H1(mesh, order=order, definedon=mesh.Boundaries("membrane"),
                                      dirichlet_bbnd=rims + ("|centre" if k in at_centre else ""),
                                      complex=complex_))
                  for k in range(3)]
    # compress each component: Compress of the product forgets the Dirichlet DOFs
    return ngs.FESpace(components)


def _amplitude_proxies(function, axis_m1: bool, lift=None, disc=None):
    """((a, da), (b, db), (c, dc)) of a trial/test function (+ w_d * lift on c)."""
    a, second, c = function[0], function[1], function[2]
    da, dsecond, dc = d_dr(a), d_dr(second), d_dr(c)
    b, db = (second - a, dsecond - da) if axis_m1 else (second, dsecond)
    if disc is not None:
        lift_c = lift.components[2]
        c, dc = c + disc * lift_c, dc + disc * d_dr(lift_c)
    return (a, da), (b, db), (c, dc)


def membrane_forms(state, m: int, trial, test, axis_m1: bool, lift=None, disc=(None, None)):
    """(energy integrand, mass integrand) of the membrane for order m (module doc)."""
    material = state.material
    energy = order_energy(m, state.displacement, _amplitude_proxies(trial, axis_m1, lift, disc[0]),
                          material, state.voltage)
    u = _amplitude_proxies(trial, axis_m1, lift, disc[0])
    v = _amplitude_proxies(test, axis_m1, lift, disc[1])
    mass = theta_integral(m) * material.areal_density * radius() * sum(
        ui[0] * vi[0] for ui, vi in zip(u, v))
    return energy * state.measure, mass * state.measure


def rim_lift(space, state):
    """GridFunction of ``space``: u_z = 1 on the inner rim, 0 on every free DOF."""
    r_o, r_i = state.outer_radius, state.inner_radius
    lift = ngs.GridFunction(space)
    lift.components[2].Set(ngs.log(r_o / ngs.x) / np.log(r_o / r_i), ngs.BND,
                           definedon=space.mesh.Boundaries("membrane"))
    values = lift.vec.FV().NumPy()
    values[np.array(space.FreeDofs())] = 0.0
    return lift


def order_operators(state, study, m: int) -> OrderOperators:
    """Dry K_s, M_s of order m about the prestressed ``state`` (SciPy CSR, whole device)."""
    mesh, order = state.mesh, study["mesh"]["order"]
    axis_m1 = m == 1 and not state.has_disc
    space = order_space(mesh, order, m, state.has_disc)
    with_disc = m == 0 and state.has_disc and study["disc"]["motion"] == "spring"
    lift = rim_lift(space, state) if with_disc else None
    trial, test = space.TnT()
    energy, mass_form = membrane_forms(state, m, trial, test, axis_m1)
    hessian = ngs.BilinearForm(space, symmetric=False)
    hessian += ngs.Variation(energy)
    hessian.AssembleLinearization(ngs.GridFunction(space).vec)     # E(u0 + u) at u = 0
    mass = ngs.BilinearForm(mass_form, symmetric=False).Assemble()
    stiffness, mass = to_scipy(hessian.mat), to_scipy(mass.mat)
    free = np.flatnonzero(np.array(space.FreeDofs()))
    k_ff, m_ff = stiffness[free][:, free], mass[free][:, free]
    if with_disc:
        spring = study["spring"]
        vector = lift.vec.FV().NumPy()
        k_ff = _border(k_ff, stiffness, vector, free, spring["stiffness"])
        m_ff = _border(m_ff, mass, vector, free, study["disc"]["mass"] + spring["mass"] / 3)
    return OrderOperators(m, k_ff.tocsr(), m_ff.tocsr(), space, free, with_disc, lift,
                          axis_m1, state, mass)


def _border(block, full, lift, free, extra):
    """[[A_ff, A l_f], [l^T A_f, l^T A l + extra]] for u = u_free + w_d * lift."""
    column = full @ lift
    corner = float(lift @ column) + extra
    return sp.bmat([[block, sp.csr_matrix(column[free][:, None])],
                    [sp.csr_matrix(column[free][None, :]), sp.csr_matrix([[corner]])]])


@dataclass
class CoupledOrderOperators:
    """The scaled coupled pencil of one order and what is needed to read its vectors
    (the axisymmetric counterpart of :class:`copdea_fem.coupled.CoupledOperators`)."""

    m: int
    stiffness: sp.csr_matrix            # A (scaled)
    mass: sp.csr_matrix                 # B (scaled)
    membrane: OrderOperators            # the dry operators of the same order
    pressure_space: object
    pressure_free: np.ndarray           # free pressure DOFs, positions in pressure_space
    pressure_index: np.ndarray          # their positions among the unknowns
    membrane_index: np.ndarray          # membrane free DOFs (+ disc) among the unknowns
    pressure_scale: float               # beta [Pa per unknown]
    air_kinetic: sp.csr_matrix          # Theta_m (1/rho_a) int_air |grad p|^2 r dA (no PML)
    mesh_motion: object
    factorize: object                   # sigma -> factorisation of A - sigma B

    @property
    def membrane_size(self) -> int:
        return self.membrane.size


def coupled_order_operators(state, study, dry: OrderOperators, motion) -> CoupledOrderOperators:
    """Membrane + air pencil of order ``dry.m`` (module doc), scaled as in
    :func:`copdea_fem.coupled.scaled_pencil`."""
    from .. import acoustics
    from ..coupled import scaled_pencil
    from ..eigen import Factorization
    from .air import air_forms, air_kinetic_form, screen_coupling, screen_normal

    m, mesh = dry.m, state.mesh
    air, geometry = study["air"], study["geometry"]
    screens = acoustics.screen_faces(geometry["frame"])
    if not state.has_disc:
        screens = "|".join(face for face in screens.split("|") if face != "disc")
    pressure_space = acoustics.pressure_space(mesh, study["mesh"]["pressure_order"], screens,
                                              also_dirichlet="axis" if m > 0 else "")
    membrane_space = order_space(mesh, study["mesh"]["order"], m, state.has_disc,
                                 complex_=True)
    spaces = [membrane_space, *pressure_space.components]
    if dry.disc_dof:
        spaces.append(ngs.NumberSpace(mesh, complex=True))
    space = ngs.FESpace(spaces)
    trial, test = space.TrialFunction(), space.TestFunction()
    lift = dry.lift        # real GridFunction: NGSolve's energy forms take no complex data
    disc = (trial[3], test[3]) if dry.disc_dof else (None, None)
    energy, mass_form = membrane_forms(state, m, trial[0], test[0], dry.axis_m1, lift, disc)
    pressure, pressure_test = (trial[1], trial[2]), (test[1], test[2])
    normal = screen_normal()
    u = _amplitude_proxies(trial[0], dry.axis_m1, lift, disc[0])
    v = _amplitude_proxies(test[0], dry.axis_m1, lift, disc[1])
    u_normal = u[0][0] * normal[0] + u[2][0] * normal[1]
    v_normal = v[0][0] * normal[0] + v[2][0] * normal[1]
    k_air, m_air = air_forms(m, pressure, pressure_test, air["density"], air["sound_speed"],
                             air["domain_radius"], air["pml_thickness"], deformation=motion)
    stiffness = ngs.BilinearForm(space)
    stiffness += ngs.Variation(energy)
    stiffness += screen_coupling(m, pressure, v_normal, "membrane", deformation=motion)
    stiffness += k_air
    mass = ngs.BilinearForm(space)
    mass += mass_form
    mass += (-1.0) * screen_coupling(m, pressure_test, u_normal, "membrane", deformation=motion)
    mass += m_air
    if dry.disc_dof:
        stiffness += screen_coupling(m, pressure, test[3] * normal[1], "disc", deformation=motion)
        mass += (-1.0) * screen_coupling(m, pressure_test, trial[3] * normal[1], "disc",
                                         deformation=motion)
    kinetic = ngs.BilinearForm(space)
    kinetic += air_kinetic_form(m, pressure, pressure_test, air["density"], deformation=motion)
    stiffness.AssembleLinearization(ngs.GridFunction(space).vec)   # Hessian at u0 (u = 0)
    mass.Assemble()
    kinetic.Assemble()
    a_all, b_all = to_scipy(stiffness.mat).tolil(), to_scipy(mass.mat).tolil()
    offsets = np.cumsum([0] + [component.ndof for component in spaces])
    if dry.disc_dof:               # lumped disc + spring (linearise.py), on the w_d unknown
        spring = study["spring"]
        a_all[offsets[3], offsets[3]] += spring["stiffness"]
        b_all[offsets[3], offsets[3]] += study["disc"]["mass"] + spring["mass"] / 3
    free = np.flatnonzero(np.array(space.FreeDofs()))
    position = -np.ones(space.ndof, dtype=int)
    position[free] = np.arange(free.size)
    membrane_index = position[offsets[0] + dry.free_dofs]
    if dry.disc_dof:
        membrane_index = np.append(membrane_index, position[offsets[3]])
    if np.any(membrane_index < 0) or membrane_index.size != dry.size:
        raise RuntimeError("coupled and membrane free DOFs disagree")
    pressure_global = free[(free >= offsets[1]) & (free < offsets[3])]
    pressure_index = position[pressure_global]
    a_full = a_all.tocsr()[free][:, free]
    b_full = b_all.tocsr()[free][:, free]
    is_air = np.zeros(free.size, dtype=bool)
    is_air[pressure_index] = True
    a_scaled, b_scaled, beta, _, _ = scaled_pencil(a_full, b_full, is_air)
    backend = study["eigen"]["backend"]
    air_kinetic = to_scipy(kinetic.mat)[pressure_global][:, pressure_global].tocsr()

    def factorize(sigma: float):
        return Factorization((a_scaled - sigma * b_scaled).tocsc(), backend)

    return CoupledOrderOperators(m, a_scaled, b_scaled, dry, pressure_space,
                                 pressure_global - offsets[1], pressure_index, membrane_index,
                                 beta, air_kinetic, motion, factorize)
