"""Incompressible-air added mass (eq. A1 of copdea_fem.reduced.airmass) against closed forms."""

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.special

from copdea_fem.reduced import build_reduced
from copdea_fem.reduced.airmass import face_added_mass, hankel_transform, ring_sources
from copdea_fem.study import parse_study

RHO = 1.204


def test_rigid_piston_gives_eight_thirds_rho_a_cubed():
    """Baffled piston, one face: 8/3 rho a^3 (Kinsler et al.); the k-tail truncation errs
    by ~ 3/(8 (k_max a)^2) = 6e-4 with k_max = 25/a (module notes)."""
    for radius in (0.01, 0.0355):
        mass = face_added_mass([(0.0, radius, 1.0, 1.0)], RHO)
        assert mass == pytest.approx(8 / 3 * RHO * radius ** 3, rel=1e-3)


def test_hankel_transform_of_a_linear_segment_matches_quadrature():
    k = np.array([1.0, 50.0, 400.0, 3000.0])
    start, end, w0, w1 = 0.012, 0.03, 0.4, -1.3
    exact = hankel_transform(k, [(start, end, w0, w1)])
    for kk, value in zip(k, exact):
        integrand = lambda r: (w0 + (w1 - w0) * (r - start) / (end - start)) * \
            scipy.special.j0(kk * r) * r  # noqa: E731
        quad, _ = scipy.integrate.quad(integrand, start, end, limit=400, epsabs=1e-14)
        assert value == pytest.approx(quad, rel=1e-9, abs=1e-14)


def test_annulus_piston_is_less_than_the_full_piston():
    """Added mass grows with the source: annulus < disc of the outer radius."""
    full = face_added_mass([(0.0, 0.0355, 1, 1)], RHO)
    ring = face_added_mass([(0.017, 0.0355, 1, 1)], RHO)
    assert 0 < ring < full


def test_flat_membrane_source_is_the_axial_displacement():
    """At z = 0 the profile is flat, h' = 0: the source is u_z itself (no u_r term)."""
    setup = build_reduced(parse_study({"disc": {"motion": "held"}}))
    eq = setup.linearisation.equilibrium
    mode = setup.basis["(0,1)"]
    for start, end, w_start, w_end in ring_sources(eq.radii, eq.heights, mode.radial,
                                                   mode.axial):
        inner = int(np.argmin(np.abs(eq.radii - start)))
        outer = int(np.argmin(np.abs(eq.radii - end)))
        assert w_start == pytest.approx(mode.axial[inner])
        assert w_end == pytest.approx(mode.axial[outer])
    assert np.all(eq.heights == 0)
    assert math.isclose(sum(e - s for s, e, *_ in ring_sources(
        eq.radii, eq.heights, mode.radial, mode.axial)), 0.0355 - 0.017)


@pytest.mark.parametrize("z, label, percent", [
    (0.0, "(0,1)", 46), (0.018, "(0,1)", 88), (0.0, "(0,2)", 10), (0.018, "(0,2)", 19)])
def test_readme_added_mass_range_of_the_ring_modes(z, label, percent):
    """README (diagnose engine): with effects.air_added_mass = incompressible, (0,1) gets
    46-88 % of its modal mass for z = 0-18 mm and (0,2) 10-19 % (G1, 2 kV, the disc on its
    spring, the default 6 rings), to the two digits quoted."""
    study = parse_study({"load": {"z": z, "voltage": "2 kV"}, "disc": {"motion": "spring"},
                         "effects": {"air_added_mass": "incompressible"}})
    reduced = build_reduced(study).reduced
    index = reduced.labels.index(label)
    assert reduced.added_mass_source[index] == "incompressible-air estimate"
    ratio = reduced.added_mass[index] / reduced.modal_mass[index]
    assert round(100 * ratio) == percent, ratio
