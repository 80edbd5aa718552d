r"""The forced response on the 3-D quadrant engine (any frame, the square one included).

A uniform electrode drives a field that is even about x = 0 and y = 0, so only the
even-even sector of the quadrant (:mod:`copdea_fem.fe.symmetry`) responds; its pencil is
:meth:`copdea_fem.fe.coupled.CoupledAssembly.restrict` of that sector.  Forcing and loss are
those of :mod:`copdea_fem.fe.forced.harmonic` (the derivation there), from the 3-D energy of
:func:`copdea_fem.fe.membrane.energy_density` on the quadrant's membrane:
``f = -2 (R(u0; V_b) - R(u0; 0)) / V_b`` reduced to the sector's free DOFs (and
``lift . f`` for the disc on the spring), ``K_el`` the Hessian at ``(u0, V = 0)``.

Where an imperfection breaks a mirror plane (:func:`copdea_fem.fe.symmetry.mirror_breaking`)
the whole device is meshed and there is no sector: the voltage then drives every order that
the imperfection couples to m = 0 (an anisotropy along 30 deg the (2,n) members, a mass off
the axis every order), and the response says so (``WHOLE_DEVICE``).

Observation: the vibrometer's points at projected radius ``r`` and polar angles
``OBSERVATION_ANGLES`` in the quadrant (the square frame makes the response depend slightly
on the angle; the average spectrum averages |v| over radii and angles), on a whole device
the same angles in each of the four quadrants (``WHOLE_ANGLES``: an imperfect device's
response is not the same in each); the reference point of ``(r cos phi, r sin phi)`` is
found on the prestressed profile along that ray.  Sound:
Kirchhoff-Helmholtz over the sphere 0.85 R as in :mod:`copdea_fem.fe.forced.radiation`,
here with 3-D surface quadrature (Gauss in the polar angle, trapezoidal in the azimuth), the
quadrant's field unfolded by the even-even parity ``p(x, y, z) = p(|x|, |y|, z)``.
"""

from __future__ import annotations

import functools
import logging
import time
from dataclasses import replace

import ngsolve as ngs
import numpy as np

from copdea_fem.fe.forced.harmonic import (
    ForcedOrder,
    checked_bias,
    forcing_from_energy,
    reduce_matrix_3d,
    reduce_vector_3d,
)
from copdea_fem.fe.forced.problem import DrivenSector, OrderZero
from copdea_fem.fe.forced.radiation import (
    AZIMUTH_POINTS,
    green_kernels,
    polar_quadrature,
    sampling_matrix,
)

#: Polar angles of the observation points in the quadrant [rad].
OBSERVATION_ANGLES = np.radians([11.25, 33.75, 56.25, 78.75])
#: ... and on a whole device: the same in each quadrant [rad].
WHOLE_ANGLES = np.concatenate([OBSERVATION_ANGLES + k * np.pi / 2 for k in range(4)])


logger = logging.getLogger(__name__)


#: Quadrature order added to the forcing of a drive weight (a segment's indicator is
#: discontinuous across its edges, which cut the elements, and the rule samples it; the
#: uniform electrode of ``response``, no weight, keeps the membrane's rule); it includes the
#: curved elements' own 2 (curve_order - order) of
#: :func:`copdea_fem.fe.membrane.membrane_measure`.  Measured on the quick G1, the ratio of
#: two sector widths' modal forces (m = 1..5) against sin(m a/2)/sin(m b/2): 4-16 % off and
#: not converging with h under the default rule, 0.16 % at 3 mm with this one.
WEIGHT_BONUS_INTORDER = 16


def _energy_form(state, voltage, weight=None, voltage_derivative=False):
    """Variation form of the quadrant's membrane energy; ``weight``: a coefficient function
    multiplying the density (its electrostatic part is what the forcing reads);
    ``voltage_derivative``: of the density's derivative in ``voltage`` instead (its
    electrostatic part only, :func:`sector_forcing`)."""
    from copdea_fem.fe.membrane import energy_density
    u = state.space.TrialFunction()
    density = energy_density(u, state.material, voltage)
    if voltage_derivative:
        density = density.Diff(voltage)
    form = ngs.BilinearForm(state.space, symmetric=False)
    if weight is None:
        form += ngs.Variation(density * state.measure)
    else:       # every weight on one rule: the segments of a turn sum to the whole electrode
        measure = ngs.ds(definedon=state.mesh.Boundaries("membrane"),
                         bonus_intorder=WEIGHT_BONUS_INTORDER)
        form += ngs.Variation(weight * density * measure)
    return form


