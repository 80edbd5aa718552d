"""Prestress: closed-form stiffness (rung 3), equilibrium checks, failure messages."""

import math

import ngsolve as ngs
import numpy as np
import pytest

from copdea_fem.fe import engine_for
from copdea_fem.fe.materials import Membrane
from copdea_fem.fe.pipeline import prepare_mesh
from copdea_fem.fe.prestress import PrestressError, force_displacement, solve_prestress
from copdea_fem.study import parse_study


@pytest.mark.parametrize("inner_radius, voltage", [("17 mm", 0.0), ("12 mm", 2000.0)])
def test_small_disc_displacement_stiffness_is_2_pi_T_over_log(inner_radius, voltage):
    z = 2e-5  # m; F - k z = O(z^3): relative nonlinearity ~ (z / width)^2 ~ 1e-6
    study = parse_study({"geometry": {"inner_radius": inner_radius},
                         "load": {"z": z, "voltage": voltage}})
    state = solve_prestress(study, prepare_mesh(study, with_air=False, engine=engine_for(study)))
    tension = Membrane.from_study(study).equibiaxial_tension(voltage)
    r_o, r_i = study.geometry.outer_radius, study.geometry.inner_radius
    stiffness = 2 * math.pi * tension / math.log(r_o / r_i)
    # the default mesh does far better than the 1 % the issue asked for (README: 1e-4)
    assert state.disc_force / z == pytest.approx(stiffness, rel=1e-4)


def test_flat_state_stays_flat_and_uniform(make_study):
    study = make_study(load={"voltage": "2 kV"})
    state = solve_prestress(study, prepare_mesh(study, with_air=False, engine=engine_for(study)))
    assert np.abs(state.displacement.vec.FV().NumPy()).max() < 1e-12
    assert state.disc_force == pytest.approx(0.0, abs=1e-9)
    fields = state.fields()
    point = state.mesh(0.025, 0.0, 0.0, ngs.BND)
    material = Membrane.from_study(study)
    sigma = material.principal_stresses(1.2, 1.2, 2000.0)[0]
    assert fields["stress_2"](point) == pytest.approx(sigma, rel=1e-10)
    assert fields["thickness"](point) == pytest.approx(100e-6 / 1.44, rel=1e-12)
    assert fields["e_field"](point) == pytest.approx(2000.0 / (100e-6 / 1.44), rel=1e-12)


def test_force_rises_with_z_and_falls_with_voltage(make_study):
    """Fig. 4b: stiffening curves, lower at 3 kV than at 0 kV."""
    study = make_study()
    mesh = prepare_mesh(study, with_air=False, engine=engine_for(study))
    z_values = np.array([4e-3, 8e-3, 12e-3, 16e-3])
    forces = force_displacement(study, mesh, z_values, [0.0, 3000.0])
    assert np.all(np.diff(forces, axis=1) > 0)
    assert np.all(forces[1] < forces[0])
    # the same state reached along another load path gives the same force
    direct = solve_prestress(study.replace({"load.z": 16e-3, "load.voltage": 3000.0}), mesh)
    assert direct.disc_force == pytest.approx(forces[1, -1], rel=1e-8)


def test_loss_of_tension_is_reported_with_the_load(make_study):
    # sigma(1.2) = 370 kPa = eps (V/h)^2 at V ~ 8 kV: 9 kV wrinkles the flat film
    study = make_study(load={"voltage": "9 kV"})
    with pytest.raises(PrestressError) as caught:
        solve_prestress(study, prepare_mesh(study, with_air=False, engine=engine_for(study)))
    assert caught.value.kind == "loss_of_tension"
    message = str(caught.value)
    assert "loss of tension" in message and "V_b" in message and "wrinkles" in message
    assert 7000 < caught.value.voltage <= 9000


def test_stretches_at_z16_are_physical(make_study):
    study = make_study(load={"z": "16 mm", "voltage": "2 kV"})
    state = solve_prestress(study, prepare_mesh(study, with_air=False, engine=engine_for(study)))
    fields = state.fields()
    point = state.mesh(0.026, 0.0, 0.0, ngs.BND)
    # meridian stretch > pre-stretch on the cone; hoop stretch close to it
    assert fields["stretch_1"](point) > 1.2
    assert 1.0 < fields["stretch_2"](point) <= 1.2 + 1e-9
    assert state.disc_force > 0
