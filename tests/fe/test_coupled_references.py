"""Every coupled column of modes.csv against a reference the FE did not make (issue 16).

In a baffle (``geometry.frame: baffle``) the air has textbook closed forms
(:mod:`baffled`): the flat annulus's Bessel modes with the exact baffled-source
impedance (added mass, radiation resistance), and for z = 16 mm the ring model's modes
(``copdea_fem.reduced``, its own discretisation) as the flat source of equal volume
flux (:mod:`copdea_fem.reduced.airmass`).  The rows compared are those ``modes.csv``
gets (:func:`copdea_fem.output.tables.mode_rows`).  G1 at V_b = 2 kV on a 4 mm, order-2 mesh
with pressure order 2: the coarsest on which (0,2) carries its added mass (at 6 mm
order 2 it is 9 % low, at 9 mm / pressure order 1 half of it; the Galerkin air
under-estimates C^T K_a^-1 C).  Every tolerance is about twice the agreement measured
on this mesh, quoted next to it.

The disc on its spring (``disc.motion: spring``, G1 at z = 16 mm, the bundled study
``g1_z16_spring_coupled``): P1 against the ring model's P1 and the lumped disc mass,
quadrant against whole mesh.
"""

import math
from pathlib import Path

import baffled
import pytest
from helpers import COARSE_AIR, coupled_study, on_its_engine

from copdea_fem.fe.materials import Membrane
from copdea_fem.fe.pipeline import coupled_modes
from copdea_fem.output.tables import mode_rows
from copdea_fem.reduced.airmass import ring_sources
from copdea_fem.reduced.model import operating_point, ring_model_of
from copdea_fem.study import load_study

MESH = {"membrane_size": "4 mm", "order": 2, "pressure_order": 2}
RINGS = 96                         # ring-model error ~ n^-2: 1e-4 on (0,1) at n = 96


ENGINES = ["3d", "axisymmetric"]    # the baffle is axisymmetric: every reference holds for both
#: The meridian air at the default mesh.air_size (0.5 r_o): at the coarse suite's 35.5 mm its
#: elements (half of it, axisymmetric.meridian) leave (0,1)'s radiation damping 3.7 % short
#: and its added mass 1.5 % (the 3-D quadrant's air is graded from the 4 mm plane faces).
AXISYMMETRIC_AIR = {"air_size": "17.75 mm"}
#: dry modal masses where the axisymmetric engine's measured error exceeds the 3-D one's
DRY_TOLERANCE_AXISYMMETRIC = {"(1,1)a": 3e-3}


class Baffled:
    """One coupled solve in the baffle on one engine, its modes.csv rows and dry partners."""

    def __init__(self, z, f_max, engine):
        mesh = {**MESH, "engine": engine, **(AXISYMMETRIC_AIR if engine == "axisymmetric" else {})}
        self.study = coupled_study(geometry={"frame": "baffle"}, mesh=mesh,
                                   load={"z": z, "voltage": "2 kV"}, eigen={"f_max": f_max})
        self.solution = on_its_engine(coupled_modes, self.study)
        self.rows = {row["label"]: row for row in mode_rows(self.solution.modes,
                                                            self.solution.dry_partner_hz)}
        self.dry = {mode.label: mode for mode in self.solution.dry_modes}
        air = self.study.air
        self.air = (air.density, air.sound_speed)
        self.material = Membrane.from_study(self.study)


def _bessel_reference(case, m, n):
    """The flat annulus's mode (m, n) in the baffle (baffled.py)."""
    geometry = case.study.geometry
    tension = case.material.equibiaxial_tension(case.study.load.voltage)
    speed = math.sqrt(tension / case.material.areal_density)
    k, shape = baffled.bessel_shape(m, n, geometry.inner_radius, geometry.outer_radius)
    reference = baffled.baffled_mode(shape, k * speed / (2 * math.pi),
                                     case.material.areal_density, *case.air)
    return reference


def _ring_reference(case, label):
    """A ring-model mode (RINGS rings) as the flat source of equal flux, in the baffle."""
    study = case.study
    ring_model = ring_model_of(study, ring_count=RINGS)
    linearisation, basis, _ = operating_point(ring_model, study.load.z,
                                              study.load.voltage)
    mode, equilibrium = basis[label], linearisation.equilibrium
    shape = baffled.piecewise_linear_shape(ring_sources(equilibrium.radii, equilibrium.heights,
                                                        mode.radial, mode.axial))
    # mass-normalised shape (q^T M_s q = 1): modal mass 1 kg; the ratios need no peak
    return baffled.baffled_mode(shape, mode.frequency_hz, case.material.areal_density,
                                *case.air, modal_mass=1.0)


_CASES: dict = {}     # (case, engine) -> Baffled: one solve per case and engine


