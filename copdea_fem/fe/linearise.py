"""Linearised membrane operators about a prestressed state (Sect. 3.1.3).

``K_s`` is the Hessian of the same energy the prestress step minimises
(:func:`copdea_fem.fe.membrane.energy_density` at the bias voltage V_b), so it
holds the material, initial-stress and electrostatic terms exactly, without a
separate hand-written form.  ``M_s`` is the consistent mass of the film,
``rho0 h0 / lambda_p^2 * integral of u . v dS`` over the pre-stretched area.

Unknowns: the free membrane DOFs (rims fixed), plus -- when the disc rides on
the biasing spring (``disc.motion: spring``) -- one rigid axial disc DOF
``w_d`` [m] that moves the inner rim: ``u = u_free + w_d * lift``.  The disc
adds mass ``M_d + M_s/3`` (Rayleigh's equivalent mass of a spring with a
linear static deflection profile; the spring's own wave modes P2, P3, ... are
Annex I's business) and stiffness ``k_d`` (eq. 4, linear spring); the point masses on the
disc (``imperfections.point_masses``, r <= r_i) add to ``M_d``, those on the membrane
enter ``M_s`` as lumped masses (:func:`point_mass_matrix`).

On a quadrant mesh (:mod:`copdea_fem.fe.symmetry`) the operators are those of one sector:
its mirror conditions remove DOFs, the disc DOF exists in the even-even
sector only, and the disc's mass and stiffness enter divided by 4.

Damping (:func:`damping_terms`, study keys ``membrane.rayleigh_alpha/beta`` and
``membrane.prony``).  Rayleigh: ``C = alpha M_s + beta K_s`` on the same unknowns (the
disc's lumped mass and spring included).  Prony (generalised Maxwell): the long-term
(relaxed) law is eq. (20), which the prestress uses; branch ``j`` adds a spring
``g_j K_mat`` (``K_mat`` the MATERIAL part of the tangent,
:func:`copdea_fem.fe.membrane.material_energy_density`) in series with a dashpot of time
``tau_j``.  With the branch's internal displacement ``q_j`` the energy and dissipation
are ``E = 1/2 u^T K_s u + sum_j 1/2 g_j (u - q_j)^T K_mat (u - q_j)``, ``D = sum_j 1/2
g_j tau_j q_j'^T K_mat q_j'``, and Lagrange-Rayleigh gives ``M u'' + C u' + K_s u + sum_j
g_j K_mat (u - q_j) = 0`` and ``g_j K_mat (tau_j q_j' + q_j - u) = 0``, i.e. ``tau_j
q_j' + q_j = u``.  The branch carries no stress in the prestressed equilibrium (relaxed),
so it adds no initial-stress term.  For ``e^{-i omega t}``, ``q_j = u / (1 - i omega
tau_j)`` and the stiffness becomes ``K_s + sum_j g_j K_mat (-i omega tau_j) / (1 - i omega
tau_j)``: relaxed (``K_s``) for ``omega tau -> 0``, glassy (``K_s + sum g_j K_mat``) for
``omega tau -> inf``.  :mod:`copdea_fem.fe.eigen.damped` solves the resulting rational
eigenproblem exactly by its linearisation with ``q_j`` as unknowns.
"""

from __future__ import annotations

from dataclasses import dataclass

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp

from copdea_fem.fe.eigen.damped import DampingTerms
from copdea_fem.fe.membrane import (
    areal_density,
    energy_density,
    material_energy_density,
    tangent_gradient,
)
from copdea_fem.fe.prestress import PrestressedState, disc_point_mass
from copdea_fem.fe.symmetry import MIRROR_NUDGE, SECTORS, Sector, membrane_mirror_dofs


