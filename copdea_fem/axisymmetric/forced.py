"""The forced response on the axisymmetric engine: the order m = 0 that a uniform electrode
drives, on the meridian (the 3-D counterpart: :mod:`copdea_fem.quadrant.forced`).

:func:`order_zero_problem` builds the forced m = 0 pencil on a prestressed meridian (the
engine, :meth:`copdea_fem.axisymmetric.engine.AxisymmetricEngine.forced_problem`, makes
the mesh and the prestress): the voltage forcing f and the elastic stiffness K_el of the
order-0 energy (:func:`voltage_forcing`, :func:`elastic_stiffness`; the derivation in
:mod:`copdea_fem.forced.harmonic`) on :class:`copdea_fem.forced.harmonic.ForcedOrder`.
:data:`MERIDIAN_SECTOR` says how the ``copdea-fem response`` pipeline
(:mod:`copdea_fem.response.run`, :mod:`copdea_fem.response.files`) reads its modes,
velocities, far field and ParaView shapes (:mod:`.fields`).
"""

from __future__ import annotations

import logging
import time
import types

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp

from ..forced.harmonic import ForcedOrder, reduce_matrix, reduce_vector
from ..forced.problem import DrivenSector, OrderZero
from ..forced.radiation import MembraneObserver, SphereSampler
from ..linearise import to_scipy


logger = logging.getLogger(__name__)


def order_zero_problem(study, mesh, state, timings: dict) -> OrderZero:
    """The ALE air and the forced m = 0 pencil on the prestressed meridian."""
    from .air import meridian_motion
    from .operators import MeridianAir, OrderForms, coupled_order_operators

    start = time.perf_counter()
    logger.info("assembling the m = 0 membrane-air pencil and the voltage forcing ...")
    motion = meridian_motion(state, mesh, study["air"]["domain_radius"])
    air = MeridianAir(state, study, motion)
    forms = OrderForms(state, study)
    dry = forms.operators(0)
    coupled = coupled_order_operators(state, study, dry, air)
    forced = forced_order(state, coupled, study["eigen"]["backend"]).with_damping(
        forms.damping(dry))
    timings["assembly"] = time.perf_counter() - start
    return OrderZero(study, state, coupled, forced, timings, MERIDIAN_SECTOR)


def forced_order(state, coupled, backend="superlu") -> ForcedOrder:
    """The m = 0 order of the axisymmetric engine with its voltage forcing f and elastic
    stiffness K_el (:mod:`copdea_fem.forced.harmonic`)."""
    dry = coupled.membrane
    force, balance = voltage_forcing(state, dry)
    return ForcedOrder.from_parts(coupled, force, elastic_stiffness(state, dry), balance,
                                  backend)


def _energy_form(state, space, voltage, axis_m1=False):
    """Variation form of the order-0 membrane energy E(u0 + u; V) of the whole device."""
    from .operators import membrane_forms
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
    :mod:`copdea_fem.forced.harmonic`), and the relative residual |R(u0; V_b)| / |R(u0; 0)|
    on the free DOFs (the prestress equilibrium check)."""
    if dry.m != 0:
        raise ValueError(f"order m = {dry.m} is not allowed for the voltage forcing; allowed: 0 "
                         "(a uniform electrode excites only the axisymmetric order)")
    voltage_b = float(state.voltage)
    if voltage_b == 0:
        raise ValueError("load.voltage = 0 is not allowed for a forced response; allowed: > 0 V "
                         "(the linear forcing V_b dC/du vanishes; the response is quadratic in V~)")
    voltage = ngs.Parameter(voltage_b)
    form = _energy_form(state, dry.space, voltage, dry.axis_m1)
    zero = ngs.GridFunction(dry.space).vec
    residuals = []
    for value in (voltage_b, 0.0):
        voltage.Set(value)
        out = zero.CreateVector()
        form.Apply(zero, out)
        residuals.append(np.array(out.FV().NumPy()) * 1.0)
    at_bias, at_zero = residuals
    force = -2.0 * (at_bias - at_zero) / voltage_b
    free = dry.free_dofs
    balance = np.linalg.norm(at_bias[free]) / max(np.linalg.norm(at_zero[free]), 1e-300)
    return reduce_vector(force, dry.free_dofs, _order_lift(dry)), float(balance)


def elastic_stiffness(state, dry) -> sp.csr_matrix:
    """K_el [N/m]: Hessian of the order-0 energy at (u0, V = 0) on the unknowns
    (:mod:`copdea_fem.forced.harmonic`)."""
    form = _energy_form(state, dry.space, ngs.Parameter(0.0), dry.axis_m1)
    form.AssembleLinearization(ngs.GridFunction(dry.space).vec)      # E(u0 + u) at u = 0
    return reduce_matrix(to_scipy(form.mat), dry.free_dofs, _order_lift(dry))


def _classify(problem, result):
    """The modes of the forced m = 0 band, with their membrane-energy fractions."""
    from .modes import OrderSampler, classify_order
    from ..modes import membrane_energy_fractions

    coupled = problem.coupled
    dry = coupled.membrane
    membrane = result.vectors[coupled.membrane_index]
    sampler = OrderSampler(problem.state, dry.space, dry.axis_m1)
    modes = classify_order(dry, membrane, result.freq_hz, result.freq_im_hz,
                           result.residuals, sampler)
    for mode, fraction in zip(modes, membrane_energy_fractions(coupled, result)):
        mode.membrane_energy_fraction = fraction
    return modes


def _label(modes) -> None:
    from .modes import label_all, number_out_of_plane
    number_out_of_plane(modes)
    label_all(modes)


def _write_shapes(staging, state, coupled, shapes, pressures):
    from .fields import write_revolved_air_vtus, write_revolved_mode_vtus
    return (write_revolved_mode_vtus(staging, state, shapes),
            write_revolved_air_vtus(staging, [coupled], shapes, pressures))


MERIDIAN_SECTOR = DrivenSector(
    name="order m = 0", excited="order m = 0", summary="m = 0", classify=_classify,
    label=_label, observer=MembraneObserver, angles=1, sphere=SphereSampler,
    shape_sector=lambda operators: None, write_shapes=_write_shapes)
