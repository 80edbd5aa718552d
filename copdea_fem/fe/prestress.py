"""Nonlinear electro-hyperelastic equilibrium of the membrane (Sect. 3.1, eqs 1-7, 20).

Minimises the membrane energy of :mod:`copdea_fem.fe.membrane` with the boundary
conditions of eq. (3): outer rim clamped in the pre-stretched position, inner
rim moving axially with the disc by ``z`` (in-plane fixed).  Newton's method
with an energy line search along a load path -- ``z`` from 0 to the target at
V = 0, then V from 0 to V_b -- with automatic step cutting.

A step that cannot converge, and an equilibrium that is lost, stop the solve
with a :class:`PrestressError` that says which and at what load:

* ``loss_of_tension`` -- a principal stress is no longer positive: a membrane
  cannot carry compression and wrinkles;
* ``pull_in``         -- the tangent stiffness lost positive definiteness
  (electromechanical instability);
* ``no_convergence``  -- Newton failed even after ``prestress.max_cuts`` halvings.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import ngsolve as ngs
import numpy as np

from copdea_fem.fe.materials import Membrane
from copdea_fem.fe.membrane import (
    displacement_space,
    energy_density,
    field_coefficients,
    membrane_measure,
)
from copdea_fem.fe.symmetry import SECTORS, Symmetry, bitarray, membrane_mirror_dofs

logger = logging.getLogger(__name__)


class PrestressError(RuntimeError):
    """The prestress solve failed; ``kind`` says why, ``z``/``voltage`` where [m, V]."""

    def __init__(self, kind: str, message: str, z: float, voltage: float):
        super().__init__(message)
        self.kind, self.z, self.voltage = kind, z, voltage


@dataclass
class PrestressedState:
    """A converged equilibrium on the flat reference mesh.

    Attributes
    ----------
    displacement : ngsolve.GridFunction
        u from the flat pre-stretched reference [m].
    z, voltage : float
        Disc displacement [m] and bias voltage [V] of this state.
    disc_force : float
        Axial force the biasing element must apply to hold the disc, dE/dz [N]
        (eq. 3-4 at rest: F_e = k_b (z - l_b)).
    newton_iterations : int
        Newton iterations over the whole load path.
    """

    mesh: object
    material: Membrane
    space: object
    displacement: object
    z: float
    voltage: float
    disc_force: float
    newton_iterations: int
    load_steps: list = field(default_factory=list)
    disc_lift: object = None        # unit axial disc displacement on the inner-rim DOFs
    outer_radius: float = 0.0       # m
    inner_radius: float = 0.0       # m
    # ds on the membrane, see copdea_fem.fe.membrane.membrane_measure
    measure: object = None
    symmetry: Symmetry = field(default_factory=Symmetry)   # the mesh's part of the device
    # (K, M) of copdea_fem.fe.linearise.membrane_matrices
    matrices: tuple | None = field(default=None, repr=False)
    # lumped masses on the membrane, ((mass [kg], x [m], y [m]), ...) on the reference
    # (imperfections.point_masses off the disc; copdea_fem.fe.linearise.point_mass_matrix)
    point_masses: tuple = ()

    @property
    def has_disc(self) -> bool:
        return self.disc_lift is not None

    def fields(self) -> dict:
        return field_coefficients(self.displacement, self.material, self.voltage)


class MembraneSolver:
    """Newton continuation for the membrane equilibrium on one mesh.

    Keeps the space, forms and the current state, so a sequence of loads (a
    force-displacement curve, a sweep over z and V_b) continues from the
    previous equilibrium.  ``settings``: the study's section ``study.prestress``.
    """

    #: NGSolve's factorisation of the Newton tangent: a sparse Cholesky (the tangent is
    #: SPD at a stable state; an indefinite one is caught by the descent test)
    inverse_kind = "sparsecholesky"

    def __init__(self, mesh, material: Membrane, order: int, outer_radius: float,
                 inner_radius: float, settings, curve_order: int = 1):
        self.mesh, self.material, self.settings = mesh, material, settings
        self.has_disc = inner_radius > 0
        self.outer_radius, self.inner_radius = outer_radius, inner_radius
        self.voltage = ngs.Parameter(0.0)
        self.z, self.newton_iterations, self.load_steps = 0.0, 0, []
        self.point_masses = ()     # the state's lumped membrane masses (make_solver sets them)
        self.space, self.free, self.symmetry, self.measure, density = self._discretise(
            order, curve_order)
        self.u = ngs.GridFunction(self.space, name="displacement")
        self.energy = ngs.BilinearForm(self.space, symmetric=True)
        self.energy += ngs.Variation(density(self.space.TrialFunction()) * self.measure)
        self.residual = self.u.vec.CreateVector()
        self.disc_lift = self.disc_extension = None
        if self.has_disc:
            self._build_disc_lift(outer_radius, inner_radius)
        self._prepare_stress_check()

    # -- the discretisation (the axisymmetric engine overrides these) ----------------
    def _discretise(self, order: int, curve_order: int):
        """(space, free DOFs, symmetry, measure, energy density of a trial function)."""
        space = displacement_space(self.mesh, order, self.has_disc)
        free = space.FreeDofs()
        symmetry = Symmetry.of_mesh(self.mesh)
        if symmetry.quarter:      # the prestress is even about both mirror planes
            mask = np.array(free)
            mask[membrane_mirror_dofs(space, self.mesh, order, SECTORS[0])] = False
            free = bitarray(mask)
        return (space, free, symmetry, membrane_measure(self.mesh, order, curve_order),
                lambda trial: energy_density(trial, self.material, self.voltage))

    def _prepare_stress_check(self) -> None:
        self._sample_points = _membrane_points(self.mesh, self.outer_radius, self.inner_radius,
                                               symmetry=self.symmetry)
        self._smallest_stress = field_coefficients(self.u, self.material, self.voltage)[
            "stress_2"].Compile()

    def _build_disc_lift(self, r_o: float, r_i: float) -> None:
        """Unit axial disc displacement: exact on the rims, log profile inside.

        ``disc_lift`` is nonzero on the inner-rim DOFs only (the Dirichlet data);
        ``disc_extension`` adds the small-z membrane shape w = ln(r_o/r)/ln(r_o/r_i)
        inside, a good Newton predictor for a z increment.
        """
        mesh = self.mesh
        lift = ngs.GridFunction(self.space)
        lift.Set(ngs.CF((0, 0, 1)), ngs.BBND, definedon=mesh.BBoundaries("inner_rim"))
        radius = ngs.sqrt(ngs.x**2 + ngs.y**2)
        extension = ngs.GridFunction(self.space)
        extension.Set(ngs.CF((0, 0, ngs.log(r_o / radius) / math.log(r_o / r_i))), ngs.BND,
                      definedon=mesh.Boundaries("membrane"))
        fixed = ~self.free
        ext = extension.vec.FV().NumPy()
        ext[np.array(fixed)] = lift.vec.FV().NumPy()[np.array(fixed)]
        self.disc_lift, self.disc_extension = lift, extension

    # -- energy, residual, force -------------------------------------------------
    def _assemble_residual(self) -> tuple[float, float]:
        """Residual dE/du at the current u; returns (free-DOF norm, reaction norm) [N]."""
        self.energy.Apply(self.u.vec, self.residual)
        values = self.residual.FV().NumPy()
        free = np.array(self.free)
        return float(np.linalg.norm(values[free])), float(np.linalg.norm(values[~free]))

    def disc_force(self) -> float:
        """dE/dz = residual . lift [N]: any lift with unit axial rim value gives the same
        (times the symmetry copies: a quadrant mesh carries a quarter of it)."""
        if not self.has_disc:
            return 0.0
        self.energy.Apply(self.u.vec, self.residual)
        return self.symmetry.copies * float(ngs.InnerProduct(self.residual, self.disc_lift.vec))

    def min_principal_stress(self) -> tuple[float, tuple[float, float]]:
        """Smallest principal Cauchy stress over the sample points [Pa], and where (r, theta)."""
        values = np.asarray(self._smallest_stress(self._sample_points["mesh_points"])).ravel()
        index = int(np.argmin(values))
        return float(values[index]), self._sample_points["polar"][index]

    # -- Newton -------------------------------------------------------------------
    def _newton(self) -> int:
        """Newton with an energy line search; returns iterations or raises _StepFailed."""
        settings = self.settings
        inverse_kind = self.inverse_kind
        for iteration in range(1, settings.max_newton_iter + 1):
            free_norm, reaction_norm = self._assemble_residual()
            if not math.isfinite(free_norm):
                raise _StepFailed("the residual is not finite")
            if free_norm <= settings.newton_tol * max(reaction_norm, 1e-300):
                return iteration - 1
            self.energy.AssembleLinearization(self.u.vec)
            inverse = self.energy.mat.Inverse(self.free, inverse=inverse_kind)
            step = (inverse * self.residual).Evaluate()
            slope = ngs.InnerProduct(step, self.residual)
            if not slope > 0:  # not a descent direction: tangent indefinite here
                raise _StepFailed("the tangent stiffness is not positive definite")
            energy0 = self.energy.Energy(self.u.vec)
            start = self.u.vec.CreateVector()
            start.data = self.u.vec
            alpha = 1.0
            while True:
                self.u.vec.data = start - alpha * step
                energy = self.energy.Energy(self.u.vec)
                # Armijo condition, with round-off slack near the minimum
                if math.isfinite(energy) and energy <= energy0 - 1e-4 * alpha * slope + \
                        1e-12 * abs(energy0):
                    break
                alpha *= 0.5
                if alpha < 1e-4:
                    self.u.vec.data = start
                    raise _StepFailed("the line search found no energy decrease")
        raise _StepFailed(f"no convergence in {settings.max_newton_iter} iterations")

    def _try_load(self, z: float, voltage: float) -> int:
        """Move to (z, V) from the current state; on failure restore it."""
        saved = self.u.vec.CreateVector()
        saved.data = self.u.vec
        saved_voltage = self.voltage.Get()
        if self.has_disc and z != self.z:
            self.u.vec.data += (z - self.z) * self.disc_extension.vec
        self.voltage.Set(voltage)
        try:
            iterations = self._newton()
        except _StepFailed:
            self.u.vec.data = saved
            self.voltage.Set(saved_voltage)
            raise
        self.z = z
        return iterations

    def go_to(self, z: float, voltage: float, steps: int) -> None:
        """Continue linearly from the current (z, V) to the target in adaptive steps."""
        z0, v0 = self.z, self.voltage.Get()
        s, ds_nominal = 0.0, 1.0 / steps
        ds = ds_nominal
        min_ds = ds_nominal / 2 ** self.settings.max_cuts
        while s < 1.0 - 1e-12:
            ds = min(ds, 1.0 - s)
            z_next, v_next = z0 + (s + ds) * (z - z0), v0 + (s + ds) * (voltage - v0)
            try:
                iterations = self._try_load(z_next, v_next)
            except _StepFailed as failure:
                if ds / 2 < min_ds * (1 - 1e-9):
                    raise self._diagnose(z_next, v_next, str(failure)) from None
                ds /= 2
                logger.info(f"  step cut: z = {z_next * 1e3:.3f} mm, V = {v_next:.0f} V "
                            f"({failure})")
                continue
            s += ds
            self.newton_iterations += iterations
            self.load_steps.append((z_next, v_next, iterations))
            logger.info(f"  z = {z_next * 1e3:7.3f} mm  V = {v_next:7.1f} V  "
                        f"Newton iterations: {iterations}")
            self._check_tension(z_next, v_next)
            if iterations <= 4:
                ds = min(2 * ds, ds_nominal)

    def _check_tension(self, z: float, voltage: float) -> None:
        stress, (radius, angle) = self.min_principal_stress()
        if stress <= 0:
            raise PrestressError(
                "loss_of_tension",
                f"loss of tension at z = {z * 1e3:.3f} mm, V_b = {voltage:.0f} V: the smallest "
                f"principal stress is {stress / 1e3:.3g} kPa at r = {radius * 1e3:.2f} mm; a "
                "membrane cannot carry compression and wrinkles. Lower load.voltage"
                + (" or membrane.prestretch_anisotropy" if self.material.anisotropy else "")
                + ", or raise membrane.prestretch or load.z.", z, voltage)

    def _diagnose(self, z: float, voltage: float, reason: str) -> PrestressError:
        """Why the last step failed: wrinkling, pull-in, or plain non-convergence."""
        stress, (radius, _) = self.min_principal_stress()
        where = f"between z = {self.z * 1e3:.3f} mm, V_b = {self.voltage.Get():.0f} V " \
                f"(last equilibrium) and z = {z * 1e3:.3f} mm, V_b = {voltage:.0f} V"
        if stress <= 0.05 * abs(self.material.c10):
            return PrestressError(
                "loss_of_tension", f"loss of tension {where}: the smallest principal stress "
                f"falls to {stress / 1e3:.3g} kPa at r = {radius * 1e3:.2f} mm and the membrane "
                "wrinkles. Lower load.voltage"
                + (" or membrane.prestretch_anisotropy" if self.material.anisotropy else "")
                + ", or raise membrane.prestretch.", z, voltage)
        if voltage != self.voltage.Get():
            return PrestressError(
                "pull_in", f"electromechanical instability (pull-in) {where}: {reason}. "
                "The bias voltage is beyond what this membrane can hold; lower load.voltage.",
                z, voltage)
        return PrestressError(
            "no_convergence", f"Newton did not converge {where}: {reason}. Raise "
            "prestress.z_steps or prestress.max_cuts, or refine the mesh.", z, voltage)

    def state(self) -> PrestressedState:
        u = ngs.GridFunction(self.space, name="displacement")
        u.vec.data = self.u.vec
        return PrestressedState(self.mesh, self.material, self.space, u, self.z,
                                self.voltage.Get(), self.disc_force(), self.newton_iterations,
                                list(self.load_steps), self.disc_lift, self.outer_radius,
                                self.inner_radius, self.measure, self.symmetry,
                                point_masses=self.point_masses)


class _StepFailed(Exception):
    pass


def _membrane_points(mesh, r_o: float, r_i: float, n_radii: int = 24, n_angles: int = 64,
                     symmetry: Symmetry = Symmetry()):
    """Polar sample points strictly inside the (meshed) membrane, for stress checks [m]."""
    inner = max(r_i, 0.02 * r_o)
    radii = inner + (r_o - inner) * (np.arange(n_radii) + 0.5) / n_radii
    angles = symmetry.angles(n_angles // symmetry.copies)
    rr, tt = np.meshgrid(radii, angles, indexing="ij")
    xs, ys = (rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel()
    return {"mesh_points": mesh(xs, ys, np.zeros_like(xs), ngs.BND),
            "polar": list(zip(rr.ravel(), tt.ravel()))}


def make_solver(study, mesh) -> MembraneSolver:
    g = study.geometry
    solver = MembraneSolver(mesh, Membrane.with_effects(study), study.mesh.order,
                            g.outer_radius, g.inner_radius, study.prestress,
                            curve_order=study.mesh.curve_order)
    solver.point_masses = membrane_point_masses(study)
    if disc_point_mass(study) and study.disc.motion == "held":
        logger.info(f"the point masses on the disc ({disc_point_mass(study) * 1e3:g} g) do "
                    "not move: the disc is held (disc.motion: held)")
    return solver


def membrane_point_masses(study) -> tuple:
    """The masses of ``imperfections.point_masses`` on the membrane, ``((mass [kg], x [m],
    y [m]), ...)`` on the flat reference (the disc's, ``r <= geometry.inner_radius``, are
    :func:`disc_point_mass`)."""
    r_i = study.geometry.inner_radius
    return tuple((point.mass, point.r * math.cos(math.radians(point.theta)),
                  point.r * math.sin(math.radians(point.theta)))
                 for point in study.imperfections.point_masses
                 if not (r_i > 0 and point.r <= r_i))


def disc_point_mass(study) -> float:
    """The masses of ``imperfections.point_masses`` on the rigid disc (``r <=
    geometry.inner_radius``) [kg]: they ride with the disc's axial motion, so they add to
    its mass (the disc has no tilt: their rotary inertia does not enter)."""
    r_i = study.geometry.inner_radius
    return float(sum(point.mass for point in study.imperfections.point_masses
                     if r_i > 0 and point.r <= r_i))


def solve_prestress(study, mesh, solver: MembraneSolver | None = None) -> PrestressedState:
    """Equilibrium at the study's (load.z, load.voltage): z first at V = 0, then V_b.

    Pass ``solver`` to continue from its current state (sweeps) instead.
    """
    solver = solver or make_solver(study, mesh)
    z, voltage = study.load.z, study.load.voltage
    settings = study.prestress
    if z != solver.z:
        solver.go_to(z, solver.voltage.Get(), settings.z_steps)
    if voltage != solver.voltage.Get():
        solver.go_to(z, voltage, settings.voltage_steps)
    solver._check_tension(z, voltage)
    return solver.state()


def force_displacement(study, mesh, z_values, voltages, new_solver=None) -> np.ndarray:
    """Static disc force F(z) [N] at each voltage (Fig. 4b): array (len(voltages), len(z)).

    Each curve continues in z from the flat state at its voltage.  ``new_solver``
    (default :func:`make_solver`) makes the solver of ``mesh``'s engine.
    """
    forces = np.empty((len(voltages), len(z_values)))
    settings = study.prestress
    new_solver = new_solver or make_solver
    for i, voltage in enumerate(voltages):
        solver = new_solver(study, mesh)
        solver.go_to(0.0, voltage, settings.voltage_steps)
        for j, z in enumerate(z_values):
            solver.go_to(z, voltage, settings.z_steps if j == 0 else 1)
            forces[i, j] = solver.disc_force()
    return forces