@dataclass
class MembraneOperators:
    """K_s [N/m] and M_s [kg] on the reduced unknowns, and how to map back.

    ``free_dofs``: indices of the membrane space's free DOFs, in the order of
    the first ``len(free_dofs)`` unknowns; if ``disc_dof`` is True the last
    unknown is the disc displacement w_d.  ``sector``: the mirror-symmetry
    class on a quadrant mesh (:class:`copdea_fem.fe.symmetry.Sector`), else None.
    ``disc_mass``: the lumped disc mass ``M_d + M_s/3`` in the disc unknown's row, on
    the meshed part of the device [kg] (a quarter of it on a quadrant), 0 without the
    disc DOF; ``mass[-1, -1]`` adds to it the membrane mass the rim lift carries.
    """

    stiffness: sp.csr_matrix
    mass: sp.csr_matrix
    free_dofs: np.ndarray
    disc_dof: bool
    state: PrestressedState
    sector: Sector | None = None
    disc_mass: float = 0.0

    @property
    def size(self) -> int:
        return self.stiffness.shape[0]

    def to_full(self, vectors: np.ndarray) -> np.ndarray:
        """Reduced vectors (size x k) -> full membrane-space coefficient vectors."""
        vectors = np.atleast_2d(vectors.T).T
        full = np.zeros((self.state.space.ndof, vectors.shape[1]), dtype=vectors.dtype)
        full[self.free_dofs] = vectors[: len(self.free_dofs)]
        if self.disc_dof:
            lift = self.state.disc_lift.vec.FV().NumPy()
            full += np.outer(lift, vectors[-1])
        return full


def to_scipy(matrix) -> sp.csr_matrix:
    """NGSolve sparse matrix -> SciPy CSR (all entries, also for symmetric storage)."""
    rows, cols, values = matrix.COO()
    shape = (matrix.height, matrix.width)
    return sp.csr_matrix((np.asarray(values), (np.asarray(rows), np.asarray(cols))), shape=shape)


def membrane_matrices(state: PrestressedState):
    """Full-space Hessian K [N/m] and consistent mass M [kg] (SciPy CSR), assembled once per
    state (kept in ``state.matrices``: the modes, the coupled step and the sweep's tracking
    all use these)."""
    if state.matrices is not None:
        return state.matrices
    space, material = state.space, state.material
    u, v = space.TnT()
    on_membrane = state.measure
    hessian = ngs.BilinearForm(space, symmetric=False)
    hessian += ngs.Variation(energy_density(u, material, state.voltage) * on_membrane)
    hessian.AssembleLinearization(state.displacement.vec)
    mass = ngs.BilinearForm(areal_density(material) * u * v * on_membrane,
                            symmetric=False).Assemble()
    mass = to_scipy(mass.mat)
    if state.point_masses:
        mass = (mass + point_mass_matrix(state)).tocsr()
    state.matrices = (to_scipy(hessian.mat), mass)
    return state.matrices


def point_mass_matrix(state: PrestressedState) -> sp.csr_matrix:
    """The lumped masses of ``state.point_masses`` on the full membrane space [kg]:
    ``sum_j m_j / copies * sum_c phi_c(x_j) phi_c(x_j)^T`` (``phi_c(x)`` the values of the
    basis functions' component c at the point: a point evaluation, rank 3 per mass --
    kinetic energy m |u(x_j)|^2 / 2 of a mass riding with the film in every direction; on
    a quadrant mesh a quarter, :mod:`copdea_fem.fe.symmetry`).

    The basis values come from the element that holds the point: one unit coefficient at
    a time on its DOFs, the field evaluated there (at most a few dozen DOFs a point).  On a
    quadrant the centre lies on both mirror faces, where a point search may return a face
    of the air: the point moves into the quadrant by :data:`~copdea_fem.fe.symmetry.
    MIRROR_NUDGE` of r_o (the field changes by that share)."""
    space, mesh = state.space, state.mesh
    probe = ngs.GridFunction(space)
    values = probe.vec.FV().NumPy()
    rows, cols, data = [], [], []
    for mass, x, y in state.point_masses:
        if state.symmetry.quarter:     # only a mass at the centre keeps the mirror planes
            step = MIRROR_NUDGE * state.outer_radius
            x, y = max(x, step), max(y, step)
        point = mesh(x, y, 0.0, ngs.BND)
        if point.nr < 0 or mesh[ngs.ElementId(ngs.BND, point.nr)].mat != "membrane":
            raise ValueError(f"imperfections.point_masses: the point ({x:g}, {y:g}) m lies off "
                             "the meshed membrane; allowed: points on the membrane")
        dofs = [dof for dof in space.GetDofNrs(ngs.ElementId(ngs.BND, point.nr)) if dof >= 0]
        basis = np.zeros((3, len(dofs)))
        for column, dof in enumerate(dofs):
            values[:] = 0.0
            values[dof] = 1.0
            basis[:, column] = probe(point)
        block = mass / state.symmetry.copies * (basis.T @ basis)
        rows += np.repeat(dofs, len(dofs)).tolist()
        cols += np.tile(dofs, len(dofs)).tolist()
        data += block.ravel().tolist()
    return sp.csr_matrix((data, (rows, cols)), shape=(space.ndof, space.ndof))


