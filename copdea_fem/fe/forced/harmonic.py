r"""Harmonic response of the coupled membrane-air model to the AC voltage.

Forcing (the FE counterpart of eq. 14)
--------------------------------------
The voltage is ``V(t) = V_b + Re{V~ e^{-i omega t}}`` (NGSolve's time convention, as
:mod:`copdea_fem.fe.acoustics`).  With ``E(u; V)`` the membrane energy of
:mod:`copdea_fem.fe.membrane` (eq. 20 plus the co-energy of eq. 7) and ``R = dE/du`` its
residual, the structure obeys ``M u'' + R(u; V) + (air traction) = 0``.  Linearised about
the prestress ``u0`` (``R(u0; V_b) = 0`` on the free DOFs)::

    (K_s - omega^2 M_s) u~ + C^T p = f V~,     f = -dR/dV (u0, V_b)     [N/V]

The co-energy ``-eps/2 (V/h0)^2 det_c`` is quadratic in V and the rest of the energy does
not depend on it, so ``R(u0; V) = R_m + V^2 R_e`` and, exactly,

    dR/dV (u0, V_b) = 2 V_b R_e = 2 (R(u0; V_b) - R(u0; 0)) / V_b.

In the capacitance language of Sect. 3.2 the electrostatic energy is ``-V^2/2 C(u)`` with
``C = int eps det_c / h0^2 dV0``, so ``f = V_b dC/du``: the reduced model's
``V_b V~ dC/dq`` (the factor 1, not the 2 that eq. 14 prints; :mod:`copdea_fem.reduced`).
The disc on the spring gets ``lift . f`` (its share of the rim reaction; the spring does not
depend on V).  Only the order m = 0 is forced by a uniform electrode.  Each engine
computes f and K_el (below) from its own energy: :mod:`copdea_fem.fe.axisymmetric.forcing`
(the order m = 0), :mod:`copdea_fem.fe.quadrant.forced` (the even-even sector); this module
holds what both share.

Hysteretic loss (direct path)
-----------------------------
``membrane.loss_factor`` eta multiplies the *elastic* part of the stiffness: ``K_el``,
the Hessian at ``(u0, V = 0)`` of the membrane energy (the Mooney-Rivlin material term
and its initial-stress term, at the prestressed state); the electrostatic (Maxwell) part
``K_s - K_el``, the spring and the air stay lossless.  In the ``e^{-i omega t}`` convention a
lossy stiffness is ``(1 - i eta) K_el`` (it is ``(1 + i eta) K_el`` for ``e^{+i omega t}``),
so the dissipated power is ``P_d = omega/2 eta u^H K_el u`` > 0.

Direct path::

    (A - i eta K_el^ - omega^2 B) x = F V~,      F = (f, 0)

on the scaled pencil of :func:`copdea_fem.fe.axisymmetric.operators.coupled_order_operators`
(membrane rows are not scaled, ``p = beta p^``).

Rayleigh and Prony damping
--------------------------
With ``membrane.rayleigh_alpha/beta`` or ``membrane.prony`` the membrane block of the
pencil gets the same terms as the damped eigen step (:mod:`copdea_fem.fe.eigen.damped`,
:func:`copdea_fem.fe.linearise.damping_terms`).  The direct path solves, exactly,

    (A - i eta K_el^ - i omega C - omega^2 B + sum_j r_j(omega) G_j) x = F V~,
    r_j(omega) = -i omega tau_j / (1 - i omega tau_j);

the modal path adds their modal (diagonal) projections ``-i omega lambda_j u_j^T C u_j``
and ``r_j(omega) lambda_j u_j^T G_j u_j`` to each mode's denominator (like the hysteretic
term below): exact for one isolated mode, an approximation where the damping couples modes.

Modal superposition
-------------------
Unscaled, ``A = [[K_s, C^T], [0, K_a]]``, ``B = [[M_s, 0], [-C, M_a]]`` (eq. A3 of
:mod:`copdea_fem.fe.acoustics`) with ``K_a, M_a`` complex symmetric; for ``A x = lambda B x``,
``x = (u, p)``, the left eigenvector is ``y = (lambda u, p)`` (``A^T y = lambda B^T y``),
and ``y_j^T B x_k = 0`` for ``lambda_j != lambda_k``.  For the scaled pencil
``A^ = R A S``, ``B^ = R B S`` (rows ``R = diag(1, alpha)``, columns ``S = diag(1, beta)``)
the right vector is ``x^ = S^-1 x`` and the left one ``y^ = R^-1 y = (lambda u, beta p^/alpha)``;
``y^T B^ x^ = y^T B x``.  Expanding ``x = sum_j c_j x_j`` and projecting with ``y_j``::

    c_j (n_j (lambda_j - omega^2) - i eta lambda_j k_j - i omega lambda_j (b/m)_j m_j) = y_j^T F V~

with ``n_j = y_j^T B x_j``, ``m_j = u_j^T M_s u_j``, ``k_j = u_j^T K_el u_j`` (no conjugates).
The damping terms are the modal (diagonal) projections of a structural damping
``D = (b/m)_j M_s`` and of the hysteretic loss: the paper's modal damping b/m (Sect. 5.3,
eq. 19: ``b_j = (b/m)_j m_j`` with m_j the *structural* modal mass) per mode label
(``reduced.damping_*``; air/PML modes get none).  For a structural mode
``lambda_j m_j / n_j`` is its membrane share of the kinetic energy, so the damping term per
total (structure + air) mass is ``(b/m)_j m/(m + m_ad)``, as in eq. (19).

Modes of the band: every computed eigenpair with ``Re f <= f_max`` (structural and air).
The rest enter through the residual (static) correction: with
``(A - omega^2 B)^-1 = sum_all x y^T / (n (lambda - omega^2))`` and
``1/(lambda - omega^2) = 1/lambda + omega^2/lambda^2 + O(omega^4/lambda^3)``::

    r0 = A^-1 F - sum_band x_j y_j^T F / (n_j lambda_j)
    r1 = A^-1 B A^-1 F - sum_band x_j y_j^T F / (n_j lambda_j^2)
    x(omega) ~ sum_band c_j(omega) x_j + (r0 + omega^2 r1) V~

(``sum_all x y^T/(n lambda) = A^-1``, ``sum_all x y^T/(n lambda^2) = A^-1 B A^-1``): exact
at omega = 0, and the omitted modes' error is ``O(omega^4 / |lambda|^2)``.  Without
structural damping the modal path then reproduces the direct one (tests).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
import scipy.sparse as sp

if TYPE_CHECKING:
    from copdea_fem.fe.eigen.damped import DampingTerms


def reduce_vector(full: np.ndarray, free_dofs, lift=None) -> np.ndarray:
    """A load on a membrane space's DOFs -> on the unknowns (free DOFs, then ``lift . load``
    when the disc rides on the spring; ``lift`` the rim-lift coefficients)."""
    reduced = full[free_dofs]
    if lift is not None:
        reduced = np.append(reduced, lift @ full)
    return reduced


def checked_bias(voltage_b: float) -> float:
    """The bias V_b [V] of a forced response, > 0 (a ValueError naming ``load.voltage``
    otherwise: at V_b = 0 the linear forcing V_b dC/du vanishes)."""
    voltage_b = float(voltage_b)
    if not voltage_b > 0:
        raise ValueError(f"load.voltage = {voltage_b:g} V is not allowed for a forced response; "
                         "allowed: > 0 V (the linear forcing V_b dC/du vanishes; the response "
                         "is quadratic in V~)")
    return voltage_b


def forcing_from_energy(energy_form, voltage, voltage_b: float, at, free_dofs):
    """f = -dR/dV (u0, V_b) = -2 (R(u0; V_b) - R(u0; 0)) / V_b [N/V] on a membrane space's DOFs
    (module doc: the co-energy is quadratic in V, so the difference quotient is exact), and
    the relative residual |R(u0; V_b)| / |R(u0; 0)| on the free DOFs (the prestress
    equilibrium check): both engines' forcing
    (:mod:`copdea_fem.fe.axisymmetric.forcing`, :mod:`copdea_fem.fe.quadrant.forced`).

    Parameters
    ----------
    energy_form : ngsolve.BilinearForm
        ``Variation`` of the membrane energy ``E(.; V)``; ``energy_form.Apply(at)`` is the
        residual R [N] at the prestress.
    voltage : ngsolve.Parameter
        The voltage [V] in ``energy_form``; set to ``voltage_b`` and 0 here, left at 0.
    voltage_b : float
        The bias V_b [V], > 0.
    at : ngsolve.BaseVector
        Where the residual is taken: the prestress u0 (3-D) or u = 0 of a form of
        ``E(u0 + u)`` (axisymmetric).
    free_dofs : array of int
        The free DOFs of the space (the balance's norm).

    Returns
    -------
    force : numpy.ndarray
        f on every DOF of the space [N/V].
    balance : float
        |R(u0; V_b)| / |R(u0; 0)| on ``free_dofs`` (0 at an exact equilibrium).
    """
    voltage_b = checked_bias(voltage_b)
    residuals = []
    for value in (voltage_b, 0.0):
        voltage.Set(value)
        out = at.CreateVector()
        energy_form.Apply(at, out)
        residuals.append(np.array(out.FV().NumPy()) * 1.0)
    at_bias, at_zero = residuals
    force = -2.0 * (at_bias - at_zero) / voltage_b
    balance = np.linalg.norm(at_bias[free_dofs]) / max(np.linalg.norm(at_zero[free_dofs]),
                                                        1e-300)
    return force, float(balance)


def reduce_matrix(full: sp.spmatrix, free_dofs, lift=None) -> sp.csr_matrix:
    """A matrix on a membrane space's DOFs -> on the unknowns (``u = u_free + w_d lift``)."""
    free = free_dofs
    block = full[free][:, free]
    if lift is None:
        return block.tocsr()
    column = full @ lift
    corner = float(lift @ column)
    return sp.bmat([[block, sp.csr_matrix(column[free][:, None])],
                    [sp.csr_matrix(column[free][None, :]), sp.csr_matrix([[corner]])]]).tocsr()


def reduce_vector_3d(full, operators):
    """:func:`reduce_vector` for :class:`copdea_fem.fe.linearise.MembraneOperators`."""
    lift = operators.state.disc_lift.vec.FV().NumPy().copy() if operators.disc_dof else None
    return reduce_vector(full, operators.free_dofs, lift)


def reduce_matrix_3d(full, operators):
    """:func:`reduce_matrix` for :class:`copdea_fem.fe.linearise.MembraneOperators`."""
    lift = operators.state.disc_lift.vec.FV().NumPy().copy() if operators.disc_dof else None
    return reduce_matrix(full, operators.free_dofs, lift)


def damping_matrix(terms, omega: float) -> sp.csr_matrix:
    """``-i omega C + sum_j r_j(omega) G_j`` (module doc) at the angular frequency ``omega``
    [rad/s]."""
    size = (terms.damping if terms.damping is not None else terms.relaxation[0][0]).shape[0]
    matrix = sp.csr_matrix((size, size), dtype=complex)
    if terms.damping is not None:
        matrix = matrix - 1j * omega * terms.damping
    for tangent, tau in terms.relaxation:
        matrix = matrix + (-1j * omega * tau / (1 - 1j * omega * tau)) * tangent
    return matrix.tocsr()


class MembranePencil(Protocol):
    """A membrane's dry operators as the forced response reads them (either engine's:
    :class:`copdea_fem.fe.linearise.MembraneOperators` of the 3-D sector, the axisymmetric
    order's operators)."""

    stiffness: sp.csr_matrix        # K_s [N/m] on the membrane unknowns
    mass: sp.csr_matrix             # M_s [kg]


class CoupledPencil(Protocol):
    """The coupled pencil as :class:`ForcedOrder` and :class:`ModalBasis` read it: either
    engine's coupled operators (:class:`copdea_fem.fe.coupled.CoupledOperators` of the 3-D
    sector, the axisymmetric order's coupled operators) or a :class:`DryPencil`."""

    stiffness: sp.csr_matrix        # A^, scaled (module doc)
    mass: sp.csr_matrix             # B^
    membrane_index: np.ndarray      # rows of the membrane unknowns
    pressure_index: np.ndarray      # rows of the free pressure unknowns
    pressure_scale: float           # Pa per scaled pressure unknown
    membrane: MembranePencil        # the membrane's dry operators


@dataclass
class DryPencil:
    """A membrane's own pencil ``K_s u = omega^2 M_s u`` (either engine's dry operators) in
    the shape of coupled operators without air: :class:`ForcedOrder` and :class:`ModalBasis`
    then drive it as they drive a coupled one (the left eigenvector ``(lambda u)`` of the
    coupled pencil is a right one here, the pencil being symmetric)."""

    membrane: MembranePencil         # dry operators: stiffness, mass, size, to_full

    @property
    def stiffness(self):
        return self.membrane.stiffness

    @property
    def mass(self):
        return self.membrane.mass

    @property
    def membrane_index(self) -> np.ndarray:
        return np.arange(self.membrane.stiffness.shape[0])

    @property
    def pressure_index(self) -> np.ndarray:
        return np.zeros(0, dtype=int)

    pressure_scale = 1.0


@dataclass
class ForcedOrder:
    """The m = 0 coupled pencil with its forcing: everything both paths need.

    ``forcing`` F [N/V] and ``elastic`` K_el^ [N/m] live on the scaled unknowns (zero air rows);
    ``alpha`` is the air row scale of the scaled pencil (module doc).
    """

    coupled: CoupledPencil          # either engine's coupled operators, or a DryPencil
    forcing: np.ndarray
    elastic: sp.csr_matrix
    alpha: float
    equilibrium_residual: float
    backend: str = "superlu"
    damping: DampingTerms | None = None     # on the scaled unknowns

    @classmethod
    def from_parts(cls, coupled, force, k_el, balance, backend="superlu") -> ForcedOrder:
        """From f and K_el on the membrane unknowns (either engine's coupled operators)."""
        n = coupled.stiffness.shape[0]
        index = np.asarray(coupled.membrane_index)
        forcing = np.zeros(n, dtype=complex)
        forcing[index] = force
        k_el = sp.coo_matrix(k_el)
        elastic = sp.csr_matrix((k_el.data.astype(complex), (index[k_el.row], index[k_el.col])),
                                shape=(n, n))
        # alpha from the coupling blocks: B^[p, u] = -alpha C, A^[u, p] = beta C^T
        pressure = coupled.pressure_index
        alpha = 1.0                                        # a dry pencil has no air rows
        if len(pressure):
            b_pu = coupled.mass[pressure][:, index]
            a_up = coupled.stiffness[index][:, pressure]
            alpha = float(coupled.pressure_scale * abs(b_pu).max() / abs(a_up).max())
        return cls(coupled, forcing, elastic, alpha, balance, backend)

    @property
    def size(self) -> int:
        return self.coupled.stiffness.shape[0]

    def operator(self, omega: float, loss_factor: float = 0.0):
        """A^ - i eta K_el^ - omega^2 B^ (scaled, CSC)."""
        matrix = self.coupled.stiffness - complex(omega) ** 2 * self.coupled.mass
        if loss_factor:
            matrix = matrix - 1j * loss_factor * self.elastic
        if self.damping is not None:
            matrix = matrix + damping_matrix(self.damping, omega)
        return matrix.tocsc()

    def with_damping(self, terms) -> ForcedOrder:
        """The same, with the membrane's damping terms (on its unknowns) in the pencil."""
        if terms is not None and not terms.empty:
            self.damping = terms.embedded(np.asarray(self.coupled.membrane_index), self.size)
        return self

    def direct(self, frequency_hz, loss_factor: float = 0.0) -> np.ndarray:
        """Scaled solutions x^ per volt at each frequency [m/V; Pa/(beta V)]: (n, lines)."""
        from copdea_fem.fe.eigen import Factorization
        frequency_hz = np.atleast_1d(np.asarray(frequency_hz, float))
        out = np.empty((self.size, frequency_hz.size), dtype=complex)
        for k, f in enumerate(frequency_hz):
            solver = Factorization(self.operator(2 * np.pi * float(f), loss_factor),
                                   self.backend)
            out[:, k] = solver.solve(self.forcing)
        return out

    def membrane(self, vectors: np.ndarray) -> np.ndarray:
        """Membrane unknowns (free DOFs + disc) of scaled vectors [m]."""
        return vectors[self.coupled.membrane_index]

    def pressure(self, vectors: np.ndarray) -> np.ndarray:
        """Free pressure DOFs [Pa] of scaled vectors."""
        return vectors[self.coupled.pressure_index] * self.coupled.pressure_scale


#: Shift of the factorisation of a singular A, ``A - sigma B`` with ``sigma = -NULL_SHIFT
#: |lambda|_max`` of the band (:func:`null_pair`): its relative error on the other pairs,
#: (sigma / lambda)^2 after one refinement, stays at round-off for any band.
NULL_SHIFT = 1e-6

#: A pencil whose smallest eigenvalue lies below this share of the band's largest
#: |lambda| has a static pair (|f| < 1e-4 f_max, as
#: :data:`copdea_fem.fe.cavity.STATIC_SHARE` drops it from the band).
NULL_SHARE = 1e-8


@dataclass
class NullPair:
    """The static pair lambda = 0 of a pencil (right ``x0``, left ``y0``, ``norm`` =
    ``y0^T B x0``) and the shifted factorisation that solves around it.

    ``A x = r`` has solutions for every r with ``y0^T r = 0`` (a forcing on the membrane
    alone: the left vector of lambda = 0 is ``(lambda u0, p0) = (0, p0)``), defined up to
    a multiple of ``x0``; the modal expansion over the other pairs picks the one with
    ``y0^T B x = 0``.  :meth:`solve` finds it as ``x = (A - sigma B)^-1 (r + sigma B x)``
    (one refinement of the shifted solve) projected by ``x - x0 (y0^T B x) / norm``.
    """

    x0: np.ndarray
    y0: np.ndarray
    norm: complex
    shifted: object          # Factorization of A - sigma B
    sigma: float
    b: sp.csr_matrix

    def project(self, vector: np.ndarray) -> np.ndarray:
        """``vector`` (n,) or (n, K) with ``y0^T B x = 0`` (each column)."""
        return vector - np.multiply.outer(self.x0, self.y0 @ (self.b @ vector)) / self.norm

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """The solution (class notes) for ``rhs`` (n,) or (n, K) (one block solve)."""
        x = self.project(self.shifted.solve(rhs))
        return self.project(self.shifted.solve(rhs + self.sigma * (self.b @ x)))


def null_pair(a, b, backend: str, scale: float) -> NullPair | None:
    """The :class:`NullPair` of the pencil (A, B), or None when its smallest eigenvalue is
    above :data:`NULL_SHARE` ``scale`` (A has an inverse).

    Inverse iteration with the shift ``sigma = -NULL_SHIFT scale`` [rad^2/s^2]: the null
    vector dominates after one step by the ratio ``lambda_1 / sigma`` of the next pair
    (>= 1e2 for any band above 1e-4 f_max), three steps each for the right vector (A - sigma B)
    and the left one (its transpose, a second factorisation).
    """
    from copdea_fem.fe.eigen import Factorization

    sigma = -NULL_SHIFT * scale
    shifted = Factorization((a - sigma * b).tocsc(), backend)
    transposed = Factorization((a - sigma * b).T.tocsc(), backend)
    rng = np.random.default_rng(0)
    x0 = rng.standard_normal(a.shape[0]) + 0j
    y0 = x0.copy()
    for _ in range(3):
        x0 = shifted.solve(b @ x0)
        x0 /= np.linalg.norm(x0)
        y0 = transposed.solve(b.T @ y0)
        y0 /= np.linalg.norm(y0)
    bx = b @ x0
    rayleigh = complex(np.vdot(bx, a @ x0) / np.vdot(bx, bx))
    if abs(rayleigh) > NULL_SHARE * scale:
        return None
    return NullPair(x0, y0, complex(y0 @ bx), shifted, sigma, sp.csr_matrix(b))


@dataclass
class ModalBasis:
    """Coupled modes of the band with their left vectors, and the residual correction.

    ``vectors`` (n, J) scaled right eigenvectors; ``eigenvalues`` lambda_j [rad^2/s^2];
    ``norms`` n_j = y^T B x; ``participation`` y_j^T F; ``structural_mass`` m_j = u^T M_s u;
    ``elastic_modal`` k_j = u^T K_el u; ``residual0``/``residual1`` r0, r1 (module doc);
    ``damping_per_mass`` (b/m)_j [1/s]; ``labels``.
    """

    eigenvalues: np.ndarray
    vectors: np.ndarray
    norms: np.ndarray
    participation: np.ndarray
    structural_mass: np.ndarray
    elastic_modal: np.ndarray
    residual0: np.ndarray
    residual1: np.ndarray
    labels: tuple
    damping_per_mass: np.ndarray
    left_residuals: np.ndarray
    viscous_modal: np.ndarray = None      # u_j^T C u_j [N s/m] (Rayleigh), or None
    relaxation_modal: tuple = ()          # (u_j^T G_j u_j [N/m], tau_j [s]) per Prony term

    @classmethod
    def build(cls, forced: ForcedOrder, eigenvalues, vectors, labels, damping_per_mass,
              singular: bool = False):
        """The basis of the band's pairs; ``singular``: the pencil may hold the static pair
        lambda = 0 of a sealed enclosure (not among ``eigenvalues``), whose A has no
        inverse: the static correction is then taken on the other pairs
        (:func:`null_pair`)."""
        return cls.build_many([forced], eigenvalues, vectors, labels, damping_per_mass,
                              singular)[0]

    @classmethod
    def build_many(cls, forced_orders, eigenvalues, vectors, labels, damping_per_mass,
                   singular: bool = False) -> list:
        """One basis (:meth:`build`) per :class:`ForcedOrder` of ``forced_orders``: forcings
        of one pencil (the same coupled operators, ``elastic`` and damping; the first's are
        used), each with its own participation and static correction.  The band's left
        vectors and modal projections are formed once, and A is factorised once: the static
        solves ``A^-1 F`` and ``A^-1 B A^-1 F`` of all the forcings are one block solve
        each."""
        from copdea_fem.fe.eigen import Factorization
        forced = forced_orders[0]
        coupled = forced.coupled
        a, b = coupled.stiffness, coupled.mass
        eigenvalues = np.asarray(eigenvalues, complex)
        vectors = np.asarray(vectors, complex)
        u_index, p_index = coupled.membrane_index, coupled.pressure_index
        left = vectors.copy()
        left[u_index] *= eigenvalues[None, :]
        left[p_index] *= coupled.pressure_scale / forced.alpha
        if eigenvalues.size:
            a_t, b_t = a.T.tocsr(), b.T.tocsr()
            left_residuals = np.array([
                np.linalg.norm(a_t @ left[:, j] - eigenvalues[j] * (b_t @ left[:, j]))
                / max(np.linalg.norm(a_t @ left[:, j]), 1e-300)
                for j in range(len(eigenvalues))])
        else:           # no pair (an order above the band: its static correction alone)
            left_residuals = np.zeros(0)
        norms = np.einsum("ij,ij->j", left, b @ vectors)
        forcings = np.column_stack([order.forcing for order in forced_orders])   # (n, K)
        participation = left.T @ forcings                                        # (J, K)
        membrane = vectors[u_index]
        mass = coupled.membrane.mass
        structural = np.einsum("ij,ij->j", membrane, mass @ membrane)
        elastic = (np.einsum("ij,ij->j", membrane, forced.elastic[u_index][:, u_index] @ membrane)
                   if eigenvalues.size else np.zeros(0, complex))
        scale = float(np.max(np.abs(eigenvalues))) if eigenvalues.size else 1.0
        pair = null_pair(a, b, forced.backend, scale) if singular else None
        if pair is None:
            static = Factorization(a.tocsc(), forced.backend)
            first = static.solve(forcings)
            second = static.solve(b @ first)
        else:
            first = pair.solve(forcings)
            second = pair.solve(b @ first)
        weights = participation / norms[:, None]
        residual0 = first - vectors @ (weights / eigenvalues[:, None])
        residual1 = second - vectors @ (weights / eigenvalues[:, None] ** 2)
        viscous, relaxation = None, ()
        if forced.damping is not None:
            terms = forced.damping
            if terms.damping is not None:
                viscous = np.einsum("ij,ij->j", vectors, terms.damping @ vectors)
            relaxation = tuple((np.einsum("ij,ij->j", vectors, tangent @ vectors), tau)
                               for tangent, tau in terms.relaxation)
        return [cls(eigenvalues, vectors, norms, participation[:, k], structural, elastic,
                    residual0[:, k], residual1[:, k], tuple(labels),
                    np.asarray(damping_per_mass, float), left_residuals, viscous, relaxation)
                for k in range(len(forced_orders))]

    def coefficients(self, frequency_hz, loss_factor: float = 0.0) -> np.ndarray:
        """Weights (lines, J + 2) of [x_1 .. x_J, r0, r1] per volt (module doc)."""
        omega = 2 * np.pi * np.asarray(frequency_hz, float)[:, None]
        lam = self.eigenvalues[None, :]
        denominator = (self.norms * (lam - omega ** 2)
                       - 1j * loss_factor * lam * self.elastic_modal
                       - 1j * omega * lam * self.damping_per_mass * self.structural_mass)
        if self.viscous_modal is not None:      # Rayleigh, diagonal projection (module doc)
            denominator = denominator - 1j * omega * lam * self.viscous_modal
        for modal_tangent, tau in self.relaxation_modal:
            denominator = denominator + (-1j * omega * tau / (1 - 1j * omega * tau)) \
                * lam * modal_tangent
        modal = self.participation / denominator
        return np.hstack([modal, np.ones_like(omega), omega ** 2])

    @property
    def basis(self) -> np.ndarray:
        """[x_1 .. x_J, r0, r1] (n, J + 2), scaled unknowns."""
        return np.hstack([self.vectors, self.residual0[:, None], self.residual1[:, None]])

    def response(self, frequency_hz, loss_factor: float = 0.0) -> np.ndarray:
        """Scaled solutions per volt (n, lines) (use observations of :attr:`basis` for many
        lines: every observable is linear)."""
        return self.basis @ self.coefficients(frequency_hz, loss_factor).T
