"""Rung 6: the ring model converges to the FE axisymmetric modes and static force."""

import numpy as np
import pytest

from copdea_fem.prestress import solve_prestress
from copdea_fem.reduced import RingModel, dry_frequencies
from copdea_fem.solve import dry_modes, prepare_mesh


def test_ring_model_converges_to_fe_modes_and_force(make_study):
    study = make_study(load={"z": "16 mm", "voltage": "2 kV"}, eigen={"f_max": "1100 Hz"},
                       mesh={"membrane_size": "4 mm", "order": 3})
    _, modes, _ = dry_modes(study)
    fe = {mode.label: mode.freq_hz for mode in modes}
    errors = []
    for rings in (6, 12, 24, 48):
        ring = dry_frequencies(study, labels=("(0,1)", "(0,2)"), ring_count=rings)
        errors.append([abs(ring[label] / fe[label] - 1) for label in ("(0,1)", "(0,2)")])
    errors = np.array(errors)
    # linear interpolation of velocities and stretches: error ~ n^-2 (4x per doubling)
    assert np.all(np.diff(errors, axis=0) < 0), errors
    assert np.all(errors[-1] < 2e-3), errors
    force_fe = solve_prestress(study, prepare_mesh(study, with_air=False)).disc_force
    ring_model = RingModel.from_study(study, ring_count=48)
    force_ring = ring_model.force_displacement(np.array([16e-3]), 2000.0)[0]
    assert force_ring == pytest.approx(force_fe, rel=2e-3)