def material_tangent(state: PrestressedState) -> sp.csr_matrix:
    """Full-space material part of the tangent K_mat [N/m] (SciPy CSR; see
    :func:`copdea_fem.fe.membrane.material_energy_density`), kept in ``state`` once assembled."""
    cached = getattr(state, "material_matrix", None)
    if cached is not None:
        return cached
    space, material = state.space, state.material
    u = space.TrialFunction()
    form = ngs.BilinearForm(space, symmetric=False)
    form += ngs.Variation(material_energy_density(tangent_gradient(state.displacement),
                                                  tangent_gradient(u), material)
                          * state.measure)
    zero = ngs.GridFunction(space)
    form.AssembleLinearization(zero.vec)
    state.material_matrix = to_scipy(form.mat)
    return state.material_matrix


def damping_terms(stiffness, mass, membrane, material=None) -> DampingTerms | None:
    """The damping of a membrane pencil (module doc): ``C = alpha M + beta K`` and the
    Prony branches ``(g_j K_mat, tau_j)``; None without damping keys (the linear path).

    ``stiffness, mass``: ``K_s`` [N/m], ``M_s`` [kg] on the pencil's unknowns;
    ``membrane``: the study's section ``study.membrane``; ``material``: a callable returning
    ``K_mat`` on the same unknowns, called only when ``membrane.prony`` is given.
    """
    alpha, beta = membrane.rayleigh_alpha, membrane.rayleigh_beta
    prony = membrane.prony
    if not (alpha or beta or prony):
        return None
    damping = (alpha * mass + beta * stiffness).tocsr() if (alpha or beta) else None
    relaxation = []
    if prony:
        tangent = material()
        relaxation = [(term.modulus_ratio * tangent, term.relaxation_time)
                      for term in prony]
    return DampingTerms(damping, relaxation)


def operator_damping(operators: MembraneOperators, study) -> DampingTerms | None:
    """:func:`damping_terms` of one (sector's) :class:`MembraneOperators`."""
    def reduced_material():
        full = material_tangent(operators.state)
        free = operators.free_dofs
        block = full[free][:, free]
        if operators.disc_dof:      # the rim lift strains the film; the spring is elastic
            block = _border(block, full, operators.state.disc_lift.vec.FV().NumPy(), free, 0.0)
        return block.tocsr()
    return damping_terms(operators.stiffness, operators.mass, study.membrane,
                         reduced_material)


def linearised_operators(state: PrestressedState, study, sector: Sector | None = None,
                         matrices=None) -> MembraneOperators:
    """K_s, M_s on the free DOFs (+ the disc DOF when the disc rides on the spring).

    ``sector``: on a quadrant mesh, the symmetry class (default: even-even);
    ``matrices``: :func:`membrane_matrices` of ``state`` if already assembled.
    """
    stiffness, mass = matrices or membrane_matrices(state)
    symmetry = state.symmetry
    if symmetry.quarter and sector is None:
        sector = SECTORS[0]
    free_mask = np.array(state.space.FreeDofs())
    free_mask[membrane_mirror_dofs(state.space, state.mesh, study.mesh.order, sector)] = False
    free = np.flatnonzero(free_mask)
    k_ff, m_ff = stiffness[free][:, free], mass[free][:, free]
    with_disc = (study.disc.motion == "spring" and state.has_disc
                 and (sector is None or sector == SECTORS[0]))
    disc_mass = 0.0
    if with_disc:
        lift = state.disc_lift.vec.FV().NumPy()
        spring = study.spring
        disc_mass = (study.disc.mass + disc_point_mass(study) + spring.mass / 3) / \
            symmetry.copies
        k_ff = _border(k_ff, stiffness, lift, free, spring.stiffness / symmetry.copies)
        m_ff = _border(m_ff, mass, lift, free, disc_mass)
    return MembraneOperators(k_ff.tocsr(), m_ff.tocsr(), free, with_disc, state, sector,
                             disc_mass)


def _border(block, full, lift, free, extra):
    """[[A_ff, A l_f], [l^T A_f, l^T A l + extra]] for u = u_free + w_d * lift."""
    column = full @ lift
    corner = float(lift @ column) + extra
    return sp.bmat([[block, sp.csr_matrix(column[free][:, None])],
                    [sp.csr_matrix(column[free][None, :]), sp.csr_matrix([[corner]])]])