def _case(name: str, engine: str) -> Baffled:
    if (name, engine) not in _CASES:
        if name == "flat_baffle":
            case = Baffled("0 mm", "850 Hz", engine)
            case.reference = {label: _bessel_reference(case, m, n) for label, m, n in
                              (("(0,1)", 0, 1), ("(0,2)", 0, 2), ("(1,1)a", 1, 1),
                               ("(2,1)a", 2, 1))}
        else:
            case = Baffled("16 mm", "960 Hz", engine)
            case.reference = {label: _ring_reference(case, label) for label in ("(0,1)", "(0,2)")}
        _CASES[name, engine] = case
    return _CASES[name, engine]


@pytest.fixture(scope="module", params=ENGINES)
def engine(request):
    return request.param


@pytest.fixture
def flat_baffle(engine):
    return _case("flat_baffle", engine)


@pytest.fixture
def cone_baffle(engine):
    return _case("cone_baffle", engine)


@pytest.fixture
def baffle(request, engine):
    return _case(request.param, engine)


# ------------------------------------------------------------------ added mass, frequencies

@pytest.mark.parametrize("baffle, label, estimate, tolerance", [
    # measured (4 mm, order 2, pressure order 2): -0.51 %, -1.22 %, +0.81 %, +2.3 %; the
    # estimate is incompressible (the exact baffle lowers (0,1) by 1.3 % at ka = 0.22)
    # and at z = 16 mm replaces the cone by a flat source ("errs low", airmass.py)
    ("flat_baffle", "(0,1)", "incompressible_added_mass_ratio", 1e-2),
    ("flat_baffle", "(0,2)", "incompressible_added_mass_ratio", 2.5e-2),
    ("cone_baffle", "(0,1)", "incompressible_added_mass_ratio", 1.6e-2),
    ("cone_baffle", "(0,2)", "incompressible_added_mass_ratio", 5e-2),
    # the non-radiating pairs against the exact (compressible) baffle: -0.07 %, -0.22 %
    ("flat_baffle", "(1,1)a", "added_mass_ratio", 2e-3),
    ("flat_baffle", "(2,1)a", "added_mass_ratio", 5e-3),
], indirect=["baffle"])
def test_added_mass_ratio_matches_the_baffled_estimate(baffle, label, estimate, tolerance):
    row, reference = baffle.rows[label], baffle.reference[label]
    assert row["added_mass_ratio"] == pytest.approx(getattr(reference, estimate),
                                                    rel=tolerance), label
    # the column is (f_dry / f)^2 - 1 of the two frequency columns
    assert row["added_mass_ratio"] == pytest.approx(
        (row["dry_freq_hz"] / row["freq_hz"]) ** 2 - 1, rel=1e-12)


@pytest.mark.parametrize("baffle, label, dry_tolerance, tolerance", [
    # dry: FE vs Bessel +1.2e-4, +1.6e-3, +1.3e-4 (4 mm order 2); vs the ring model (n = 96)
    # +8e-5, +1.4e-3.  Coupled vs f_dry / sqrt(1 + mu(k)) with the exact baffle's mu (the
    # dry shape kept): -1.1e-3, +2.1e-3, +2e-4; at z = 16 mm (flat source) -5.3e-3, +2.5e-4
    ("flat_baffle", "(0,1)", 3e-4, 3e-3), ("flat_baffle", "(0,2)", 4e-3, 5e-3),
    ("flat_baffle", "(1,1)a", 3e-4, 1e-3),
    ("cone_baffle", "(0,1)", 3e-4, 1.1e-2), ("cone_baffle", "(0,2)", 3e-3, 3e-3),
], indirect=["baffle"])
def test_dry_and_coupled_frequencies_match_the_references(baffle, label, dry_tolerance,
                                                          tolerance):
    row, reference = baffle.rows[label], baffle.reference[label]
    assert row["dry_freq_hz"] == pytest.approx(reference.dry_freq_hz, rel=dry_tolerance)
    assert row["freq_hz"] == pytest.approx(reference.freq_hz, rel=tolerance)


# ------------------------------------------------------------------ radiation damping

@pytest.mark.parametrize("baffle, tolerance", [
    # measured +0.35 % (z = 0) and -0.11 % (z = 16 mm, flat source of the ring mode); the
    # exact baffle's resistance is 0.9 % below the low-ka monopole at ka = 0.22
    ("flat_baffle", 1e-2), ("cone_baffle", 1e-2),
], indirect=["baffle"])
def test_radiation_damping_of_01_matches_the_baffled_monopole(baffle, tolerance):
    """zeta = rho_a k V^2 / (2 pi (M + M_a)): the (0,1) mode radiates as a baffled
    monopole of volume V (both faces); V, M, M_a from the reference shape alone."""
    row, reference = baffle.rows["(0,1)"], baffle.reference["(0,1)"]
    assert row["damping_ratio"] == pytest.approx(reference.low_ka_damping_ratio, rel=tolerance)
    # e^{-i omega t}: a radiating mode decays, Im f < 0, and zeta = -Im f / |f|
    assert row["freq_im_hz"] < 0
    assert -row["freq_im_hz"] / math.hypot(row["freq_hz"], row["freq_im_hz"]) == pytest.approx(
        reference.low_ka_damping_ratio, rel=tolerance)


