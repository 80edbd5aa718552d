"""Ring model of the COP-DEA membrane (Sect. 3.2.1, eqs 9-14).

The flat pre-stretched annulus ``r_i <= R <= r_o`` is cut into ``n`` rings of
equal width by the node radii ``R_0 = r_o > R_1 > ... > R_n = r_i`` (ring
``k`` spans ``R_k <= R <= R_{k-1}``; ``k = 1`` is the outer ring, as in the
paper).  Node ``k`` sits at ``(r_k, z_k)`` in the deformed state; node 0 is
clamped at ``(r_o, 0)``, node ``n`` is glued to the rigid disc at radius
``r_i`` and axial position ``z_n`` (the disc's).  The generalised coordinates
are ``q = [r_1..r_{n-1}, z_1..z_n]`` (``2n - 1`` of them) when the disc rides
on the biasing spring, and ``q = [r_1..r_{n-1}, z_1..z_{n-1}]`` when the disc
is held.

Derivation, checked against the paper
-------------------------------------
Stretches (eq. 9, right as printed).  A ring is a conical frustum whose
meridian segment has length ``s_k = sqrt((r_{k-1}-r_k)^2 + (z_{k-1}-z_k)^2)``
and whose mean radius is ``(r_{k-1}+r_k)/2``.  Measured from the unstretched
film (flat pre-stretched lengths divided by ``lambda_p``):

    lambda_1k = lambda_p s_k / (R_{k-1} - R_k),
    lambda_2k = lambda_p (r_{k-1} + r_k) / (R_{k-1} + R_k).

Elastic energy (eq. 13).  Energy density times the ring's unstretched volume
``Omega_k = pi (R_{k-1}^2 - R_k^2) h0 / lambda_p^2`` (incompressible: the
flat pre-stretched volume; ``t0 = h0``), with the strain-energy function of
:class:`copdea_fem.fe.materials.Membrane` (eq. 20) evaluated at
``tr_c = lambda_1^2 + lambda_2^2``, ``det_c = lambda_1^2 lambda_2^2``.  The
paper's ``k_b (l_b - z)^2 / 2`` is the biasing spring.

Capacitance (eq. 11, corrected).  A ring of deformed area ``A_k`` and
thickness ``h_k = h0 / (lambda_1 lambda_2)`` is a parallel-plate capacitor,
``C_k = eps A_k / h_k``; volume conservation ``A_k h_k = Omega_k`` gives
``C_k = eps A_k^2 / Omega_k``.  The frustum's lateral area is
``A_k = pi (r_{k-1} + r_k) s_k`` -- the paper prints ``(r_k + r_{k+1})``,
and its sum index ``k+1`` should read ``k = 1``; the sum runs over
``k = 1..n``.  Hence

    C = sum_k eps pi^2 (r_{k-1} + r_k)^2 s_k^2 / Omega_k.

With eq. (9) one finds ``A_k = Omega_k lambda_1 lambda_2 / h0`` exactly, so
``-V^2/2 C`` equals the integral of eq. (7)'s co-energy
``-eps/2 (V/h0)^2 det_c`` over the rings: the ring model and the FE model
share one electro-elastic energy (a test checks it).

Kinetic energy (eq. 12, right as printed).  Velocities vary linearly in R
over each ring, with mass per flat pre-stretched area ``rho0 h0/lambda_p^2``;
``M = d^2 T / d qdot^2`` is the exact (consistent) mass matrix
``2 pi rho0 h0/lambda_p^2 * int N_a N_b R dR`` plus the disc mass ``M_d`` on
``z_n``.

Linearisation (eq. 14, corrected).  With ``V = V_b + V~`` the electrostatic
term of eq. (10) is ``V^2/2 dC/dq`` and
``V^2/2 = V_b^2/2 + V_b V~ + V~^2/2``.  To first order in ``V~`` and
``q~ = q - q0``,

    V^2/2 dC/dq(q0 + q~) = V_b^2/2 dC/dq(q0) + V_b^2/2 d2C/dq2(q0) q~
                           + V_b V~ dC/dq(q0),

so ``K_s = d2U_m/dq2 - V_b^2/2 d2C/dq2`` (as printed) and the forcing is
``d(t) = V_b V~(t) dC/dq`` -- not ``2 V_b V~ dC/dq`` as the paper prints
(``d(V^2/2)/dV = V``).

All derivatives are exact: first and second derivatives of the stretches are
polynomials in the node coordinates, and the constitutive partials come from
:meth:`Membrane.free_energy_partials` at zero voltage (the chain rule below).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from copdea_fem.fe.materials import Membrane


class ReducedModelError(ValueError):
    """The reduced model cannot be built or solved for these inputs; says why."""


# Local coordinate order of one ring: [r_{k-1}, r_k, z_{k-1}, z_k].
_MERIDIAN_PATTERN = np.array([[1., -1., 0., 0.], [-1., 1., 0., 0.],
                              [0., 0., 1., -1.], [0., 0., -1., 1.]])
_HOOP_PATTERN = np.array([[1., 1., 0., 0.], [1., 1., 0., 0.],
                          [0., 0., 0., 0.], [0., 0., 0., 0.]])


@dataclass(frozen=True)
class Equilibrium:
    """Static equilibrium of the ring model with the disc at ``z`` (Sect. 3.2.1).

    Attributes
    ----------
    radii, heights : ndarray, shape (n + 1,)
        Node positions r_k, z_k [m], k = 0 (outer clamp) .. n (disc rim).
    voltage : float
        Bias voltage V_b [V].
    disc_force : float
        Axial force F the disc must receive to stay at z [N]: dPi/dz_n with
        Pi = U_membrane - V^2/2 C (eqs 10, 13); Fig. 4b's force.
    newton_iterations : int
        Newton iterations spent (all load steps together).
    """

    radii: np.ndarray
    heights: np.ndarray
    voltage: float
    disc_force: float
    newton_iterations: int

    @property
    def disc_position(self) -> float:
        """z = z_n [m]."""
        return float(self.heights[-1])


@dataclass(frozen=True)
class Linearisation:
    """Eq. (14) about an equilibrium: ``M_s q~'' + K_s q~ = d_per_volt V~(t)``.

    Attributes
    ----------
    equilibrium : Equilibrium
    coordinates : tuple of str
        Names of the generalised coordinates, ``"r1" .. "z{n}"`` (paper order).
    mass_matrix : ndarray
        M_s [kg] (eq. 14, from eq. 12).
    stiffness_matrix : ndarray
        K_s [N/m] (eq. 14, from eqs 11, 13; includes k_d when the disc is free).
    forcing_per_volt : ndarray
        d / V~ = V_b dC/dq [N/V] (eq. 14 corrected, see module notes).
    axial_stiffness : float
        k_DE = dF/dz of the membrane at fixed V_b [N/m] (static condensation of
        K_s without the spring onto z_n; the slope of Fig. 4b; Annex I).
    spring_preload : float
        l_b = z + F / k_d [m], the spring's rest position that makes ``z`` the
        equilibrium at V_b (eq. 13); ``nan`` when the disc is held or k_d = 0.
    """

    equilibrium: Equilibrium
    coordinates: tuple
    mass_matrix: np.ndarray
    stiffness_matrix: np.ndarray
    forcing_per_volt: np.ndarray
    axial_stiffness: float
    spring_preload: float


@dataclass(frozen=True)
class RingModel:
    """Lossless axisymmetric ring model of the COP-DEA (Sect. 3.2.1).

    Attributes
    ----------
    membrane : Membrane
        Constitutive law and film data (eqs 7, 20; Table 1).
    outer_radius, inner_radius : float
        r_o, r_i of the flat pre-stretched membrane [m] (Table 1).
    ring_count : int
        Number n of rings (Sect. 5.1 uses 6).
    disc_mass : float
        M_d [kg] (Table 1).
    disc_free : bool
        True: the disc rides on the spring (z_n is a coordinate, P1 exists);
        False: the disc is held (structural modes only).
    spring_stiffness : float
        k_d [N/m] (Table 1); used only when ``disc_free``.
    """

    membrane: Membrane
    outer_radius: float
    inner_radius: float
    ring_count: int
    disc_mass: float
    disc_free: bool = True
    spring_stiffness: float = 0.0

    def __post_init__(self):
        if not (isinstance(self.ring_count, (int, np.integer)) and self.ring_count >= 2):
            raise ReducedModelError(f"ring_count = {self.ring_count!r} is not allowed; "
                                    "allowed: an integer >= 2")
        if not 0 < self.inner_radius < self.outer_radius:
            raise ReducedModelError(
                f"inner_radius = {self.inner_radius!r} m is not allowed; allowed: "
                f"(0, {self.outer_radius:g}) m (the ring model needs a disc, r_i > 0)")
        if self.disc_mass <= 0 or self.spring_stiffness < 0:
            raise ReducedModelError(f"disc_mass = {self.disc_mass!r} kg, spring_stiffness = "
                                    f"{self.spring_stiffness!r} N/m are not allowed; allowed: "
                                    "disc_mass > 0, spring_stiffness >= 0")

    # -- construction -------------------------------------------------------------
    @classmethod
    def from_study(cls, study, ring_count: int | None = None) -> "RingModel":
        """Ring model of a :class:`copdea_fem.study.Study` (``reduced.rings`` rings)."""
        from copdea_fem.study import StudyError
        from copdea_fem.study.imperfections import imperfections_given
        given = imperfections_given(study)
        if given:
            raise StudyError(f"{given} is not allowed for the reduced model; allowed: "
                             "a perfect (round) device, the keys at their defaults (the ring "
                             "model of Sect. 3.2.1 is axisymmetric; the 3-D FE models "
                             "imperfections)")
        r_i = study.geometry.inner_radius
        if r_i == 0:
            raise StudyError("geometry.inner_radius = 0 is not allowed for the reduced model; "
                             f"allowed: (0, {study.geometry.outer_radius:g}) m "
                             "(the ring model of Sect. 3.2.1 needs the central disc)")
        return cls(membrane=Membrane.from_study(study),
                   outer_radius=study.geometry.outer_radius, inner_radius=r_i,
                   ring_count=int(ring_count or study.reduced.rings),
                   disc_mass=study.disc.mass,
                   disc_free=study.disc.motion == "spring",
                   spring_stiffness=study.spring.stiffness)

    def with_membrane(self, membrane: Membrane) -> "RingModel":
        return replace(self, membrane=membrane)

    # -- discretisation data -----------------------------------------------------------
    @property
    def node_count(self) -> int:
        return self.ring_count + 1

    @property
    def reference_radii(self) -> np.ndarray:
        """R_k of the flat pre-stretched membrane, k = 0..n [m] (Fig. 3b)."""
        return np.linspace(self.outer_radius, self.inner_radius, self.node_count)

    @property
    def ring_volumes(self) -> np.ndarray:
        """Omega_k = pi (R_{k-1}^2 - R_k^2) h0 / lambda_p^2 [m^3] (eq. 11)."""
        R = self.reference_radii
        return math.pi * (R[:-1] ** 2 - R[1:] ** 2) * self.membrane.prestretched_thickness

    @property
    def _meridian_factor(self) -> np.ndarray:
        """lambda_p^2 / (R_{k-1} - R_k)^2 [1/m^2]: lambda_1k^2 = this * s_k^2 (eq. 9)."""
        R = self.reference_radii
        return self.membrane.prestretch ** 2 / (R[:-1] - R[1:]) ** 2

    @property
    def _hoop_factor(self) -> np.ndarray:
        """lambda_p^2 / (R_{k-1} + R_k)^2 [1/m^2]: lambda_2k^2 = this * (r_{k-1}+r_k)^2."""
        R = self.reference_radii
        return self.membrane.prestretch ** 2 / (R[:-1] + R[1:]) ** 2

    @property
    def _ring_dofs(self) -> np.ndarray:
        """Indices of [r_{k-1}, r_k, z_{k-1}, z_k] in the full node vector [r_0..r_n, z_0..z_n]."""
        j = np.arange(self.ring_count)
        N = self.node_count
        return np.stack([j, j + 1, N + j, N + j + 1], axis=1)

    @property
    def disc_dof(self) -> int:
        """Index of z_n in the full node vector."""
        return 2 * self.node_count - 1

    @property
    def interior_dofs(self) -> np.ndarray:
        """r_1..r_{n-1}, z_1..z_{n-1}: the unknowns of the static solve."""
        n, N = self.ring_count, self.node_count
        return np.concatenate([np.arange(1, n), N + np.arange(1, n)])

    @property
    def free_dofs(self) -> np.ndarray:
        """The generalised coordinates q in paper order (eq. 10)."""
        if self.disc_free:
            return np.append(self.interior_dofs, self.disc_dof)
        return self.interior_dofs

    @property
    def coordinate_names(self) -> tuple:
        n = self.ring_count
        names = [f"r{k}" for k in range(1, n)] + [f"z{k}" for k in range(1, n)]
        return tuple(names + ([f"z{n}"] if self.disc_free else []))

    @property
    def membrane_mass(self) -> float:
        """rho0 h0/lambda_p^2 * pi (r_o^2 - r_i^2) [kg]."""
        return self.membrane.areal_density * math.pi * (self.outer_radius ** 2
                                                         - self.inner_radius ** 2)

    # -- kinematics (eq. 9) --------------------------------------------------------------
    def stretches_squared(self, radii, heights):
        """lambda_1k^2, lambda_2k^2 of every ring (eq. 9) [-], arrays of shape (n,)."""
        dr, dz = radii[:-1] - radii[1:], heights[:-1] - heights[1:]
        return (self._meridian_factor * (dr ** 2 + dz ** 2),
                self._hoop_factor * (radii[:-1] + radii[1:]) ** 2)

    def _stretch_derivatives(self, radii, heights):
        """x = lambda_1^2, y = lambda_2^2, their gradients (n,4) and Hessians (n,4,4)."""
        dr, dz = radii[:-1] - radii[1:], heights[:-1] - heights[1:]
        sr = radii[:-1] + radii[1:]
        a, b = self._meridian_factor, self._hoop_factor
        x, y = a * (dr ** 2 + dz ** 2), b * sr ** 2
        zero = np.zeros_like(dr)
        gx = 2 * a[:, None] * np.stack([dr, -dr, dz, -dz], axis=1)
        gy = 2 * (b * sr)[:, None] * np.stack([np.ones_like(dr), np.ones_like(dr), zero, zero],
                                              axis=1)
        hx = 2 * a[:, None, None] * _MERIDIAN_PATTERN
        hy = 2 * b[:, None, None] * _HOOP_PATTERN
        return x, y, gx, gy, hx, hy

    # -- elastic energy (eqs 13, 20) -----------------------------------------------------
    def elastic_energy(self, radii, heights, membrane: Membrane | None = None) -> float:
        """U_m of the membrane, sum_k Omega_k Psi_m (eq. 13 without the spring) [J]."""
        mat = membrane or self.membrane
        x, y = self.stretches_squared(radii, heights)
        return float(np.sum(self.ring_volumes * mat.strain_energy(x + y, x * y)))

    def elastic_derivatives(self, radii, heights, membrane: Membrane | None = None,
                            hessian: bool = True):
        """Gradient [N] and Hessian [N/m] of U_m in the full node vector (eq. 13).

        Chain rule: with x = lambda_1^2, y = lambda_2^2, tr = x + y, det = x y,
        Psi_x = Psi_tr + y Psi_det, Psi_y = Psi_tr + x Psi_det,
        Psi_xx = Psi_tr,tr + 2y Psi_tr,det + y^2 Psi_det,det (and x <-> y),
        Psi_xy = Psi_tr,tr + (x+y) Psi_tr,det + xy Psi_det,det + Psi_det;
        dU = Omega (Psi_x dx + Psi_y dy),
        d2U = Omega (Psi_xx dx dx + Psi_xy (dx dy + dy dx) + Psi_yy dy dy
                     + Psi_x d2x + Psi_y d2y).
        The partials of Psi come from ``Membrane.free_energy_partials`` at V = 0
        (pure eq. 20); the voltage enters through the capacitance instead.
        """
        mat = membrane or self.membrane
        x, y, gx, gy, hx, hy = self._stretch_derivatives(radii, heights)
        d_tr, d_det, d_tt, d_td, d_dd = mat.free_energy_partials(x + y, x * y, 0.0)
        psi_x, psi_y = d_tr + y * d_det, d_tr + x * d_det
        vol = self.ring_volumes
        ring_grad = vol[:, None] * (psi_x[:, None] * gx + psi_y[:, None] * gy)
        size = 2 * self.node_count
        dofs = self._ring_dofs
        grad = np.zeros(size)
        np.add.at(grad, dofs, ring_grad)
        if not hessian:
            return grad, None
        psi_xx = d_tt + 2 * y * d_td + y ** 2 * d_dd
        psi_yy = d_tt + 2 * x * d_td + x ** 2 * d_dd
        psi_xy = d_tt + (x + y) * d_td + x * y * d_dd + d_det
        outer = lambda u, v: u[:, :, None] * v[:, None, :]  # noqa: E731
        ring_hess = vol[:, None, None] * (
            psi_xx[:, None, None] * outer(gx, gx)
            + psi_xy[:, None, None] * (outer(gx, gy) + outer(gy, gx))
            + psi_yy[:, None, None] * outer(gy, gy)
            + psi_x[:, None, None] * hx + psi_y[:, None, None] * hy)
        hess = np.zeros((size, size))
        np.add.at(hess, (dofs[:, :, None], dofs[:, None, :]), ring_hess)
        return grad, hess

    # -- capacitance (eq. 11, corrected) -------------------------------------------------
    def ring_capacitances(self, radii, heights) -> np.ndarray:
        """C_k = eps A_k^2 / Omega_k with A_k = pi (r_{k-1} + r_k) s_k [F] (eq. 11)."""
        dr, dz = radii[:-1] - radii[1:], heights[:-1] - heights[1:]
        area = math.pi * (radii[:-1] + radii[1:]) * np.sqrt(dr ** 2 + dz ** 2)
        return self.membrane.permittivity * area ** 2 / self.ring_volumes

    def capacitance(self, radii, heights) -> float:
        """Total capacitance C = sum_{k=1..n} C_k [F] (eq. 11)."""
        return float(np.sum(self.ring_capacitances(radii, heights)))

    def capacitance_derivatives(self, radii, heights, hessian: bool = True):
        """Gradient [F/m] and Hessian [F/m^2] of C in the full node vector (eq. 11).

        C_k = c_k P Q with c_k = eps pi^2 / Omega_k, P = (r_{k-1}+r_k)^2,
        Q = s_k^2; dC_k = c_k (Q dP + P dQ),
        d2C_k = c_k (Q d2P + P d2Q + dP dQ + dQ dP).
        """
        dr, dz = radii[:-1] - radii[1:], heights[:-1] - heights[1:]
        sr = radii[:-1] + radii[1:]
        c = self.membrane.permittivity * math.pi ** 2 / self.ring_volumes
        P, Q = sr ** 2, dr ** 2 + dz ** 2
        zero, one = np.zeros_like(dr), np.ones_like(dr)
        gP = 2 * sr[:, None] * np.stack([one, one, zero, zero], axis=1)
        gQ = 2 * np.stack([dr, -dr, dz, -dz], axis=1)
        ring_grad = c[:, None] * (Q[:, None] * gP + P[:, None] * gQ)
        size = 2 * self.node_count
        dofs = self._ring_dofs
        grad = np.zeros(size)
        np.add.at(grad, dofs, ring_grad)
        if not hessian:
            return grad, None
        outer = lambda u, v: u[:, :, None] * v[:, None, :]  # noqa: E731
        ring_hess = c[:, None, None] * (
            Q[:, None, None] * 2 * _HOOP_PATTERN + P[:, None, None] * 2 * _MERIDIAN_PATTERN
            + outer(gP, gQ) + outer(gQ, gP))
        hess = np.zeros((size, size))
        np.add.at(hess, (dofs[:, :, None], dofs[:, None, :]), ring_hess)
        return grad, hess

    # -- potential Pi = U_m - V^2/2 C (eq. 10 without the spring) ------------------------
    def potential(self, radii, heights, voltage: float) -> float:
        """Pi = U_m - V^2/2 C [J] (eqs 10, 11, 13 without the spring)."""
        return (self.elastic_energy(radii, heights)
                - 0.5 * voltage ** 2 * self.capacitance(radii, heights))

    def potential_derivatives(self, radii, heights, voltage: float, hessian: bool = True):
        """Gradient [N] and Hessian [N/m] of Pi in the full node vector."""
        g_el, h_el = self.elastic_derivatives(radii, heights, hessian=hessian)
        g_c, h_c = self.capacitance_derivatives(radii, heights, hessian=hessian)
        half_v2 = 0.5 * voltage ** 2
        return g_el - half_v2 * g_c, (h_el - half_v2 * h_c) if hessian else None

    # -- kinetic energy (eq. 12) ---------------------------------------------------------
    def node_mass_matrix(self) -> np.ndarray:
        """Consistent scalar mass matrix 2 pi mu int N_a N_b R dR of the nodes [kg] (eq. 12).

        mu = rho0 h0 / lambda_p^2.  Ring from R_in = R_k to R_in + L: with
        R = R_in + xi L, int (1-xi)^2 R dR = L (R_in/3 + L/12),
        int xi (1-xi) R dR = L (R_in/6 + L/12), int xi^2 R dR = L (R_in/3 + L/4).
        """
        R = self.reference_radii
        r_in, length = R[1:], R[:-1] - R[1:]
        mu2pi = 2 * math.pi * self.membrane.areal_density
        outer_outer = mu2pi * length * (r_in / 3 + length / 4)
        outer_inner = mu2pi * length * (r_in / 6 + length / 12)
        inner_inner = mu2pi * length * (r_in / 3 + length / 12)
        N = self.node_count
        mass = np.zeros((N, N))
        j = np.arange(self.ring_count)
        np.add.at(mass, (j, j), outer_outer)
        np.add.at(mass, (j + 1, j + 1), inner_inner)
        np.add.at(mass, (j, j + 1), outer_inner)
        np.add.at(mass, (j + 1, j), outer_inner)
        return mass

    def full_mass_matrix(self) -> np.ndarray:
        """d^2 T / d qdot^2 in the full node vector, disc mass on z_n [kg] (eq. 12)."""
        m1 = self.node_mass_matrix()
        N = self.node_count
        mass = np.zeros((2 * N, 2 * N))
        mass[:N, :N] = m1
        mass[N:, N:] = m1
        mass[self.disc_dof, self.disc_dof] += self.disc_mass
        return mass

    # -- static equilibrium ----------------------------------------------------------------
    def flat_state(self):
        """Node positions of the flat pre-stretched membrane: r_k = R_k, z_k = 0 [m]."""
        return self.reference_radii.copy(), np.zeros(self.node_count)

    def _force_scale(self) -> float:
        """2 pi r_o c10 h0 [N]: the size of the membrane's nodal forces, for tolerances."""
        return 2 * math.pi * self.outer_radius * abs(self.membrane.c10) * self.membrane.thickness

    def equilibrium(self, z: float, voltage: float, start=None,
                    tolerance: float = 1e-10) -> Equilibrium:
        """Static equilibrium with the disc held at ``z`` [m] under ``voltage`` [V].

        Minimises Pi = U_m - V^2/2 C over r_1..r_{n-1}, z_1..z_{n-1} by Newton's
        method with a backtracking line search on Pi; if a step fails, the disc
        position is reached in smaller load steps from ``start`` (default: the
        flat state).  Converged when the largest interior nodal force is below
        ``tolerance * 2 pi r_o c10 h0`` (1e-10 of the membrane's force scale:
        Newton reaches ~1e-14, double round-off of the sums).

        Raises
        ------
        ReducedModelError
            Newton fails after 20 step halvings, or the membrane loses tension
            (a principal stress <= 0: wrinkles, outside the membrane model).
        """
        if start is None:
            start = self.flat_state()
        radii, heights = np.array(start[0], float), np.array(start[1], float)
        z_start, total_iterations = heights[-1], 0
        done, increment, halvings = 0.0, 1.0, 0
        while True:
            fraction = min(1.0, done + increment)
            target = z_start + fraction * (z - z_start)
            if heights[-1] != 0:   # predictor: scale the last profile to the new disc position
                trial_h = heights * (target / heights[-1])
            else:                  # from flat: a straight cone
                trial_h = (self.outer_radius - radii) / (self.outer_radius - radii[-1]) * target
            ok, r_new, h_new, its = self._newton(radii.copy(), trial_h, voltage, tolerance)
            total_iterations += its
            if ok:
                radii, heights, done = r_new, h_new, fraction
                if done >= 1.0:
                    break
            else:
                halvings += 1
                if halvings > 20:
                    raise ReducedModelError(
                        f"static equilibrium not found at load.z = {z:g} m, load.voltage = "
                        f"{voltage:g} V with {self.ring_count} rings (Newton failed after 20 "
                        "load-step halvings); allowed: a stable, tensioned membrane")
                increment *= 0.5
        self._check_tension(radii, heights, voltage, z)
        grad, _ = self.potential_derivatives(radii, heights, voltage, hessian=False)
        return Equilibrium(radii=radii, heights=heights, voltage=float(voltage),
                           disc_force=float(grad[self.disc_dof]),
                           newton_iterations=total_iterations)

    def _newton(self, radii, heights, voltage, tolerance, max_iterations=50):
        free = self.interior_dofs
        N = self.node_count
        state = np.concatenate([radii, heights])
        limit = tolerance * self._force_scale()
        energy = self._safe_potential(state, voltage)
        for iteration in range(max_iterations + 1):
            grad, hess = self.potential_derivatives(state[:N], state[N:], voltage)
            g = grad[free]
            if np.max(np.abs(g)) <= limit:
                return True, state[:N], state[N:], iteration
            if iteration == max_iterations or not np.isfinite(energy):
                return False, None, None, iteration
            H = hess[np.ix_(free, free)]
            step = _regularised_newton_step(H, g)
            length, accepted = 1.0, False
            while length > 1e-8:
                trial = state.copy()
                trial[free] += length * step
                trial_energy = self._safe_potential(trial, voltage)
                # Armijo with a slack of 1e-14 |Pi| so that round-off near the
                # minimum does not reject a Newton step that reduces |g|
                if trial_energy <= energy + 1e-4 * length * g @ step + 1e-14 * abs(energy):
                    accepted = True
                    break
                length *= 0.5
            if not accepted:
                return False, None, None, iteration
            state, energy = trial, trial_energy
        return False, None, None, max_iterations

    def _safe_potential(self, state, voltage) -> float:
        N = self.node_count
        x, y = self.stretches_squared(state[:N], state[N:])
        if np.any(x <= 0) or np.any(y <= 0):
            return math.inf
        value = self.potential(state[:N], state[N:], voltage)
        return value if math.isfinite(value) else math.inf

    def _check_tension(self, radii, heights, voltage, z):
        x, y = self.stretches_squared(radii, heights)
        s1, s2 = self.membrane.principal_stresses(np.sqrt(x), np.sqrt(y), voltage)
        if np.min(s1) <= 0 or np.min(s2) <= 0:
            raise ReducedModelError(
                f"load.voltage = {voltage:g} V at load.z = {z:g} m is not allowed: the membrane "
                f"loses tension (smallest principal stress {min(np.min(s1), np.min(s2)):.3g} Pa)"
                "; allowed: a voltage that keeps both principal stresses > 0 (no wrinkles)")

    def force_displacement(self, z_values, voltage: float) -> np.ndarray:
        """Static disc force F(z) [N] at ``voltage`` [V] for each z [m] (Fig. 4b).

        Solved in increasing |z| with each equilibrium started from the previous.
        """
        z_values = np.asarray(z_values, dtype=float)
        order = np.argsort(np.abs(z_values))
        forces = np.empty_like(z_values)
        state = None
        for index in order:
            eq = self.equilibrium(z_values[index], voltage, start=state)
            state = (eq.radii, eq.heights)
            forces[index] = eq.disc_force
        return forces

    # -- linearisation (eq. 14) -----------------------------------------------------------
    def linearise(self, equilibrium: Equilibrium) -> Linearisation:
        """M_s, K_s, d/V~ and k_DE about an equilibrium (eq. 14, corrected forcing)."""
        r, h, voltage = equilibrium.radii, equilibrium.heights, equilibrium.voltage
        g_el, h_el = self.elastic_derivatives(r, h)
        g_c, h_c = self.capacitance_derivatives(r, h)
        k_full = h_el - 0.5 * voltage ** 2 * h_c
        interior, disc = self.interior_dofs, self.disc_dof
        k_ii = k_full[np.ix_(interior, interior)]
        k_id = k_full[interior, disc]
        axial_stiffness = float(k_full[disc, disc] - k_id @ np.linalg.solve(k_ii, k_id))
        if self.disc_free:
            k_full = k_full.copy()
            k_full[disc, disc] += self.spring_stiffness
            preload = (equilibrium.disc_position + equilibrium.disc_force / self.spring_stiffness
                       if self.spring_stiffness > 0 else math.nan)
            unbalanced = abs(equilibrium.disc_force) > 1e-9 * self._force_scale()
            if self.spring_stiffness == 0 and unbalanced:
                raise ReducedModelError(
                    f"spring.stiffness = 0 N/m is not allowed with a free disc at load.z = "
                    f"{equilibrium.disc_position:g} m: nothing balances the membrane force "
                    f"{equilibrium.disc_force:.3g} N; allowed: > 0 N/m, or disc.motion = held")
        else:
            preload = math.nan
        free = self.free_dofs
        mass = self.full_mass_matrix()[np.ix_(free, free)]
        stiffness = k_full[np.ix_(free, free)]
        stiffness = 0.5 * (stiffness + stiffness.T)  # exact symmetry (assembly is symmetric)
        return Linearisation(equilibrium=equilibrium, coordinates=self.coordinate_names,
                             mass_matrix=mass, stiffness_matrix=stiffness,
                             forcing_per_volt=voltage * g_c[free],
                             axial_stiffness=axial_stiffness, spring_preload=preload)

    def operating_point(self, z: float, voltage: float) -> Linearisation:
        """Equilibrium at (z, V_b) and its linearisation (eq. 14) in one call."""
        return self.linearise(self.equilibrium(z, voltage))

    def expand(self, generalised) -> tuple[np.ndarray, np.ndarray]:
        """Node arrays (r, z) of a vector over the generalised coordinates (zeros elsewhere)."""
        full = np.zeros(2 * self.node_count, dtype=np.result_type(generalised, float))
        full[self.free_dofs] = generalised
        return full[:self.node_count], full[self.node_count:]


def _regularised_newton_step(H, g):
    """Newton step -H^-1 g; if H is not positive definite, H + mu I with growing mu."""
    shift = 0.0
    scale = max(np.max(np.abs(np.diag(H))), 1e-300)
    for _ in range(60):
        try:
            L = np.linalg.cholesky(H + shift * np.eye(len(g)))
            return -np.linalg.solve(L.T, np.linalg.solve(L, g))
        except np.linalg.LinAlgError:
            shift = 1e-8 * scale if shift == 0 else 4 * shift
    return -g / scale
