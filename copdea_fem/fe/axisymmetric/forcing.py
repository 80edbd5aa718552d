"""The voltage forcing f [N/V] and the elastic stiffness K_el [N/m] of the order m = 0 on
the meridian: the axisymmetric engine's forced pencil
(:class:`copdea_fem.fe.forced.harmonic.ForcedOrder`) for
:func:`copdea_fem.fe.axisymmetric.forced.order_zero_problem`.

``f = -dR/dV = -2 (R(u0; V_b) - R(u0; 0)) / V_b`` and ``K_el`` the Hessian of the membrane
energy at ``(u0, V = 0)``, from the order-0 energy of
:func:`copdea_fem.fe.axisymmetric.operators.membrane_forms` (the derivation:
:mod:`copdea_fem.fe.forced.harmonic`; the 3-D counterpart: :mod:`copdea_fem.fe.quadrant.forced`).
"""

from __future__ import annotations

import types

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp

from copdea_fem.fe.axisymmetric.operators import membrane_forms
from copdea_fem.fe.forced.harmonic import (
    ForcedOrder,
    forcing_from_energy,
    reduce_matrix,
    reduce_vector,
)
from copdea_fem.fe.linearise import to_scipy


def forced_order(state, coupled, backend="superlu") -> ForcedOrder:
    """The m = 0 order of the axisymmetric engine with its voltage forcing f and elastic
    stiffness K_el (:mod:`copdea_fem.fe.forced.harmonic`)."""
    dry = coupled.membrane
    force, balance = voltage_forcing(state, dry)
    return ForcedOrder.from_parts(coupled, force, elastic_stiffness(state, dry), balance,
                                  backend)


def _energy_form(state, space, voltage, axis_m1=False, m=0, radial=None):
    """Variation form of the order-m membrane energy E(u0 + u; V) of the whole device
    (:func:`copdea_fem.fe.axisymmetric.membrane.order_energy`); ``radial``: a coefficient
    function rho(R) weighting the co-energy, an indicator (0 or 1; None: no weight).  The
    co-energy goes as V^2 (eq. 7) and nothing else depends on V, so the voltage
    ``V rho(R)`` weights it by rho^2 = rho and leaves the elastic energy as it is."""
    local = voltage if radial is None else voltage * radial
    at_voltage = types.SimpleNamespace(material=state.material, displacement=state.displacement,
                                       voltage=local, measure=state.measure)
    trial, test = space.TnT()
    energy, _ = membrane_forms(at_voltage, int(m), trial, test, axis_m1)
    form = ngs.BilinearForm(space, symmetric=False)
    form += ngs.Variation(energy)
    return form


def _order_lift(dry):
    return dry.lift.vec.FV().NumPy().copy() if dry.disc_dof else None


def voltage_forcing(state, dry) -> tuple[np.ndarray, float]:
    """f = -dR/dV at (u0, V_b) on the order-0 unknowns [N/V] (derivation:
    :mod:`copdea_fem.fe.forced.harmonic`), and the relative residual |R(u0; V_b)| / |R(u0; 0)|
    on the free DOFs (the prestress equilibrium check)."""
    if dry.m != 0:
        raise ValueError(f"order m = {dry.m} is not allowed for the voltage forcing; allowed: 0 "
                         "(a uniform electrode excites only the axisymmetric order)")
    voltage = ngs.Parameter(float(state.voltage))
    form = _energy_form(state, dry.space, voltage, dry.axis_m1)
    force, balance = forcing_from_energy(form, voltage, state.voltage,
                                     ngs.GridFunction(dry.space).vec, dry.free_dofs)
    return reduce_vector(force, dry.free_dofs, _order_lift(dry)), balance