def test_radiation_damping_range_quoted_in_the_readme(flat_baffle, cone_baffle):
    """README / schema: baffled flat G1 (0,1) ~2e-2, ~3e-2 at z = 16 mm; (0,2) ~1e-4..4e-4."""
    assert 0.015 < flat_baffle.rows["(0,1)"]["damping_ratio"] < 0.025
    assert 0.025 < cone_baffle.rows["(0,1)"]["damping_ratio"] < 0.035
    for case in (flat_baffle, cone_baffle):
        assert 5e-5 < case.rows["(0,2)"]["damping_ratio"] < 1e-3


# ------------------------------------------------------------------ modal mass

@pytest.mark.parametrize("label, dry_tolerance, tolerance", [
    # dry partner (unit peak normal displacement, sampled on the 40 x 64 polar grid) vs
    # Bessel: -0.20 %, -2.7 %, +0.03 %, +0.15 % (4 mm order 2; the (0,2) peak is an
    # order-2 field's); coupled: the air reshapes the mode, +1.43 %, -3.1 %, +0.89 %, +0.72 %.
    # Axisymmetric engine (peaks on 9 points per element): (1,1)a dry +0.13 %, hence 3e-3
    # there (DRY_TOLERANCE_AXISYMMETRIC) and 1e-3 on the 3-D quadrant
    ("(0,1)", 5e-3, 3e-2), ("(0,2)", 6e-2, 7e-2), ("(1,1)a", 1e-3, 2e-2),
    ("(2,1)a", 3e-3, 1.5e-2),
])
def test_modal_mass_matches_the_bessel_annulus_integral(flat_baffle, label, dry_tolerance,
                                                        tolerance):
    """M = c_m 2 pi rho_s int W^2 r dr / max W^2 with W the J_m, Y_m cross product."""
    reference = flat_baffle.reference[label].modal_mass
    if flat_baffle.study.mesh.engine == "axisymmetric":
        dry_tolerance = DRY_TOLERANCE_AXISYMMETRIC.get(label, dry_tolerance)
    assert flat_baffle.dry[label].modal_mass == pytest.approx(reference, rel=dry_tolerance)
    assert flat_baffle.rows[label]["modal_mass"] == pytest.approx(reference, rel=tolerance)


# ------------------------------------------------------------------ energy fraction

@pytest.mark.parametrize("label", ["(1,1)a", "(2,1)a"])
def test_membrane_energy_fraction_is_one_over_one_plus_the_added_mass(flat_baffle, label):
    """Incompressible air: KE_air / KE_membrane = M_a / M (the added mass is the air's
    kinetic energy), so the fraction is 1 / (1 + M_a / M) with M_a from the Bessel shape.
    For m >= 1 the air's energy stays near the membrane (dipole and up: the part beyond the
    3.5 r_o sphere, where the FE stops counting, is ~(r_o / R)^3 small).  Measured -0.25 %
    and -0.07 % (4 mm, order 2); 0.5 % allowed.  (For the monopole (0,1) 16 % of M_a lies
    beyond R: rho_a V^2 / (pi R), not a closed form the FE's energy sees.)"""
    reference = 1 / (1 + flat_baffle.reference[label].incompressible_added_mass_ratio)
    assert flat_baffle.rows[label]["membrane_energy_fraction"] == pytest.approx(reference,
                                                                                rel=5e-3)


def test_held_disc_takes_no_energy(flat_baffle):
    assert all(row["disc_fraction"] == 0 for row in flat_baffle.rows.values())


# ------------------------------------------------------------------ disc on its spring

SPRING_STUDY = Path(__file__).resolve().parents[2] / "studies" / "g1_z16_spring_coupled.yaml"


def spring_study(symmetry="quarter"):
    """The bundled study on the coarse coupled mesh of test_coupled, band to 150 Hz."""
    changes = {f"mesh.{key}": value for key, value in COARSE_AIR.items()}
    return load_study(SPRING_STUDY).replace({**changes, "mesh.symmetry": symmetry,
                                              "eigen.f_max": "150 Hz"})


