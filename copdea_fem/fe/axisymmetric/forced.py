"""The forced response on the axisymmetric engine: the order m = 0 that a uniform electrode
drives, on the meridian (the 3-D counterpart: :mod:`copdea_fem.fe.quadrant.forced`).

:func:`order_zero_problem` builds the forced m = 0 pencil on a prestressed meridian (the
engine, :meth:`copdea_fem.fe.axisymmetric.engine.AxisymmetricEngine.forced_problem`, makes
the mesh and the prestress), with the voltage forcing and the elastic stiffness of
:mod:`.forcing`.
:data:`MERIDIAN_SECTOR` says how the ``copdea-fem response`` pipeline
(:mod:`copdea_fem.forced_response.run`, :mod:`copdea_fem.forced_response.files`) reads its modes,
velocities, far field and ParaView shapes (:mod:`.fields`).
"""

from __future__ import annotations

import logging
import time

from copdea_fem.fe.forced.problem import DrivenSector, OrderZero
from copdea_fem.fe.forced.radiation import MembraneObserver, SphereSampler

logger = logging.getLogger(__name__)


def order_zero_problem(study, mesh, state, timings: dict) -> OrderZero:
    """The ALE air and the forced m = 0 pencil on the prestressed meridian."""
    from copdea_fem.fe.axisymmetric.air import meridian_motion
    from copdea_fem.fe.axisymmetric.forcing import forced_order
    from copdea_fem.fe.axisymmetric.meridian import MeridianSpec
    from copdea_fem.fe.axisymmetric.operators import (
        MeridianAir,
        OrderForms,
        coupled_order_operators,
    )

    start = time.perf_counter()
    logger.info("assembling the m = 0 membrane-air pencil and the voltage forcing ...")
    motion = meridian_motion(state, mesh, study.air.domain_radius,
                             cavity=MeridianSpec.from_study(study).cavity)
    air = MeridianAir(state, study, motion)
    forms = OrderForms(state, study)
    dry = forms.operators(0)
    coupled = coupled_order_operators(state, study, dry, air)
    forced = forced_order(state, coupled, study.eigen.backend).with_damping(
        forms.damping(dry))
    timings["assembly"] = time.perf_counter() - start
    return OrderZero(study, state, coupled, forced, timings, MERIDIAN_SECTOR)


def _classify(problem, result):
    """The modes of the forced m = 0 band, with their membrane-energy fractions."""
    from copdea_fem.fe.axisymmetric.modes import OrderSampler, classify_order
    from copdea_fem.fe.modes import membrane_energy_fractions

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
    from copdea_fem.fe.axisymmetric.modes import label_all, number_out_of_plane
    number_out_of_plane(modes)
    label_all(modes)


def _write_shapes(staging, state, coupled, shapes, pressures):
    from copdea_fem.fe.axisymmetric.fields import write_revolved_air_vtus, write_revolved_mode_vtus
    return (write_revolved_mode_vtus(staging, state, shapes),
            write_revolved_air_vtus(staging, [coupled], shapes, pressures))


MERIDIAN_SECTOR = DrivenSector(
    name="order m = 0", excited="order m = 0", summary="m = 0", classify=_classify,
    label=_label, observer=MembraneObserver, angles=1, sphere=SphereSampler,
    shape_sector=lambda operators: None, write_shapes=_write_shapes)