def quadrant_forcing(state, operators, imperfection=None):
    """f [N/V] on the sector's unknowns and the equilibrium residual (:mod:`.harmonic`).

    ``imperfection``: a drive weight (the protocol of :mod:`copdea_fem.fe.forced.electrode`:
    an :class:`~copdea_fem.fe.forced.electrode.ElectrodeImperfection`, a
    :class:`~copdea_fem.fe.forced.electrode.SegmentWeight`); the forcing is then that
    weight's on the operators' sector (the weight W_s of its eq. 2 on the co-energy; the
    residual is the weighted energy's, 0 only for the uniform electrode)."""
    voltage = ngs.Parameter(float(state.voltage))
    weight = None
    if imperfection is not None:
        weight = imperfection.sector_weight(operators.sector, ngs.x, ngs.y)
    force, balance = forcing_from_energy(_energy_form(state, voltage, weight), voltage,
                                         state.voltage, state.displacement.vec,
                                         operators.free_dofs)
    return reduce_vector_3d(force, operators), balance


def sector_forcing(state, operators, imperfection=None):
    """f [N/V] on the sector's unknowns of :func:`quadrant_forcing`, without the residual.

    The same ``f = -dR/dV (u0, V_b)`` as the difference quotient of
    :func:`copdea_fem.fe.forced.harmonic.forcing_from_energy`, here as one application of
    the Variation of ``dPsi/dV`` (NGSolve's symbolic derivative of the density in the
    voltage): R is linear in the density, so ``dR/dV`` is the residual of ``dPsi/dV``, and
    ``dPsi/dV`` holds only the co-energy's terms (the strain energy does not depend on V).
    One residual of the electrostatic part instead of two of the whole energy; equal to the
    difference quotient to rounding (it also skips that quotient's cancellation of the
    strain energy's residual).  Used where the residual is not wanted (the modal model's
    inputs, :meth:`copdea_fem.fe.quadrant.engine.QuadrantEngine.electrode_forcing`)."""
    voltage = ngs.Parameter(checked_bias(state.voltage))
    weight = None
    if imperfection is not None:
        weight = imperfection.sector_weight(operators.sector, ngs.x, ngs.y)
    at = state.displacement.vec
    derivative = at.CreateVector()
    _energy_form(state, voltage, weight, voltage_derivative=True).Apply(at, derivative)
    return reduce_vector_3d(-np.array(derivative.FV().NumPy()), operators)


def quadrant_elastic(state, operators):
    """K_el [N/m] on the sector's unknowns: the Hessian at (u0, V = 0)."""
    from copdea_fem.fe.linearise import to_scipy
    form = _energy_form(state, ngs.Parameter(0.0))
    form.AssembleLinearization(state.displacement.vec)
    return reduce_matrix_3d(to_scipy(form.mat), operators)


def prepare_quadrant(study):
    """Mesh, prestress, coupled assembly and the even-even sector, forced."""
    from copdea_fem.fe.coupled import assemble_coupled
    from copdea_fem.fe.linearise import linearised_operators, membrane_matrices, operator_damping
    from copdea_fem.fe.prestress import solve_prestress
    from copdea_fem.fe.quadrant.geometry import study_mesh
    from copdea_fem.fe.symmetry import SECTORS

    timings = {}
    start = time.perf_counter()
    mesh = study_mesh(study, with_air=True)
    logger.info("prestress (Newton, load steps in z then V_b) ...")
    state = solve_prestress(study, mesh)
    timings["prestress"] = time.perf_counter() - start
    start = time.perf_counter()
    matrices = membrane_matrices(state)
    forms = assemble_coupled(study, mesh, state)
    sector = SECTORS[0] if state.symmetry.quarter else None
    operators = linearised_operators(state, study, sector, matrices)
    coupled = forms.restrict(operators)
    force, balance = quadrant_forcing(state, operators)
    elastic = quadrant_elastic(state, operators)
    forced = ForcedOrder.from_parts(coupled, force, elastic, balance, study.eigen.backend)
    forced.with_damping(operator_damping(operators, study))
    cavity, dry_band = None, None
    # over an enclosure the air changes what the m = 0 modes are (a vent's Helmholtz mode,
    # the stiffened (0,1)): cavity orders and dry partners, as solve (_label); an open back
    # costs no dry solve
    if study.geometry.enclosure != "none":
        from copdea_fem.fe.quadrant.cavity import QuadrantCavitySampler
        from copdea_fem.fe.quadrant.geometry import GeometrySpec
        from copdea_fem.fe.quadrant.labels import sector_dry_modes
        cavity = QuadrantCavitySampler(coupled.pressure_space, GeometrySpec.from_study(study))
        dry_band = functools.partial(sector_dry_modes, operators, study, 0.0)
    timings["assembly"] = time.perf_counter() - start
    return OrderZero(study, state, coupled, forced, timings,
                     QUADRANT_SECTOR if sector is not None else WHOLE_DEVICE, cavity=cavity,
                     dry_band=dry_band)