@pytest.fixture(scope="module")
def spring_pair():
    """G1 at z = 16 mm, 2 kV, the disc on its spring, square frame (9 mm mesh, pressure
    order 1): quadrant and whole mesh; and the ring model's P1 (disc M_d, no M_s/3)."""
    solutions = {symmetry: on_its_engine(coupled_modes, spring_study(symmetry))
                 for symmetry in ("quarter", "none")}
    study = spring_study()
    ring_model = ring_model_of(study, ring_count=RINGS)
    _, basis, _ = operating_point(ring_model, study.load.z, study.load.voltage)
    return study, solutions, ring_model, basis["P1"]


def _pumping(solution):
    rows = mode_rows(solution.modes, solution.dry_partner_hz)
    pumping = [row for row in rows if row["kind"] == "pumping"]
    dry = [mode for mode in solution.dry_modes if mode.kind == "pumping"]
    return pumping, dry


def test_coupled_pumping_mode_sits_just_below_the_dry_one(spring_pair):
    """P1 present once; the air adds a little mass: below the incompressible estimate for the
    membrane and disc in a baffle (the square frame's open aperture only lowers it, Kelvin's
    minimum energy), 0.030 from the ring model's P1; measured 0.021 (quadrant and whole)."""
    study, solutions, ring_model, ring_p1 = spring_pair
    equilibrium = operating_point(ring_model, study.load.z,
                                  study.load.voltage)[0].equilibrium
    disc = ring_p1.axial[-1]
    shape = baffled.piecewise_linear_shape(ring_sources(
        equilibrium.radii, equilibrium.heights, ring_p1.radial / disc, ring_p1.axial / disc,
        disc_axial=1.0))
    membrane_share = 1 / disc**2 - ring_model.disc_mass          # per unit disc displacement
    lumped = study.disc.mass + study.spring.mass / 3
    air = study.air
    baffled_ratio = 2 * baffled.face_impedance(shape, air.density)[0] / (lumped +
                                                                             membrane_share)
    assert 0.02 < baffled_ratio < 0.04
    for symmetry, solution in solutions.items():
        (p1,), (dry,) = _pumping(solution)
        assert p1["label"] == "P1" and dry.label == "P1"
        assert p1["freq_hz"] < p1["dry_freq_hz"] == pytest.approx(dry.freq_hz)
        # small: between half the baffled estimate and the estimate itself (+10 % for the
        # 9 mm mesh; the FE baffle gives 0.029-0.032 on 9 / 6 mm)
        assert 0.5 * baffled_ratio < p1["added_mass_ratio"] < 1.1 * baffled_ratio, symmetry


def test_pumping_mode_against_the_ring_model_and_the_lumped_disc(spring_pair):
    """Per unit disc displacement the modal mass is M_d + M_s/3 (lumped) plus the membrane's
    share, which the ring model gives (its P1, mass-normalised: 1 / u_disc^2 - M_d);
    the disc's share of it is the lumped mass.  Stiffness from the ring model's P1:
    (2 pi f)^2 / u_disc^2.  Measured (9 mm): modal mass +1.3e-4, dry P1 +1.6e-4."""
    study, solutions, ring_model, ring_p1 = spring_pair
    disc = ring_p1.axial[-1]
    lumped = study.disc.mass + study.spring.mass / 3
    modal_mass = lumped + 1 / disc**2 - ring_model.disc_mass
    stiffness = (2 * math.pi * ring_p1.frequency_hz) ** 2 / disc**2
    dry_p1 = math.sqrt(stiffness / modal_mass) / (2 * math.pi)
    for symmetry, solution in solutions.items():
        (p1,), (dry,) = _pumping(solution)
        assert dry.freq_hz == pytest.approx(dry_p1, rel=5e-4), symmetry
        assert dry.modal_mass == pytest.approx(modal_mass, rel=5e-4), symmetry
        assert p1["modal_mass"] == pytest.approx(modal_mass, rel=5e-4), symmetry
        # disc_fraction = (M_d + M_s/3) |w_d|^2 / KE: the lumped share of the modal mass
        assert p1["disc_fraction"] * p1["modal_mass"] == pytest.approx(lumped, rel=1e-6)
        assert p1["disc_fraction"] == pytest.approx(lumped / modal_mass, rel=5e-4), symmetry


def test_pumping_mode_same_on_quadrant_and_whole_mesh(spring_pair):
    """Two meshes of one device: P1 within 1e-3 (measured 1.4e-4; the issue asks 1e-2);
    the disc's spring and mass enter the quadrant's pencil divided by 4."""
    _, solutions, _, _ = spring_pair
    (quarter,), _ = _pumping(solutions["quarter"])
    (whole,), _ = _pumping(solutions["none"])
    for column, tolerance in (("freq_hz", 1e-3), ("dry_freq_hz", 1e-3), ("modal_mass", 1e-3),
                              ("added_mass_ratio", 5e-2), ("membrane_energy_fraction", 1e-3),
                              ("disc_fraction", 1e-3)):
        assert quarter[column] == pytest.approx(whole[column], rel=tolerance), column
