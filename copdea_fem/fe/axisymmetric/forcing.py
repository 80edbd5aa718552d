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


def _energy_form(state, space, voltage, axis_m1=False):
    """Variation form of the order-0 membrane energy E(u0 + u; V) of the whole device."""
    at_voltage = types.SimpleNamespace(material=state.material, displacement=state.displacement,
                                       voltage=voltage, measure=state.measure)
    trial, test = space.TnT()
    energy, _ = membrane_forms(at_voltage, 0, trial, test, axis_m1)
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


def elastic_stiffness(state, dry) -> sp.csr_matrix:
    """K_el [N/m]: Hessian of the order-0 energy at (u0, V = 0) on the unknowns
    (:mod:`copdea_fem.fe.forced.harmonic`)."""
    form = _energy_form(state, dry.space, ngs.Parameter(0.0), dry.axis_m1)
    form.AssembleLinearization(ngs.GridFunction(dry.space).vec)      # E(u0 + u) at u = 0
    return reduce_matrix(to_scipy(form.mat), dry.free_dofs, _order_lift(dry))