class QuadrantObserver:
    """u_z and u_r = u . e_r at projected radii and OBSERVATION_ANGLES (module doc)."""

    angles = OBSERVATION_ANGLES

    def __init__(self, state, operators, fractions):
        self.state, self.operators = state, operators
        mesh = state.mesh
        r_i, r_o = state.inner_radius, state.outer_radius
        grid = np.linspace(r_i, r_o, 401)
        self.projected = r_i + np.asarray(fractions, float) * (r_o - r_i)
        points, directions = [], []
        for phi in self.angles:
            e = np.array([np.cos(phi), np.sin(phi)])
            ray = mesh(grid * e[0], grid * e[1], np.zeros_like(grid), ngs.BND)
            u0 = np.asarray(state.displacement(ray))
            deformed = grid + u0[:, :2] @ e
            reference = np.interp(self.projected, deformed, grid)
            points.append(reference[:, None] * e[None, :])
            directions.append(np.broadcast_to(e, (reference.size, 2)))
        self.points = np.concatenate(points)
        self.directions = np.concatenate(directions)
        self.mesh_points = mesh(self.points[:, 0], self.points[:, 1],
                                np.zeros(len(self.points)), ngs.BND)
        self.gf = ngs.GridFunction(state.space)

    def observe(self, membrane_vectors):
        """(axial, radial) (points, columns); points = radii x angles, radius fastest."""
        full = self.operators.to_full(np.asarray(membrane_vectors))
        axial = np.zeros((len(self.points), full.shape[1]), complex)
        radial = np.zeros_like(axial)
        for k in range(full.shape[1]):
            for part, factor in ((full[:, k].real, 1.0), (full[:, k].imag, 1j)):
                self.gf.vec.FV().NumPy()[:] = part
                values = np.asarray(self.gf(self.mesh_points))
                axial[:, k] += factor * values[:, 2]
                radial[:, k] += factor * np.einsum("ij,ij->i", values[:, :2], self.directions)
        return axial, radial

    def average(self, values):
        """Mean over angles of (points, ...) -> (radii, ...)."""
        return values.reshape(len(self.angles), -1, *values.shape[1:])


class WholeObserver(QuadrantObserver):
    """:class:`QuadrantObserver` on a whole device: at ``WHOLE_ANGLES`` (module doc)."""

    angles = WHOLE_ANGLES


class QuadrantSphere:
    """p, dp/drho of sector pressure vectors on the Kirchhoff sphere (3-D quadrature)."""

    def __init__(self, coupled, radius: float, hemispheres=("upper", "lower")):
        mesh = coupled.pressure_space.mesh
        self.coupled, self.radius = coupled, radius
        polar, weight = polar_quadrature(hemispheres)
        phi = 2 * np.pi * (np.arange(AZIMUTH_POINTS) + 0.5) / AZIMUTH_POINTS
        theta, azimuth = np.meshgrid(polar, phi, indexing="ij")
        self.xyz = radius * np.stack([np.sin(theta) * np.cos(azimuth),
                                      np.sin(theta) * np.sin(azimuth), np.cos(theta)],
                                     axis=-1).reshape(-1, 3)
        self.area = (np.repeat(weight * np.sin(polar), AZIMUTH_POINTS) * radius ** 2
                     * 2 * np.pi / AZIMUTH_POINTS)
        folded = np.abs(self.xyz[:, :2]) if coupled.membrane.sector is not None else \
            self.xyz[:, :2]
        self.points = mesh(folded[:, 0], folded[:, 1], self.xyz[:, 2])
        self.sign = np.where(self.xyz[:, :2] < 0, -1.0, 1.0) if coupled.membrane.sector \
            is not None else np.ones((len(self.xyz), 2))
        self.gf = ngs.GridFunction(coupled.pressure_space)
        from copdea_fem.fe.acoustics import outside_pressures

        # the outside air's pressure (an enclosure's cavity lies inside the sphere)
        upper, lower = outside_pressures(tuple(self.gf.components))
        self._upper, self._lower = (
            ngs.CF((sum(parts[1:], parts[0]),
                    sum((ngs.grad(part) for part in parts[1:]), ngs.grad(parts[0]))))
            for parts in (upper, lower))
        self.is_upper = self.xyz[:, 2] > 0
        self._upper_points = self.points[self.is_upper]
        self._lower_points = self.points[~self.is_upper]
        self.normal = self.xyz / radius
        self._sampling = None

    def _values(self):
        """(points, 4) p and grad p of what ``self.gf`` holds, each half at its points
        (real: ``gf`` holds a real indicator vector, :func:`.radiation.sampling_matrix`; the
        complex space - the PML's - returns it with a zero imaginary part)."""
        values = np.empty((len(self.xyz), 4))
        values[self.is_upper] = np.asarray(self._upper(self._upper_points)).real
        values[~self.is_upper] = np.asarray(self._lower(self._lower_points)).real
        return values

    def sample(self, pressure_vectors):
        """(p, dp/drho) (points, columns) of pressure vectors on the sector's free DOFs: one
        sampling matrix (:func:`.radiation.sampling_matrix`, built once) for all columns."""
        pressure_vectors = np.atleast_2d(np.asarray(pressure_vectors).T).T
        if self._sampling is None:
            self._sampling = sampling_matrix(self.gf, self.coupled.pressure_free,
                                             self.points["nr"], self._values)
        values = (self._sampling @ pressure_vectors).reshape(len(self.xyz), 4, -1)
        gradient = values[:, 1:].copy()
        gradient[:, :2] *= self.sign[:, :, None]          # even parity: d/dx flips with x
        return values[:, 0], np.einsum("ijk,ij->ik", gradient, self.normal)

    def kernels(self, microphone, wavenumber: float, baffle: bool):
        """(K_p, K_g) per sphere point (:func:`.radiation.kirchhoff_kernels`): the shared
        :func:`.radiation.green_kernels` times the quadrature areas."""
        d_green, green = green_kernels(self.xyz, self.normal, microphone, wavenumber, baffle)
        return d_green * self.area, green * self.area


