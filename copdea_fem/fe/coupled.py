"""Fully-coupled membrane-air eigenproblem about the prestressed state (Sect. 3.1.3).

Unknowns ``x = (u, p)``: the membrane displacement on its free DOFs (plus the
rigid disc DOF when the disc rides on the spring) [m] and the air pressure with
its jump across the screens [Pa] (:func:`copdea_fem.fe.acoustics.pressure_space`).  With
the forms of :mod:`copdea_fem.fe.acoustics` (eq. A3 there)::

    [ K_s  C^T ] x = omega^2 [ M_s   0  ] x,      C_ij = int_screens [p'_i] (u_j . n) ds
    [ 0    K_a ]             [ -C   M_a ]

``K_s, M_s`` come from :mod:`copdea_fem.fe.linearise` (flat reference, Lagrangian);
``K_a, M_a, C`` are assembled on the deformed air (:mod:`copdea_fem.fe.ale`, Eulerian)
with the PML set, so the pencil is complex and non-symmetric.  The air rows and the
pressure unknowns are scaled (``p = beta p^``, air rows times ``alpha``) so
that all blocks have the size of ``K_s``; the eigenvalues do not change and the
relative residuals of :mod:`copdea_fem.fe.eigen` then weigh both physics alike.

:func:`assemble_coupled` assembles the forms once on all DOFs;
:meth:`CoupledAssembly.restrict` cuts out the pencil of one mirror-symmetry
sector on a quadrant mesh (:mod:`copdea_fem.fe.symmetry`), or the whole pencil.

Modes whose kinetic energy lies mostly in the air (``air.min_membrane_energy``)
are air/PML modes (``kind = "air"``).  Each structural mode is matched to the
dry mode of the same operators (same mesh) by label and by the modal assurance
criterion of the membrane displacement; ``added_mass_ratio = (f_dry/f)^2 - 1``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp

from copdea_fem.fe import acoustics
from copdea_fem.fe.airbox import cavity_depth
from copdea_fem.fe.ale import air_mesh_displacement
from copdea_fem.fe.eigen import Factorization, NativeShiftedInverse
from copdea_fem.fe.linearise import MembraneOperators, point_mass_matrix, to_scipy
from copdea_fem.fe.membrane import (
    areal_density,
    displacement_space,
    energy_density,
    tangent_gradient,
)
from copdea_fem.fe.prestress import disc_point_mass

logger = logging.getLogger(__name__)


@dataclass
class CoupledOperators:
    """The scaled pencil A x = omega^2 B x and what is needed to read its vectors.

    Unknowns are the free DOFs of the product space ``(u, p, q[, w_d])``
    assembled natively complex in NGSolve; ``membrane_index`` picks the
    membrane's free DOFs (then the disc DOF) out of them in the order of
    :class:`MembraneOperators`, ``pressure_index`` the pressure DOFs.
    """

    stiffness: sp.csr_matrix            # A (scaled)
    mass: sp.csr_matrix                 # B (scaled)
    membrane: MembraneOperators
    pressure_space: object
    pressure_free: np.ndarray           # free pressure DOFs, positions in pressure_space
    pressure_index: np.ndarray          # their positions among the unknowns
    membrane_index: np.ndarray          # membrane free DOFs (+ disc) among the unknowns
    pressure_scale: float               # beta [Pa per unknown]
    air_kinetic: sp.csr_matrix          # (1/rho_a) int_air grad p . grad p' (no PML)
    mesh_motion: object                 # ALE deformation D (GridFunction)
    factorize: object                   # sigma -> factorisation of A - sigma B (eigen hook)

    @property
    def membrane_size(self) -> int:
        return self.membrane.size


def _pressure_sign_fixed_normal():
    """Unit normal of the deformed screens pointing to the + (upper) side."""
    normal = ngs.specialcf.normal(3)
    return ngs.IfPos(normal[2], 1.0, -1.0) * normal


def assemble_coupled(study, mesh, state) -> "CoupledAssembly":
    """Assemble the coupled forms natively complex on the deformed air with the PML.

    The membrane terms (Hessian of the energy about u0, mass) are integrated on
    the flat reference; the air and coupling terms with the ALE deformation
    ``D`` (``dx(..., deformation=D)``).  The disc on the spring is a
    :class:`ngsolve.NumberSpace` unknown ``w_d`` moving the inner rim through
    the lift of :mod:`copdea_fem.fe.linearise` (``u = u_free + w_d lift``), with mass
    ``M_d + M_s/3`` and stiffness ``k_d`` spread over the disc face (a quadrant
    mesh's disc face carries a quarter of them, :mod:`copdea_fem.fe.symmetry`).  One
    assembly serves every symmetry sector: :meth:`CoupledAssembly.restrict`.  Point masses
    on the disc add to ``M_d``; point masses on the membrane add their lumped
    masses (:func:`copdea_fem.fe.linearise.point_mass_matrix`) to the membrane block.
    """
    air, geometry = study.air, study.geometry
    closed = geometry.enclosure != "none"
    outside = air.outside or not closed
    screens = acoustics.enclosure_screen_faces(geometry.frame, outside) if closed else \
        acoustics.screen_faces(geometry.frame)
    if geometry.inner_radius == 0:
        screens = "|".join(face for face in screens.split("|") if face != "disc")
    logger.info("air mesh follows the membrane (ALE) ...")
    def depth(radius):         # the air inside follows the membrane down to the bottom
        return cavity_depth(geometry.enclosure, geometry.enclosure_depth,
                            geometry.enclosure_radius, radius)

    motion = air_mesh_displacement(state, mesh, air.domain_radius,
                                   cavity_depth=depth if closed else None)
    # a square frame beyond a cylinder's or bowl's rim separates the outside halves too
    frame_beyond_rim = closed and outside and geometry.frame == "square" \
        and geometry.enclosure != "box"
    pressure_space = acoustics.pressure_space(mesh, study.mesh.pressure_order, screens,
                                              vacuum_above=not outside,
                                              outside_jump=frame_beyond_rim)
    membrane_space = displacement_space(mesh, study.mesh.order, state.has_disc,
                                        complex_=True)
    if membrane_space.ndof != state.space.ndof:
        raise RuntimeError("complex and real membrane spaces differ; cannot couple")
    with_disc = study.disc.motion == "spring" and state.has_disc
    spaces = [membrane_space, *pressure_space.components]
    disc_component = len(spaces)       # after (p, q) or (p, q, q_o): acoustics.pressure_space
    if with_disc:
        spaces.append(ngs.NumberSpace(mesh, complex=True))
    space = ngs.FESpace(spaces)
    trial, test = space.TrialFunction(), space.TestFunction()
    lift = state.disc_lift
    u = trial[0] + trial[disc_component] * lift if with_disc else trial[0]
    v = test[0] + test[disc_component] * lift if with_disc else test[0]
    pressure = tuple(trial[1:disc_component])
    pressure_test = tuple(test[1:disc_component])
    normal = _pressure_sign_fixed_normal()
    material, measure = state.material, state.measure
    density, sound_speed = air.density, air.sound_speed
    if with_disc:       # the device's disc area: lumped terms per unit area of the disc face
        disc_area = state.symmetry.copies * ngs.Integrate(ngs.CF(1) * ngs.ds("disc"), mesh)
        disc_mass = study.disc.mass + disc_point_mass(study) + study.spring.mass / 3

    gradient = tangent_gradient(state.displacement) + tangent_gradient(trial[0])
    if with_disc:
        gradient = gradient + trial[disc_component] * tangent_gradient(lift)
    stiffness = ngs.BilinearForm(space)
    stiffness += ngs.Variation(energy_density(None, material, state.voltage, gradient=gradient)
                               * measure)
    # eq. (A3) with the tested forms (copdea_fem.fe.acoustics.coupled_forms); k_s is the
    # Variation above
    coupling_and_air, membrane_mass_and_air = acoustics.coupled_forms(
        pressure, pressure_test, u * normal, v * normal, None,
        areal_density(material) * u * v * measure, density, sound_speed, "membrane",
        deformation=motion)
    stiffness += coupling_and_air
    mass = ngs.BilinearForm(space)
    mass += membrane_mass_and_air
    if with_disc:
        disc, disc_test = trial[disc_component], test[disc_component]
        stiffness += (study.spring.stiffness / disc_area) * disc * disc_test * ngs.ds("disc")
        disc_traction, disc_acceleration = acoustics.coupling_forms(
            pressure, pressure_test, disc * normal[2], disc_test * normal[2], "disc",
            deformation=motion)
        stiffness += disc_traction
        mass += (disc_mass / disc_area) * disc * disc_test * ngs.ds("disc")
        mass += disc_acceleration

    logger.info(f"assembling the coupled operators ({space.ndof} DOFs) ...")
    zero = ngs.GridFunction(space)
    kinetic = ngs.BilinearForm(space)
    kinetic += _physical_air_energy(pressure, pressure_test, density, motion)
    kinetic.Assemble()                   # before the PML: a real energy norm
    if outside:
        acoustics.set_pml(mesh, air.domain_radius, air.pml_thickness)
    try:
        stiffness.AssembleLinearization(zero.vec)      # Hessian at u0 (E(u0 + u) at u = 0)
        mass.Assemble()
    finally:
        if outside:
            mesh.UnSetPML(acoustics.PML_REGIONS)
    if stiffness.mat.nze != mass.mat.nze:  # A - sigma B is formed entry by entry
        raise RuntimeError("coupled stiffness and mass have different sparsity patterns")
    if state.point_masses:      # the membrane is the product space's first component
        add_in_pattern(mass.mat, point_mass_matrix(state))
    offsets = np.cumsum([0] + [component.ndof for component in spaces])
    return CoupledAssembly(study, state, space, offsets, with_disc, stiffness.mat, mass.mat,
                           to_scipy(stiffness.mat), to_scipy(mass.mat), to_scipy(kinetic.mat),
                           pressure_space, motion)


def add_in_pattern(matrix, extra: sp.spmatrix) -> None:
    """Add ``extra`` (SciPy, on the first ``extra.shape[0]`` DOFs) to the NGSolve sparse
    ``matrix`` in place, entry by entry within its pattern (its values, ``AsVector``, are
    stored in the order of ``COO``: rows ascending); an entry outside the pattern is an
    error (the lumped masses of :func:`copdea_fem.fe.linearise.point_mass_matrix` couple
    the DOFs of one membrane element, which the membrane's mass form couples already)."""
    rows, columns, _ = matrix.COO()
    rows, columns = np.asarray(rows), np.asarray(columns)
    values = matrix.AsVector().FV().NumPy()
    extra = extra.tocoo()
    for row, column, value in zip(extra.row, extra.col, extra.data):
        start, stop = np.searchsorted(rows, row, "left"), np.searchsorted(rows, row, "right")
        found = start + np.flatnonzero(columns[start:stop] == column)
        if found.size != 1:
            raise RuntimeError(f"entry ({row}, {column}) lies outside the matrix's pattern")
        values[found[0]] += value


@dataclass
class CoupledAssembly:
    """The assembled coupled forms on all DOFs of ``(u, p, q[, w_d])``, for every sector."""

    study: dict
    state: object
    space: object                       # the product FESpace
    offsets: np.ndarray                 # first DOF of each component in ``space``
    with_disc: bool                     # the disc's NumberSpace is the last component
    stiffness_matrix: object            # NGSolve (complex, PML set at assembly)
    mass_matrix: object
    stiffness: sp.csr_matrix            # the same, SciPy
    mass: sp.csr_matrix
    kinetic: sp.csr_matrix              # physical air energy (no PML), SciPy
    pressure_space: object
    mesh_motion: object

    def release(self) -> None:
        """Free the whole-space matrices once every sector is restricted: the SciPy copies,
        and the NGSolve ones unless the sectors factorise natively in NGSolve (``umfpack``,
        ``pardiso``).  The 0.65 m drum: ~0.5 GB of its peak during the eigen stage."""
        self.stiffness = self.mass = self.kinetic = None
        if self.study.eigen.backend == "superlu":
            self.stiffness_matrix = self.mass_matrix = None

    def restrict(self, operators: MembraneOperators) -> "CoupledOperators":
        """The scaled pencil of the sector of ``operators`` (None on a whole mesh)."""
        from copdea_fem.fe.symmetry import membrane_mirror_dofs, pressure_mirror_dofs

        if self.stiffness is None:
            raise RuntimeError("CoupledAssembly.restrict after release()")

        sector, state, offsets = operators.sector, self.state, self.offsets
        mesh = state.mesh
        free_mask = np.array(self.space.FreeDofs())
        free_mask[offsets[0] + membrane_mirror_dofs(state.space, mesh,
                                                    self.study.mesh.order, sector)] = False
        free_mask[offsets[1] + pressure_mirror_dofs(self.pressure_space, mesh, sector)] = False
        pressure_end = offsets[1] + self.pressure_space.ndof     # the disc DOF, if any
        if self.with_disc and not operators.disc_dof:     # the disc moves in even-even only
            free_mask[pressure_end] = False
        free = np.flatnonzero(free_mask)
        position = -np.ones(self.space.ndof, dtype=int)
        position[free] = np.arange(free.size)
        membrane_index = position[offsets[0] + operators.free_dofs]
        if operators.disc_dof:
            membrane_index = np.append(membrane_index, position[pressure_end])
        if np.any(membrane_index < 0) or membrane_index.size != operators.size:
            raise RuntimeError("coupled and membrane free DOFs disagree")
        pressure_global = np.arange(offsets[1], pressure_end)
        pressure_global = pressure_global[free_mask[pressure_global]]
        pressure_index = position[pressure_global]
        pressure_free = pressure_global - offsets[1]
        a_full = self.stiffness[free][:, free].tocsr()
        b_full = self.mass[free][:, free].tocsr()
        air_kinetic = self.kinetic[pressure_global][:, pressure_global].tocsr()

        is_air = np.zeros(free.size, dtype=bool)
        is_air[pressure_index] = True
        a_scaled, b_scaled, beta, row_scale, column_scale = scaled_pencil(a_full, b_full, is_air)
        backend = self.study.eigen.backend

        def factorize(sigma: float):
            if backend == "superlu":      # SciPy factorises the complex scaled pencil natively
                return Factorization((a_scaled - sigma * b_scaled).tocsc(), backend)
            return NativeShiftedInverse(self.stiffness_matrix, self.mass_matrix, free_mask,
                                         sigma, row_scale, column_scale, backend)

        return CoupledOperators(a_scaled, b_scaled, operators, self.pressure_space,
                                pressure_free, pressure_index, membrane_index, beta,
                                air_kinetic, self.mesh_motion, factorize)


def _physical_air_energy(pressure, pressure_test, density, motion):
    """``(1/rho_a) int_air grad p . grad p' dx`` over the air of every region (not the PML),
    on the deformed air: the kinetic energy of the air that classifies modes."""
    total = None
    for (air, _, value), (_, _, test) in zip(acoustics.region_pressures(pressure),
                                             acoustics.region_pressures(pressure_test)):
        term = (1.0 / density) * ngs.grad(value) * ngs.grad(test) * ngs.dx(
            air, deformation=motion)
        total = term if total is None else total + term
    return total


def scaled_pencil(a_full, b_full, is_air):
    """Scale the air unknowns and rows (module doc): ``p = beta p^``, air rows times alpha,
    with beta = |K_s| / |C| and alpha = |K_s| / (beta |K_a|) (max-norms), so every block
    has the size of ``K_s``; returns (A scaled, B scaled, beta, row scale, column scale).

    The norms and the scaling work on the CSR entries (each entry knows its row and
    column), without slicing the blocks out or multiplying by diagonal matrices."""
    a_full, b_full = a_full.tocsr(), b_full.tocsr()
    a_rows, b_rows = _entry_rows(a_full), _entry_rows(b_full)
    membrane_block = ~is_air[a_rows] & ~is_air[a_full.indices]
    k_s = _block_norm(a_full, membrane_block)
    beta = k_s / _block_norm(b_full, is_air[b_rows] & ~is_air[b_full.indices])
    alpha = k_s / (beta * _block_norm(a_full, is_air[a_rows] & is_air[a_full.indices]))
    row_scale, column_scale = np.where(is_air, alpha, 1.0), np.where(is_air, beta, 1.0)
    return (_scaled(a_full, a_rows, row_scale, column_scale),
            _scaled(b_full, b_rows, row_scale, column_scale), beta, row_scale, column_scale)


def _entry_rows(matrix) -> np.ndarray:
    """The row of every stored entry of a CSR matrix."""
    return np.repeat(np.arange(matrix.shape[0]), np.diff(matrix.indptr))


def _block_norm(matrix, entries) -> float:
    """Max-norm of the stored entries selected by ``entries`` (1 for an empty block)."""
    values = matrix.data[entries]
    return float(np.abs(values).max()) if values.size else 1.0


def _scaled(matrix, rows, row_scale, column_scale):
    """``diag(row_scale) matrix diag(column_scale)`` (CSR; stored zeros dropped, as the
    product by diagonal matrices does)."""
    scaled = matrix.copy()
    scaled.data = matrix.data * (row_scale[rows] * column_scale[matrix.indices])
    scaled.eliminate_zeros()
    return scaled
