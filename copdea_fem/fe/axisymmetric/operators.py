r"""Order-m operators of the axisymmetric engine: dry (K_s, M_s) and coupled pencils.

Membrane unknowns of order m: the amplitudes (a, b, c) of
``(u_r, u_theta, u_z) = (a cos m theta, b sin m theta, c cos m theta)`` on the
membrane line (:mod:`.membrane`); for m = 0 also the rigid disc displacement
``w_d`` [m] when the disc rides on the spring (``u_z = c + w_d lift`` on the
inner rim; mass ``M_d + M_s/3`` and stiffness ``k_d``, as in
:mod:`copdea_fem.fe.linearise`).  The disc moves axially only, so for m >= 1 the
inner rim is clamped.  ``K_s`` is the Hessian of the order-m energy of
:func:`.membrane.order_energy` at the prestress, ``M_s`` the consistent mass;
both refer to the whole device (the theta integral is done).

Coupled (eq. A3 of :mod:`copdea_fem.fe.acoustics`, in cylindrical coordinates,
the pressure ``p(r, z) cos m theta``)::

    k_a = Theta_m int (1/rho_a) (grad p . grad p' + m^2/r^2 p p') r dA
    m_a = Theta_m int 1/(rho_a c_a^2) p p' r dA
    c   = Theta_m int_screens [p'] (a n_r + c n_z) r ds

on the deformed meridian (ALE, :func:`copdea_fem.fe.axisymmetric.air.meridian_motion`),
``Theta_m = 2 pi`` (m = 0) or pi.  In the PML shell the 3-D stretch ``x~ = x r~/r`` (spherical
``r``) acts in the meridian as ``J2 = s I + (r~' - s) e e^T`` (``s = r~/r``,
``e`` the unit radial vector of the (r, z) plane) and stretches the hoop
direction by ``s``, so ``dV~ = s det J2 r dA dtheta`` and ``1/r~ = 1/(s r)``::

    k_a,pml = Theta_m int (1/rho_a) (J2^-1 grad p . J2^-1 grad p' + m^2/(s r)^2 p p') s det(J2) r dA
    m_a,pml = Theta_m int 1/(rho_a c_a^2) p p' s det(J2) r dA

with the unbounded profile of :func:`copdea_fem.fe.acoustics.radial_pml`.  On the
axis r = 0 the pressure of an order m >= 1 vanishes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp

from copdea_fem.fe.axisymmetric.membrane import d_dr, order_energy, radius
from copdea_fem.fe.axisymmetric.meridian import theta_integral
from copdea_fem.fe.bands import lowest_frequency_hz
from copdea_fem.fe.linearise import to_scipy


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
    disc_mass: float = 0.0                # lumped M_d + M_s/3 of the disc unknown [kg]
    #: M_n on all DOFs of ``space`` [kg] (:func:`normal_mass_form`;
    #: :func:`.modes.normal_mass_matrix`)
    normal_mass: sp.csr_matrix = field(default=None, repr=False, compare=False)

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


def amplitude_proxies(function, axis_m1: bool, lift=None, disc=None):
    """((a, da), (b, db), (c, dc)) of a trial/test function (+ w_d * lift on c)."""
    a, second, c = function[0], function[1], function[2]
    da, dsecond, dc = d_dr(a), d_dr(second), d_dr(c)
    b, db = (second - a, dsecond - da) if axis_m1 else (second, dsecond)
    if disc is not None:
        lift_c = lift.components[2]
        c, dc = c + disc * lift_c, dc + disc * d_dr(lift_c)
    return (a, da), (b, db), (c, dc)


def membrane_forms(state, m, trial, test, axis_m1: bool, lift=None, disc=(None, None),
                   theta=None, material_only=False):
    """(energy integrand, mass integrand) of the membrane for order m (module doc).

    ``m`` may be an NGSolve Parameter (m >= 1); ``theta`` replaces the theta integral
    Theta_m (1.0: the caller scales)."""
    material = state.material
    u = amplitude_proxies(trial, axis_m1, lift, disc[0])
    v = amplitude_proxies(test, axis_m1, lift, disc[1])
    energy = order_energy(m, state.displacement, u, material, state.voltage, theta=theta,
                          material_only=material_only)
    theta = theta_integral(m) if theta is None else theta
    mass = theta * material.areal_density * radius() * sum(
        ui[0] * vi[0] for ui, vi in zip(u, v))
    return energy * state.measure, mass * state.measure


def normal_mass_form(state, trial, test, theta: float):
    """``theta rho_s R (a n_r + c n_z)(a' n_r + c' n_z)`` on the membrane line: the integrand
    of M_n [kg], the mass of the normal part (n the prestressed normal, :mod:`.modes`)."""
    normal = state.fields()["normal"]

    def normal_part(function):
        a, _, c = function
        return a * normal[0] + c * normal[1]

    return (theta * state.material.areal_density * radius() * normal_part(trial)
            * normal_part(test) * state.measure)


def rim_lift(space, state):
    """GridFunction of ``space``: u_z = 1 on the inner rim, 0 on every free DOF."""
    r_o, r_i = state.outer_radius, state.inner_radius
    lift = ngs.GridFunction(space)
    lift.components[2].Set(ngs.log(r_o / ngs.x) / np.log(r_o / r_i), ngs.BND,
                           definedon=space.mesh.Boundaries("membrane"))
    values = lift.vec.FV().NumPy()
    values[np.array(space.FreeDofs())] = 0.0
    return lift


class OrderForms:
    """The membrane forms of every order on one prestressed state, built once.

    The order enters the harmonic energy (:mod:`.membrane`) through an NGSolve
    ``Parameter``, so one symbolic form serves m = 1, 2, ... (m = 0 has its own);
    a space is shared by all orders with the same rim and centre conditions.

    The Hessian is assembled for the first three orders of a space only.  ``G_c`` and
    ``G_s`` of :mod:`.membrane` are linear in m and the Hessian of ``W(G0 + G)`` at
    ``G = 0`` is a quadratic form in G, so every entry of the order-m stiffness is a
    polynomial of degree 2 in m: ``K(m) = sum_j L_j(m) K(m_j)`` with the Lagrange weights
    ``L_j`` of the three assembled orders ``m_j`` is exact (the weights' cancellation
    costs ~m^0 eps relative: ``sum |L_j| ~ m^2 / 2`` against ``|K(m)| ~ (m / m_2)^2 |K(m_2)|``).
    The sum costs a small fraction of an assembly.
    """

    #: orders assembled per space before the stiffness is interpolated (degree 2 in m)
    ASSEMBLED_ORDERS = 3

    def __init__(self, state, study):
        self.state, self.study = state, study
        self.order = ngs.Parameter(1.0)
        self._forms: dict = {}
        self._assembled: dict = {}      # (form key, m) -> theta-free Hessian on all DOFs

    def _space_key(self, m: int):
        return ("disc",) if self.state.has_disc else ("centre", min(m, 2))

    def _forms_for(self, m: int):
        key = (self._space_key(m), m == 0)
        if key not in self._forms:
            state, study = self.state, self.study
            axis_m1 = m == 1 and not state.has_disc
            space = order_space(state.mesh, study.mesh.order, m, state.has_disc)
            trial, test = space.TnT()
            energy, mass_form = membrane_forms(state, 0 if m == 0 else self.order, trial, test,
                                               axis_m1, theta=1.0)
            hessian = ngs.BilinearForm(space, symmetric=False)
            hessian += ngs.Variation(energy)
            mass = to_scipy(ngs.BilinearForm(mass_form, symmetric=False).Assemble().mat)
            normal_mass = to_scipy(ngs.BilinearForm(normal_mass_form(
                state, trial, test, 1.0)).Assemble().mat)
            self._forms[key] = (space, hessian, mass, normal_mass, axis_m1)
        return self._forms[key]

    def operators(self, m: int) -> OrderOperators:
        """Dry K_s, M_s of order m (SciPy CSR, whole device)."""
        state, study = self.state, self.study
        space, hessian, mass, normal_mass, axis_m1 = self._forms_for(m)
        theta = theta_integral(m)
        stiffness = theta * self._hessian((self._space_key(m), m == 0), hessian, space, m)
        mass = theta * mass
        with_disc = m == 0 and state.has_disc and study.disc.motion == "spring"
        lift = rim_lift(space, state) if with_disc else None
        free = np.flatnonzero(np.array(space.FreeDofs()))
        k_ff, m_ff = stiffness[free][:, free], mass[free][:, free]
        disc_mass = 0.0
        if with_disc:
            spring = study.spring
            vector = lift.vec.FV().NumPy()
            disc_mass = study.disc.mass + spring.mass / 3
            k_ff = _border(k_ff, stiffness, vector, free, spring.stiffness)
            m_ff = _border(m_ff, mass, vector, free, disc_mass)
        return OrderOperators(m, k_ff.tocsr(), m_ff.tocsr(), space, free, with_disc, lift,
                              axis_m1, state, mass.tocsr(), disc_mass,
                              normal_mass=theta * normal_mass)


    def _hessian(self, key, hessian, space, m: int) -> sp.csr_matrix:
        """The theta-free Hessian of ``hessian`` (a form of ``space``) at order m, all DOFs:
        assembled for m = 0 and the first :data:`ASSEMBLED_ORDERS` orders of the form,
        interpolated in m beyond them (class doc)."""
        if (key, m) not in self._assembled:
            nodes = [order for (k, order) in self._assembled if k == key and order > 0]
            if m == 0 or len(nodes) < self.ASSEMBLED_ORDERS or m < max(nodes):
                self.order.Set(float(m))
                hessian.AssembleLinearization(ngs.GridFunction(space).vec)  # E(u0 + u) at 0
                self._assembled[key, m] = to_scipy(hessian.mat)
            else:
                nodes = sorted(nodes)[:self.ASSEMBLED_ORDERS]
                matrix = None
                for j in nodes:
                    weight = math.prod((m - i) / (j - i) for i in nodes if i != j)
                    term = weight * self._assembled[key, j]
                    matrix = term if matrix is None else matrix + term
                return matrix.tocsr()
        return self._assembled[key, m]

    def material_tangent(self, operators: OrderOperators):
        """The material part of the tangent K_mat [N/m] of ``operators``' order on its
        unknowns (the Prony branches, :func:`copdea_fem.fe.linearise.damping_terms`): the
        Hessian of :func:`.membrane.order_energy` with ``material_only``, bordered with the
        rim lift like K_s (no spring: it is elastic)."""
        state, m = self.state, operators.m
        space, _, _, _, axis_m1 = self._forms_for(m)     # the same space as K_s
        key = ("material", self._space_key(m), m == 0)
        if key not in self._forms:          # one symbolic form per space, m a Parameter
            trial, test = space.TnT()
            energy, _ = membrane_forms(state, 0 if m == 0 else self.order, trial, test,
                                       axis_m1, theta=1.0, material_only=True)
            hessian = ngs.BilinearForm(space, symmetric=False)
            hessian += ngs.Variation(energy)
            self._forms[key] = hessian
        full = theta_integral(m) * self._hessian(key, self._forms[key], space, m)
        free = operators.free_dofs
        block = full[free][:, free]
        if operators.disc_dof:
            block = _border(block, full, operators.lift.vec.FV().NumPy(), free, 0.0)
        return block.tocsr()

    def damping(self, operators: OrderOperators):
        """:func:`copdea_fem.fe.linearise.damping_terms` of one order (None: undamped)."""
        from copdea_fem.fe.linearise import damping_terms
        cache = self.__dict__.setdefault("_damping", {})   # once per order (dry + coupled)
        if id(operators) not in cache:
            cache[id(operators)] = (operators, damping_terms(
                operators.stiffness, operators.mass, self.study.membrane,
                lambda: self.material_tangent(operators)))
        return cache[id(operators)][1]


def order_operators(state, study, m: int) -> OrderOperators:
    """Dry K_s, M_s of order m about the prestressed ``state`` (one-off; see OrderForms)."""
    return OrderForms(state, study).operators(m)


def _border(block, full, lift, free, extra):
    """[[A_ff, A l_f], [l^T A_f, l^T A l + extra]] for u = u_free + w_d * lift."""
    column = full @ lift
    corner = float(lift @ column) + extra
    return sp.bmat([[block, sp.csr_matrix(column[free][:, None])],
                    [sp.csr_matrix(column[free][None, :]), sp.csr_matrix([[corner]])]])


@dataclass
class CoupledOrderOperators:
    """The scaled coupled pencil of one order and what is needed to read its vectors
    (the axisymmetric counterpart of :class:`copdea_fem.fe.coupled.CoupledOperators`)."""

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
    #: the pencil's blocks before :func:`copdea_fem.fe.coupled.scaled_pencil` (module doc):
    #: Theta_m C [m^2] (pressure_free x the membrane's unknowns), Theta_m M_a [m^4 s^2/kg]
    coupling: sp.csr_matrix = None
    air_mass: sp.csr_matrix = None

    @property
    def membrane_size(self) -> int:
        return self.membrane.size


class MeridianAir:
    """The air and coupling matrices of every order, assembled once (module doc).

    ``k_a(m) = Theta_m (K0 + m^2 K1)``, ``m_a(m) = Theta_m M_a`` on the pressure space
    ``(p, q)`` (no condition on the axis; orders m >= 1 drop the axis DOFs), and the
    coupling ``C[p', u] = int_screens [p'] (a n_r + c n_z) r ds`` with the membrane's
    (a, b, c) space (the same DOF layout for every order) plus the disc's
    ``int_disc [p'] n_z r ds``; all on the deformed meridian (``motion``).
    """

    def __init__(self, state, study, motion):
        from copdea_fem.fe import acoustics
        from copdea_fem.fe.axisymmetric.air import air_form_parts, air_kinetic_parts, screen_normal

        mesh, air = state.mesh, study.air
        enclosed = acoustics.has_cavity(mesh)
        vacuum_above = enclosed and not air.outside
        screens = (acoustics.enclosure_screen_faces(study.geometry.frame, air.outside)
                   if enclosed else acoustics.screen_faces(study.geometry.frame))
        if not state.has_disc:
            screens = "|".join(face for face in screens.split("|") if face != "disc")
        self.pressure_space = acoustics.pressure_space(mesh, study.mesh.pressure_order,
                                                       screens, vacuum_above=vacuum_above)
        trial, test = self.pressure_space.TnT()
        parts = air_form_parts(trial, test, air.density, air.sound_speed,
                               air.domain_radius, air.pml_thickness, deformation=motion)
        self.gradient, self.hoop, self.mass = (_assemble(self.pressure_space, part)
                                               for part in parts)
        kinetic = air_kinetic_parts(trial, test, air.density, deformation=motion)
        self.kinetic_gradient, self.kinetic_hoop = (_assemble(self.pressure_space, part)
                                                    for part in kinetic)
        membrane_space = order_space(mesh, study.mesh.order, 2, state.has_disc,
                                     complex_=True)
        self.membrane_ndof = membrane_space.ndof
        both = ngs.FESpace([membrane_space, self.pressure_space])
        (u, pressure), (_, pressure_test) = both.TnT()
        normal = screen_normal()
        u_normal = u[0] * normal[0] + u[2] * normal[1]
        coupling = ngs.BilinearForm(both, nonassemble=False)
        coupling += (-pressure_test[1]) * u_normal * ngs.x * ngs.ds("membrane",
                                                                   deformation=motion)
        matrix = to_scipy(coupling.Assemble().mat).tocsr()
        split = membrane_space.ndof
        self.coupling = matrix[split:][:, :split].tocsr()         # (pressure, membrane)
        self.disc_coupling = None
        if state.has_disc:
            form = ngs.LinearForm(self.pressure_space)
            form += (-test[1]) * normal[1] * ngs.x * ngs.ds("disc", deformation=motion)
            self.disc_coupling = form.Assemble().vec.FV().NumPy().copy()
        free = np.array(self.pressure_space.FreeDofs())
        on_axis = np.array(self.pressure_space.GetDofs(mesh.Boundaries("axis")))
        self._free = {0: np.flatnonzero(free), 1: np.flatnonzero(free & ~on_axis)}
        self.motion = motion
        self._blocks: dict = {}

    def free_pressure(self, m: int) -> np.ndarray:
        """Free pressure DOFs of order m (p = q = 0 on the axis for m >= 1)."""
        return self._free[min(m, 1)]

    def blocks(self, m: int, membrane_free: np.ndarray) -> dict:
        """The matrices of the module doc on the free DOFs of order m, without Theta_m:
        ``gradient``, ``hoop``, ``mass``, ``kinetic_gradient``, ``kinetic_hoop`` (pressure x
        pressure), ``coupling`` (pressure x the membrane's ``membrane_free``) and
        ``coupling_rows`` (pressure x all membrane DOFs); sliced once for all orders that
        share the free DOFs."""
        key = (min(m, 1), membrane_free.tobytes())
        if key not in self._blocks:
            free = self.free_pressure(m)
            blocks = {name: getattr(self, name)[free][:, free].tocsr() for name in
                      ("gradient", "hoop", "mass", "kinetic_gradient", "kinetic_hoop")}
            blocks["coupling_rows"] = self.coupling[free].tocsr()
            blocks["coupling"] = blocks["coupling_rows"][:, membrane_free].tocsr()
            self._blocks[key] = blocks
        return self._blocks[key]


def _assemble(space, integrand):
    form = ngs.BilinearForm(space)
    form += integrand
    return to_scipy(form.Assemble().mat).tocsr()


def coupled_order_operators(state, study, dry: OrderOperators, air: MeridianAir
                            ) -> CoupledOrderOperators:
    """Membrane + air pencil of order ``dry.m`` (eq. A3 of :mod:`copdea_fem.fe.acoustics`)::

        A = [[K_s, Theta C^T], [0, Theta (K0 + m^2 K1)]],  B = [[M_s, 0], [-Theta C, Theta M_a]]

    on the free DOFs, scaled as in :func:`copdea_fem.fe.coupled.scaled_pencil`."""
    from copdea_fem.fe.coupled import scaled_pencil
    from copdea_fem.fe.eigen import Factorization

    m = dry.m
    theta = theta_integral(m)
    if air.membrane_ndof != dry.space.ndof:
        raise RuntimeError("membrane spaces of the orders differ; cannot couple")
    pressure_free = air.free_pressure(m)
    blocks = air.blocks(m, dry.free_dofs)
    coupling = blocks["coupling"]
    if dry.disc_dof:
        disc_column = blocks["coupling_rows"] @ dry.lift.vec.FV().NumPy() \
            + air.disc_coupling[pressure_free]
        coupling = sp.hstack([coupling, sp.csr_matrix(disc_column[:, None])])
    coupling = theta * coupling.tocsr()
    air_stiffness = theta * (blocks["gradient"] + m**2 * blocks["hoop"])
    air_mass = theta * blocks["mass"]
    n_u, n_p = dry.size, pressure_free.size
    a_full = sp.bmat([[dry.stiffness, coupling.T], [None, air_stiffness]], format="csr")
    b_full = sp.bmat([[dry.mass, None], [-coupling, air_mass]], format="csr")
    is_air = np.zeros(n_u + n_p, dtype=bool)
    is_air[n_u:] = True
    a_scaled, b_scaled, beta, _, _ = scaled_pencil(a_full.astype(complex),
                                                   b_full.astype(complex), is_air)
    kinetic = theta * (blocks["kinetic_gradient"] + m**2 * blocks["kinetic_hoop"])
    backend = study.eigen.backend

    def factorize(sigma: float):
        return Factorization((a_scaled - sigma * b_scaled).tocsc(), backend)

    return CoupledOrderOperators(m, a_scaled, b_scaled, dry, air.pressure_space, pressure_free,
                                 np.arange(n_u, n_u + n_p), np.arange(n_u), beta,
                                 kinetic.tocsr(), air.motion, factorize, coupling,
                                 air_mass.tocsr())


def dry_order(band, forms: OrderForms, m: int, f_max: float, initial_shifts=None):
    """The dry pencil of order m and its modes from 0 Hz to ``f_max`` [Hz] (``band``: the
    study's :class:`copdea_fem.fe.bands.BandSolver`), and the frequency of its lowest mode
    [Hz] (from the band, else one lowest-eigenvalue solve)."""
    operators = forms.operators(m)
    # damping keys: the quadratic/rational step in omega (copdea_fem.fe.eigen.damped),
    # else linear
    result = band.solve(operators.stiffness, operators.mass, 0.0, f_max,
                        damping=forms.damping(operators), initial_shifts=initial_shifts)
    lowest = float(np.min(result.freq_hz)) if len(result) else \
        lowest_frequency_hz(operators.stiffness, operators.mass)
    return operators, result, lowest