def _classify(problem, result):
    """The modes of the forced even-even band with their membrane-energy fractions, and
    their pressure vectors (:func:`copdea_fem.fe.modes.coupled_mode_list`)."""
    from copdea_fem.fe.modes import ModeSampler, coupled_mode_list
    return coupled_mode_list(problem.coupled, result, problem.study.air.min_membrane_energy,
                             ModeSampler(problem.state))


def _label(problem, modes, pressures, f_max: float) -> None:
    """Name the modes of the forced even-even band of ``f_max`` [Hz] as ``solve`` names
    its sectors' (:func:`copdea_fem.fe.quadrant.labels.label_cavity_orders`,
    :func:`copdea_fem.fe.quadrant.labels.name_coupled_modes`): over an enclosure with the
    cavity orders and the dry partners below :data:`copdea_fem.fe.bands.DRY_PARTNER_FACTOR`
    f_max; the air modes (also those the response's band adds) are ``air``."""
    from copdea_fem.fe.bands import DRY_PARTNER_FACTOR
    from copdea_fem.fe.linearise import membrane_matrices
    from copdea_fem.fe.modes import AIR
    from copdea_fem.fe.quadrant.labels import label_cavity_orders, name_coupled_modes
    for mode in modes:
        if mode.kind == AIR:
            mode.label, mode.m, mode.n = "air", 0, 0
    coupled = problem.coupled
    if problem.cavity is not None:
        label_cavity_orders(problem.cavity, coupled.membrane.sector, coupled, modes, pressures)
    name_coupled_modes(modes, problem.dry_partners(DRY_PARTNER_FACTOR * f_max),
                       membrane_matrices(problem.state)[1])


def _write_shapes(staging, state, coupled, shapes, pressures):
    from copdea_fem.fe.quadrant.fields import MembraneSampler, write_air_vtus, write_mode_vtus
    return (write_mode_vtus(staging, state, shapes, MembraneSampler(state.mesh)),
            write_air_vtus(staging, [coupled], shapes, pressures))


QUADRANT_SECTOR = DrivenSector(
    name="even-even sector", excited="even-even symmetry sector",
    summary="3-D, even-even sector", classify=_classify, label=_label,
    observer=QuadrantObserver, angles=len(OBSERVATION_ANGLES), sphere=QuadrantSphere,
    shape_sector=lambda operators: operators.sector, write_shapes=_write_shapes,
    default_method="reduced",      # its modal band costs minutes
    modal_method="reduced_modal")

#: The whole device (an imperfection broke a mirror plane): no sector, every order driven.
WHOLE_DEVICE = replace(
    QUADRANT_SECTOR, name="whole device", summary="3-D, whole device",
    excited="whole device (an imperfection breaks the mirror planes: every order it couples)",
    observer=WholeObserver, angles=len(WHOLE_ANGLES))
