"""The 3-D engine's forced response pinned to the axisymmetric engine's.

Both engines share the voltage forcing (:func:`copdea_fem.fe.forced.harmonic.forcing_from_energy`)
and the Kirchhoff-Helmholtz Green's function (:func:`copdea_fem.fe.forced.radiation.green_kernels`),
but each builds its own energy, mesh, observer and sphere quadrature: one baffled case (G1,
z = 16 mm, 2 kV, disc held, coarse mesh) through the whole ``response`` pipeline on both must
give the same velocity spectra and on-axis pressure.  A 3-D forcing off by a factor, or a
Green's function with the wrong time sign, fails here (tools/mutation_check.py plants both).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import on_its_engine

from copdea_fem.fe.forced.radiation import KIRCHHOFF_FRACTION, pressure_parts
from copdea_fem.forced_response.run import forced_response, prepare_order_zero
from copdea_fem.study import parse_study

#: Lines [Hz] off the resonances (the (0,1) of this case is near 383 Hz): there the engines'
#: coupled frequencies, which differ by <= 0.075 % on the default mesh, shift the response
#: by far more than their discretisations do elsewhere.
LINES_HZ = np.array([150.0, 300.0, 550.0, 800.0])
#: 1 %: on this coarse mesh (membrane 6 mm, order 3, pressure order 2) the engines differ
#: by <= 0.56 % (radial velocity at 550 Hz; axial <= 0.28 %, on-axis |p| <= 0.36 %, measured);
#: the default mesh's slow test: <= 0.36 %.  A halved forcing is off by 50 %.
ENGINE_TOLERANCE = 0.01
#: Extinction: the exterior representation at a point inside the Kirchhoff sphere, relative to
#: the FE pressure there, on the lines >= 300 Hz (measured 0.28-0.48 %; the piston's
#: closed-form test: < 1 %).  The outgoing G is what makes it vanish: G with e^{-ikd} leaves
#: 5.8-15 % there (at 150 Hz, k rho_s ~ 0.6, the two differ too little: 1.4 % against 4.3 %).
EXTINCTION_TOLERANCE = 0.02
EXTINCTION_FROM_HZ = 300.0


def _study(engine):
    return parse_study({"geometry": {"inner_radius": "17 mm", "frame": "baffle"},
                        "load": {"z": "16 mm", "voltage": "2 kV"}, "air": {"enabled": True},
                        "mesh": {"engine": engine, "membrane_size": "6 mm", "order": 3,
                                 "pressure_order": 2},
                        "response": {"method": "direct"}}, name=f"g1_z16_baffle_{engine}")


@pytest.fixture(scope="module")
def engines():
    """(3-D problem, 3-D result, axisymmetric result) at :data:`LINES_HZ`, 1 V each."""
    quadrant = on_its_engine(prepare_order_zero, _study("3d"))
    meridian = on_its_engine(prepare_order_zero, _study("axisymmetric"))
    assert (quadrant.engine, meridian.engine) == ("3d", "axisymmetric")
    volts = np.ones(LINES_HZ.size, complex)
    return (quadrant, forced_response(quadrant, LINES_HZ, volts),
            forced_response(meridian, LINES_HZ, volts))


@pytest.mark.parametrize("spectrum", ["average_axial", "average_radial", "point_axial",
                                      "point_radial"])
def test_quadrant_velocity_spectra_match_the_axisymmetric_engine(engines, spectrum):
    _, three_d, axisymmetric = engines
    mine, reference = getattr(three_d, spectrum), getattr(axisymmetric, spectrum)
    assert np.max(np.abs(mine - reference) / np.abs(reference)) < ENGINE_TOLERANCE


def test_quadrant_on_axis_sound_matches_the_axisymmetric_engine(engines):
    """|p| at 1 m on the axis within 1 % (0.09 dB of SPL), the Rayleigh far field of each
    engine's own sphere quadrature."""
    _, three_d, axisymmetric = engines
    assert [name for name, _ in three_d.microphones] == ["axis"]
    mine, reference = np.abs(three_d.pressure[:, 0]), np.abs(axisymmetric.pressure[:, 0])
    assert np.max(np.abs(mine - reference) / reference) < ENGINE_TOLERANCE
    assert np.max(np.abs(three_d.spl_db[:, 0] - axisymmetric.spl_db[:, 0])) < 0.1


def test_quadrant_exterior_representation_vanishes_inside_its_sphere(engines):
    """At (0, 0, rho_s / 2), inside the Kirchhoff sphere, the 3-D engine's half-space
    representation (its quadrature, the shared kernels) is the extinction's ~0, not the FE
    pressure there."""
    quadrant, three_d, _ = engines
    study = quadrant.study
    radius = KIRCHHOFF_FRACTION * study.air.domain_radius
    sampler = quadrant.sector.sphere(quadrant.coupled, radius, ("upper",))
    pressures = quadrant.forced.pressure(three_d.vectors)
    p, dp = sampler.sample(pressures)
    inside = np.array([0.0, 0.0, 0.5 * radius])
    point = sampler.coupled.pressure_space.mesh(*inside)
    for line in np.flatnonzero(LINES_HZ >= EXTINCTION_FROM_HZ):
        frequency = LINES_HZ[line]
        wavenumber = 2 * math.pi * frequency / study.air.sound_speed
        kp, kg = sampler.kernels(inside, wavenumber, baffle=True)
        local = 0j
        for _, factor in pressure_parts(sampler.gf, quadrant.coupled.pressure_free,
                                        pressures[:, line:line + 1]):
            local += factor * sampler.gf.components[0](point)
        represented = kp @ p[:, line] - kg @ dp[:, line]
        assert abs(represented) < EXTINCTION_TOLERANCE * abs(local), (frequency, represented,
                                                                      local)
