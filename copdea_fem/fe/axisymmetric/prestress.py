"""Axisymmetric prestress: the 1-D equilibrium u_r(R), u_z(R) of the same energy.

The Newton continuation, load path, step cutting and failure diagnosis are
those of :class:`copdea_fem.fe.prestress.MembraneSolver`; only the space and the
energy differ: ``(u_r, u_z)`` on the membrane line of the meridian mesh with
the energy ``2 pi int W(G0) R dR`` of :mod:`.membrane`.  Rims as in eq. (3):
the outer rim clamped, the inner rim moving axially with the disc by z.
"""

from __future__ import annotations

import math

import ngsolve as ngs
import numpy as np

from copdea_fem.fe.axisymmetric.membrane import prestress_energy, prestress_gradient
from copdea_fem.fe.axisymmetric.meridian import LineSampler
from copdea_fem.fe.axisymmetric.perturbation import round_material
from copdea_fem.fe.materials import Membrane
from copdea_fem.fe.prestress import MembraneSolver, PrestressedState
from copdea_fem.fe.symmetry import Symmetry


def _membrane_line_space(mesh, order: int, has_disc: bool):
    rims = "outer_rim|inner_rim" if has_disc else "outer_rim"
    space = ngs.VectorH1(mesh, order=order, definedon=mesh.Boundaries("membrane"),
                         dirichlet_bbnd=rims)
    return ngs.Compress(space)


class AxisymmetricState(PrestressedState):
    """A converged axisymmetric equilibrium; ``displacement`` = (u_r, u_z) on the meridian."""

    engine = "axisymmetric"

    def fields(self) -> dict:
        """:func:`axisymmetric_fields` of this state (CoefficientFunctions of its displacement
        GridFunction), built once per displacement, material and voltage."""
        key = (id(self.displacement), id(self.material), self.voltage)
        if getattr(self, "_fields", (None,))[0] != key:
            self._fields = (key, axisymmetric_fields(self.displacement, self.material,
                                                     self.voltage))
        return self._fields[1]

    def line(self) -> LineSampler:
        """The membrane line's sampler (:class:`.meridian.LineSampler`), made once per state."""
        if getattr(self, "_line", None) is None:
            self._line = LineSampler(self.mesh)
        return self._line

    def profile(self, radii) -> np.ndarray:
        """(u_r, u_z) [m] at reference radii ``radii`` [m]: array (len, 2)."""
        return self.line().at(self.displacement, radii)


def axisymmetric_fields(u, material: Membrane, voltage: float) -> dict:
    """Post-processing fields of the prestress (SI) as CFs on the membrane line.

    The axisymmetric principal directions are meridional and hoop:
    lambda_m = lambda_p |(1 + u_r', u_z')|, lambda_h = lambda_p (1 + u_r/R);
    ``stretch_1`` is the larger (as :func:`copdea_fem.fe.membrane.field_coefficients`),
    ``stress_1`` the stress along it; ``normal`` = (n_r, n_z).
    """
    g0 = prestress_gradient(u)
    slope = ngs.sqrt((1 + g0[0, 0]) ** 2 + g0[2, 0] ** 2)
    meridional, hoop = slope * material.prestretch, (1 + g0[1, 1]) * material.prestretch
    tr_c, det_c = meridional**2 + hoop**2, meridional**2 * hoop**2
    d_tr, d_det, *_ = material.free_energy_partials(tr_c, det_c, voltage)
    stress_meridional = 2 * meridional**2 * (d_tr + hoop**2 * d_det)
    stress_hoop = 2 * hoop**2 * (d_tr + meridional**2 * d_det)
    meridional_larger = meridional - hoop
    tangent = ngs.CF((1 + g0[0, 0], g0[2, 0])) / slope
    return {
        "displacement": u,
        "stretch_1": ngs.IfPos(meridional_larger, meridional, hoop),
        "stretch_2": ngs.IfPos(meridional_larger, hoop, meridional),
        "stress_1": ngs.IfPos(meridional_larger, stress_meridional, stress_hoop),
        "stress_2": ngs.IfPos(meridional_larger, stress_hoop, stress_meridional),
        "thickness": material.thickness_at(det_c),
        "e_field": material.electric_field(det_c, voltage),
        "normal": ngs.CF((-tangent[1], tangent[0])),
    }


class AxisymmetricMembraneSolver(MembraneSolver):
    """:class:`MembraneSolver` on the membrane line of a meridian mesh."""

    #: the line's tangent has tens of unknowns (38 for G1 at order 3): NGSolve's sparse
    #: Cholesky's set-up costs far more per factorisation, whatever the size, than UMFPACK's
    #: whole factorisation of so small a matrix, and the line is factorised once per Newton
    #: iteration.
    #: On the 3-D membrane (thousands of unknowns) the Cholesky is the faster one.
    inverse_kind = "umfpack"

    def _discretise(self, order: int, curve_order: int):
        """(u_r, u_z) on the membrane line; energy 2 pi int W(G0) R dR (.membrane)."""
        space = _membrane_line_space(self.mesh, order, self.has_disc)
        measure = ngs.ds(definedon=self.mesh.Boundaries("membrane"), bonus_intorder=2)
        return (space, space.FreeDofs(), Symmetry(), measure,
                lambda trial: prestress_energy(trial, self.material, self.voltage))

    def _prepare_stress_check(self) -> None:
        self._line = LineSampler(self.mesh, points_per_element=5)
        fields = axisymmetric_fields(self.u, self.material, self.voltage)
        first, second = fields["stress_1"], fields["stress_2"]
        self._smallest_stress = ngs.IfPos(first - second, second, first).Compile()

    def min_principal_stress(self) -> tuple[float, tuple[float, float]]:
        """Smallest principal Cauchy stress on the membrane line [Pa], and where (r, 0)."""
        values = self._line.values(self._smallest_stress).ravel()
        index = int(np.argmin(values))
        return float(values[index]), (float(self._line.radii.ravel()[index]), 0.0)

    def _build_disc_lift(self, r_o: float, r_i: float) -> None:
        """Unit axial disc displacement on the inner rim; log profile inside (predictor)."""
        extension = ngs.GridFunction(self.space)
        extension.Set(ngs.CF((0, ngs.log(r_o / ngs.x) / math.log(r_o / r_i))), ngs.BND,
                      definedon=self.mesh.Boundaries("membrane"))
        lift = ngs.GridFunction(self.space)     # the rim values only (1 at r_i, 0 at r_o)
        lift.vec.FV().NumPy()[:] = np.where(np.array(self.free), 0.0,
                                            extension.vec.FV().NumPy())
        self.disc_lift, self.disc_extension = lift, extension

    def state(self) -> AxisymmetricState:
        u = ngs.GridFunction(self.space, name="displacement")
        u.vec.data = self.u.vec
        return AxisymmetricState(self.mesh, self.material, self.space, u, self.z,
                                 self.voltage.Get(), self.disc_force(), self.newton_iterations,
                                 list(self.load_steps), self.disc_lift, self.outer_radius,
                                 self.inner_radius, self.measure, self.symmetry)


def make_axisymmetric_solver(study, mesh) -> AxisymmetricMembraneSolver:
    """The Newton solver of the round device: an imperfect film's round part (its
    imperfection enters by perturbation, :mod:`.perturbation`)."""
    g = study.geometry
    return AxisymmetricMembraneSolver(mesh, round_material(Membrane.with_effects(study)),
                                      study.mesh.order,
                                      g.outer_radius, g.inner_radius,
                                      study.prestress,
                                      curve_order=study.mesh.curve_order)
