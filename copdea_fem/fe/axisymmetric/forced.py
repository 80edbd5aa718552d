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

import functools
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
    enclosure = MeridianSpec.from_study(study).cavity         # None: an open back
    motion = meridian_motion(state, mesh, study.air.domain_radius, cavity=enclosure)
    air = MeridianAir(state, study, motion)
    forms = OrderForms(state, study)
    dry = forms.operators(0)
    coupled = coupled_order_operators(state, study, dry, air)
    forced = forced_order(state, coupled, study.eigen.backend).with_damping(
        forms.damping(dry))
    cavity, dry_band = None, None
    # over an enclosure the air changes what the m = 0 modes are (a vent's Helmholtz mode,
    # the stiffened (0,1)): cavity orders and dry partners, as solve (_label); an open back
    # loads them only, its counted n is the partners' and costs no dry solve
    if enclosure is not None:
        from copdea_fem.fe.axisymmetric.modes import CavitySampler
        cavity = CavitySampler(air.pressure_space, enclosure)
        dry_band = functools.partial(_dry_modes, forms, study)
    timings["assembly"] = time.perf_counter() - start
    return OrderZero(study, state, coupled, forced, timings, MERIDIAN_SECTOR, cavity=cavity,
                     dry_band=dry_band)


def _dry_modes(forms, study, f_max: float):
    """The dry m = 0 modes from 0 Hz to ``f_max`` [Hz], classified and numbered as
    ``solve``'s dry partners (:func:`copdea_fem.fe.axisymmetric.modes.numbered_dry_modes`)."""
    from copdea_fem.fe.axisymmetric.modes import numbered_dry_modes
    from copdea_fem.fe.axisymmetric.operators import dry_order
    from copdea_fem.fe.bands import BandSolver
    operators, result, _ = dry_order(BandSolver.from_study(study), forms, 0, f_max)
    return numbered_dry_modes(operators, result)


def _classify(problem, result):
    """The modes of the forced m = 0 band with their membrane-energy fractions, and their
    pressure vectors (:func:`copdea_fem.fe.axisymmetric.modes.coupled_order_modes`)."""
    from copdea_fem.fe.axisymmetric.modes import coupled_order_modes
    return coupled_order_modes(problem.coupled, result,
                               problem.study.air.min_membrane_energy)


def _label(problem, modes, pressures, f_max: float) -> None:
    """Name the modes of the forced m = 0 band of ``f_max`` [Hz] as ``solve`` names its
    order m = 0 (:func:`copdea_fem.fe.axisymmetric.modes.name_coupled_order`): over an
    enclosure with the cavity orders and the dry partners below
    :data:`copdea_fem.fe.bands.DRY_PARTNER_FACTOR` f_max, else by rank."""
    from copdea_fem.fe.axisymmetric.modes import label_all, name_coupled_order
    from copdea_fem.fe.bands import DRY_PARTNER_FACTOR
    name_coupled_order(modes, pressures, problem.dry_partners(DRY_PARTNER_FACTOR * f_max),
                       problem.coupled, problem.cavity)
    label_all(modes)


def _write_shapes(staging, state, coupled, shapes, pressures):
    from copdea_fem.fe.axisymmetric.fields import write_revolved_air_vtus, write_revolved_mode_vtus
    return (write_revolved_mode_vtus(staging, state, shapes),
            write_revolved_air_vtus(staging, [coupled], shapes, pressures))


MERIDIAN_SECTOR = DrivenSector(
    name="order m = 0", excited="order m = 0", summary="m = 0", classify=_classify,
    label=_label, observer=MembraneObserver, angles=1, sphere=SphereSampler,
    shape_sector=lambda operators: None, write_shapes=_write_shapes)