def order_forcing(state, dry, radial=None) -> np.ndarray:
    """The forcing [N/V] on the order-m unknowns of the drive weight ``rho(R) cos(m theta)``
    on the co-energy (:mod:`copdea_fem.fe.forced.electrode`), for the cos family of ``dry``'s
    order; the uniform electrode's (:func:`voltage_forcing`) for m = 0 and ``rho = 1``.

    ``radial``: ``rho(R)``, a coefficient function of the reference radius (None: 1),
    weighting the co-energy inside the forcing integral (:func:`_energy_form`).

    For m >= 1 the order's energy is ``pi int [W(G0 + G_c) + W(G0 + G_s)] R dR``
    (:mod:`.membrane`), so its gradient at u = 0 is ``pi int W'(G0) : (G_c + G_s) R dR``.
    The weighted device's virtual work on the cos-family field
    ``(a cos, b sin, c cos)(m theta)`` is ``int_0^2pi cos(m theta) W_e'(G0) : (G_c cos m theta
    + G_s sin m theta) R dR dtheta = pi int W_e'(G0) : G_c R dR`` (W_e the co-energy part), and
    ``W_e'(G0) : G_s = 0``: at the axisymmetric prestress the stress of an isotropic energy
    has no entry where G_s has one ((1,2), (2,1), (3,2) of :mod:`.membrane`).  So the
    difference quotient of :func:`copdea_fem.fe.forced.harmonic.forcing_from_energy` on
    the order-m energy is this forcing, exactly."""
    if dry.m == 0 and radial is None:
        return voltage_forcing(state, dry)[0]
    voltage = ngs.Parameter(float(state.voltage))
    form = _energy_form(state, dry.space, voltage, dry.axis_m1, dry.m, radial)
    force, _ = forcing_from_energy(form, voltage, state.voltage,
                                   ngs.GridFunction(dry.space).vec, dry.free_dofs)
    return reduce_vector(force, dry.free_dofs, _order_lift(dry))


def weight_forcing(state, dry, weight) -> np.ndarray:
    """The forcing [N/V] on the order-m unknowns of ``rho(R) cos(m theta)``, ``rho`` the
    radial factor of ``weight`` (the protocol of :mod:`copdea_fem.fe.forced.electrode`:
    ``weight.radial_weight(R)``, None for 1), on the cos family of ``dry``'s order
    (:func:`order_forcing`)."""
    from copdea_fem.fe.axisymmetric.membrane import radius
    return order_forcing(state, dry, weight.radial_weight(radius()))


class WeightForcings:
    """:func:`weight_forcing` of one prestressed state for every order, the orders m >= 4
    from two assembled ones.

    The order-m forcing is ``pi int W_e'(G0) : G_c R dR`` (:func:`order_forcing`) and
    ``G_c`` is linear in m (:class:`copdea_fem.fe.axisymmetric.operators.OrderForms`), so on
    one space the forcing is ``f(m) = f(2) + (m - 2) (f(3) - f(2))``, exactly (round-off:
    2e-15 of it at m = 40, checked in the tests).  The forcings of the orders 2 and 3 are
    assembled once per space and radial factor (a weight's ``radii``); the others as
    :func:`weight_forcing`.  A drive of a segment's many Fourier orders then costs two
    assemblies, not one per order.
    """

    #: the orders whose forcing is assembled (the interpolation's nodes)
    NODES = (2, 3)

    def __init__(self, state):
        self.state = state
        self._assembled: dict = {}       # (id(space), radii, m) -> (space, forcing)

    def __call__(self, dry, weight) -> np.ndarray:
        """The forcing [N/V] of ``rho(R) cos(m theta)`` on ``dry``'s order (as
        :func:`weight_forcing`)."""
        m = int(dry.m)
        if m <= max(self.NODES) or dry.disc_dof:
            return self._assembled_forcing(dry, weight, m)
        low, high = (self._assembled_forcing(dry, weight, node) for node in self.NODES)
        return low + (m - self.NODES[0]) * (high - low)

    def _assembled_forcing(self, dry, weight, m: int) -> np.ndarray:
        key = (id(dry.space), getattr(weight, "radii", None), m)
        found = self._assembled.get(key)
        if found is None or found[0] is not dry.space:
            operators = dry if m == dry.m else _same_space_order(dry, m)
            found = (dry.space, weight_forcing(self.state, operators, weight))
            self._assembled[key] = found
        return found[1]


def _same_space_order(dry, m: int):
    """``dry`` (an order's operators, m >= 2) as the operators of order m on the same space:
    the forcing reads only its space, free DOFs, lift, axis flag and order."""
    import dataclasses
    return dataclasses.replace(dry, m=m)


def elastic_stiffness(state, dry) -> sp.csr_matrix:
    """K_el [N/m]: Hessian of the order-0 energy at (u0, V = 0) on the unknowns
    (:mod:`copdea_fem.fe.forced.harmonic`)."""
    form = _energy_form(state, dry.space, ngs.Parameter(0.0), dry.axis_m1)
    form.AssembleLinearization(ngs.GridFunction(dry.space).vec)      # E(u0 + u) at u = 0
    return reduce_matrix(to_scipy(form.mat), dry.free_dofs, _order_lift(dry))

