"""The axisymmetric-harmonic engine (mesh.engine: axisymmetric) against closed forms and the
3-D engine on the same physics.

Closed forms: the Bessel cross-product roots of the flat annulus (rung 2), the
small-z disc stiffness 2 pi T / ln(r_o/r_i) (rung 3), the baffled piston's
radiation impedance through the meridian PML (rung 4).  The 3-D quadrant is an
independent discretisation of the same equations (other mesh, other space,
NGSolve's own PML), so agreement there tests the harmonic reduction itself
(the m^2/r^2 terms, the hoop stretch of the PML, the cos/sin families).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import bessel_frequency, on_its_engine
from scipy.special import j1, struve

from copdea_fem.api import Solution
from copdea_fem.fe import acoustics, engine_for
from copdea_fem.fe.axisymmetric.air import air_forms, screen_coupling
from copdea_fem.fe.axisymmetric.engine import prepare_meridian, solve_axisymmetric_prestress
from copdea_fem.fe.materials import Membrane
from copdea_fem.fe.pipeline import coupled_modes, dry_modes, run_solve
from copdea_fem.study import StudyError, engine_of, parse_study

ngsolve = pytest.importorskip("ngsolve")


def axisymmetric_study(**sections):
    raw = {"geometry": {"frame": "baffle"}, "mesh": {"engine": "axisymmetric"}}
    for section, values in sections.items():
        raw.setdefault(section, {}).update(values)
    return parse_study(raw, name="axisymmetric")


# ------------------------------------------------------------------ selection
@pytest.mark.parametrize("frame, engine", [("baffle", "axisymmetric"), ("none", "axisymmetric"),
                                           ("circle", "axisymmetric"), ("square", "3d")])
def test_auto_engine_follows_the_frame(frame, engine):
    assert engine_of(parse_study({"geometry": {"frame": frame}})) == engine


@pytest.mark.parametrize("raw, first_words", [
    ({"geometry": {"frame": "square"}, "mesh": {"engine": "axisymmetric"}},
     "mesh.engine = 'axisymmetric' is not allowed (the axisymmetric engine needs frame none"),
    ({"geometry": {"frame": "circle"}, "mesh": {"engine": "3d"}},
     "mesh.engine = '3d' is not allowed (the 3-D mesh has no circular frame)"),
    ({"geometry": {"frame": "circle", "frame_radius": "30 mm"}},
     "geometry.frame_radius = 0.03 is not allowed"),
])
def test_engine_and_frame_keys_are_checked(raw, first_words):
    with pytest.raises(StudyError) as error:
        parse_study(raw)
    assert str(error.value).startswith(first_words)


# ------------------------------------------------------------------ rung 2: Bessel roots
@pytest.mark.parametrize("inner_radius", ["17 mm", "12 mm"], ids=["G1", "G2"])
@pytest.mark.parametrize("voltage", ["0 kV", "2 kV"])
def test_flat_modes_match_bessel_roots(inner_radius, voltage):
    """Every out-of-plane mode < 1 kHz, each m >= 1 as its pair, within 4e-6.

    2 mm membrane mesh, order 3: measured worst 1.7e-6 (G2, 2 kV); 2.9e-5 on the
    default 3 mm mesh.
    """
    study = axisymmetric_study(geometry={"inner_radius": inner_radius},
                               load={"voltage": voltage}, mesh={"membrane_size": "2 mm"})
    _, modes, result = dry_modes(study, engine=engine_for(study))
    counts = {}
    for mode in modes:
        if mode.kind == "out-of-plane":
            assert mode.freq_hz == pytest.approx(bessel_frequency(study, mode.m, mode.n),
                                                 rel=4e-6), mode.label
            counts[(mode.m, mode.n)] = counts.get((mode.m, mode.n), 0) + 1
    for m in range(0, 25):
        for n in range(1, 5):
            try:
                exact = bessel_frequency(study, m, n)
            except IndexError:
                break
            if exact < study.eigen.f_max * (1 - 1e-3):
                assert counts.get((m, n)) == (1 if m == 0 else 2), (m, n)
    assert np.all(result.residuals < study.eigen.residual_tol)


def test_full_membrane_axis_conditions():
    """r_i = 0: single-valuedness on the axis (module doc of axisymmetric.membrane);
    J_m zeros within 4e-6 (measured 1.1e-5 on 3 mm, less on 2 mm), m = 0, 1, 2 present."""
    study = axisymmetric_study(geometry={"inner_radius": 0, "frame": "none"},
                               mesh={"membrane_size": "2 mm"}, eigen={"f_max": "700 Hz"})
    _, modes, _ = dry_modes(study, engine=engine_for(study))
    out_of_plane = [mode for mode in modes if mode.kind == "out-of-plane"]
    assert [mode.label for mode in out_of_plane[:5]] == ["(0,1)", "(1,1)a", "(1,1)b",
                                                         "(2,1)a", "(2,1)b"]
    for mode in out_of_plane:
        assert mode.freq_hz == pytest.approx(bessel_frequency(study, mode.m, mode.n), rel=4e-6)


def test_bessel_error_converges_at_rate_2p():
    """Order 2: the (0,2) and (3,1) errors fall as h^{2p} = h^4; fitted slope within 3.5..5."""
    sizes = np.array([6e-3, 4e-3, 3e-3, 2e-3])
    errors = {label: [] for label in ("(0,2)", "(3,1)a")}
    for size in sizes:
        study = axisymmetric_study(mesh={"membrane_size": float(size), "order": 2})
        _, modes, _ = dry_modes(study, engine=engine_for(study))
        by_label = {mode.label: mode for mode in modes}
        for label in errors:
            mode = by_label[label]
            errors[label].append(abs(mode.freq_hz / bessel_frequency(study, mode.m, mode.n) - 1))
    for label, values in errors.items():
        slope = np.polyfit(np.log(sizes), np.log(values), 1)[0]
        assert 3.5 < slope < 5.0, (label, slope, values)


@pytest.mark.parametrize("inner_radius, z", [("17 mm", "16 mm"), ("0 mm", "0 mm")],
                         ids=["disc-cone", "full-flat"])
def test_order_stiffness_interpolated_in_m_equals_its_assembly(inner_radius, z):
    """OrderForms assembles three orders per space and interpolates beyond them (degree 2 in
    m, class doc): the order-m stiffness and material tangent equal a fresh assembly of the
    same form at that order (NGSolve, the Parameter set to m) to round-off."""
    import ngsolve as ngs

    from copdea_fem.fe.axisymmetric.meridian import theta_integral
    from copdea_fem.fe.axisymmetric.operators import OrderForms, membrane_forms, order_space
    from copdea_fem.fe.linearise import to_scipy

    study = axisymmetric_study(geometry={"inner_radius": inner_radius, "frame": "none"},
                               load={"z": z, "voltage": "2 kV"},
                               mesh={"membrane_size": "3 mm"})
    mesh = prepare_meridian(study)
    state = solve_axisymmetric_prestress(study, mesh)
    forms = OrderForms(state, study)
    for m in range(0, 13):
        operators = forms.operators(m)
        tangent = forms.material_tangent(operators)
        if m < 5:
            continue                                   # the assembled orders
        space = order_space(state.mesh, study.mesh.order, m, state.has_disc)
        trial, test = space.TnT()
        free = operators.free_dofs
        for material_only, interpolated in ((False, operators.stiffness), (True, tangent)):
            energy, _ = membrane_forms(state, m, trial, test, False, theta=1.0,
                                       material_only=material_only)
            hessian = ngs.BilinearForm(space, symmetric=False)
            hessian += ngs.Variation(energy)
            hessian.AssembleLinearization(ngs.GridFunction(space).vec)
            direct = theta_integral(m) * to_scipy(hessian.mat)[free][:, free]
            if operators.disc_dof:
                interpolated = interpolated[:-1, :-1]      # m >= 1: no disc unknown anyway
            difference = abs(interpolated - direct).max()
            assert difference <= 1e-12 * abs(direct).max(), (m, material_only, difference)


# ------------------------------------------------------------------ rung 3: disc stiffness
def test_small_z_disc_stiffness_matches_closed_form():
    """F/z -> 2 pi T / ln(r_o/r_i) for small z (T the flat tension), within 1e-4 at z = 1 um."""
    study = axisymmetric_study(load={"z": "1 um"})
    mesh = prepare_meridian(study)
    state = solve_axisymmetric_prestress(study, mesh)
    tension = Membrane.from_study(study).equibiaxial_tension(0.0)
    g = study.geometry
    exact = 2 * math.pi * tension / math.log(g.outer_radius / g.inner_radius)
    assert state.disc_force / state.z == pytest.approx(exact, rel=1e-4)


# ------------------------------------------------------------------ rung 4: meridian PML
SOUND_SPEED = parse_study({}).air.sound_speed
DENSITY = parse_study({}).air.density


def _meridian_piston_impedance(frequency, domain_factor=3.5):
    """Force on the upper face of a rigid baffled piston (membrane + disc) / velocity [N s/m]."""
    study = axisymmetric_study(air={"enabled": True,
                                    "domain_radius": domain_factor * 0.0355},
                               mesh={"membrane_size": "6 mm"})
    mesh = prepare_meridian(study)
    space = acoustics.pressure_space(mesh, 2, acoustics.screen_faces("baffle"))
    trial, test = space.TnT()
    omega = 2 * math.pi * frequency
    stiffness, mass = air_forms(0, trial, test, DENSITY, SOUND_SPEED,
                                study.air.domain_radius, study.air.pml_thickness)
    system = ngsolve.BilinearForm(space)
    system += stiffness - omega**2 * mass
    system.Assemble()
    load = ngsolve.LinearForm(space)     # -omega^2 c(u, p') with u . n = i v0 / omega, v0 = 1
    load += -omega**2 * screen_coupling(0, test, 1j / omega, "membrane|disc")
    load.Assemble()
    solution = ngsolve.GridFunction(space)
    solution.vec.data = system.mat.Inverse(space.FreeDofs(), inverse="umfpack") * load.vec
    p = solution.components[0]
    return 2 * math.pi * ngsolve.Integrate(p * ngsolve.x, mesh, ngsolve.BND,
                                           definedon=mesh.Boundaries("membrane|disc"))


def _piston_closed_form(frequency, radius=0.0355):
    """Baffled piston Z = rho c S [1 - J1(2ka)/ka - i H1(2ka)/ka] (e^{-i omega t}) [N s/m]."""
    ka = 2 * math.pi * frequency / SOUND_SPEED * radius
    area = math.pi * radius**2
    return DENSITY * SOUND_SPEED * area * (1 - j1(2 * ka) / ka - 1j * struve(1, 2 * ka) / ka)


@pytest.mark.parametrize("frequency", [200.0, 500.0, 1000.0])
def test_meridian_pml_baffled_piston_impedance(frequency):
    """Reactance and resistance within 1 % (the issue's bound), 6 mm membrane mesh, pressure
    order 2.  Measured: reactance -0.22 / -0.19 / -0.20 %, resistance +0.74 / +0.07 / +0.14 %
    at 200 / 500 / 1000 Hz (at 200 Hz the PML sits at kR = 0.45)."""
    impedance = _meridian_piston_impedance(frequency)
    exact = _piston_closed_form(frequency)
    assert abs(impedance.imag - exact.imag) / abs(exact.imag) < 0.01
    assert abs(impedance.real - exact.real) / exact.real < 0.01
    assert impedance.imag < 0


# ------------------------------------------------------------------ coupled
@pytest.fixture(scope="module")
def coupled_z16():
    study = axisymmetric_study(air={"enabled": True}, load={"z": "16 mm", "voltage": "2 kV"},
                               eigen={"f_max": "700 Hz"})
    return study, coupled_modes(study, engine=engine_for(study))


def test_coupled_air_loading_lowers_every_mode(coupled_z16):
    _, solution = coupled_z16
    structural = [mode for mode in solution.modes if mode.kind == "out-of-plane"]
    assert [mode.label for mode in structural[:3]] == ["(0,1)", "(1,1)a", "(1,1)b"]
    for index, mode in enumerate(solution.modes):
        if mode.kind in ("out-of-plane", "in-plane"):
            assert mode.freq_hz <= solution.dry_partner_hz[index] * (1 + 1e-9), mode.label
            assert mode.damping_ratio > -1e-6, mode.label


def test_pairs_share_frequency_and_carry_their_parity(coupled_z16):
    _, solution = coupled_z16
    by_label = {mode.label: mode for mode in solution.modes}
    first, second = by_label["(1,1)a"], by_label["(1,1)b"]
    assert first.freq_hz == second.freq_hz
    assert (first.sector.name, second.sector.name) == ("odd-even", "even-odd")
    assert by_label["(2,1)b"].sector.name == "odd-odd"


def test_largest_mac_assignment_is_scipys():
    """The wet-dry assignment is an optimum of the assignment problem: the one
    :func:`scipy.optimize.linear_sum_assignment` gives where the optimum is unique (random
    tables, tables like a solve's: one MAC near 1 per mode), the same total MAC where ties
    allow several, a one-to-one pairing of the smaller side always."""
    from scipy.optimize import linear_sum_assignment

    from copdea_fem.fe.modes import largest_mac_assignment

    generator = np.random.default_rng(5)
    for trial in range(600):
        wet, dry = generator.integers(1, 6, 2)
        macs = generator.random((wet, dry))
        if trial % 3 == 1:          # one dry partner per wet mode, the rest near 0
            macs *= 0.01
            for row, column in enumerate(generator.permutation(max(wet, dry))[:wet]):
                if column < dry:
                    macs[row, column] = 0.99
        elif trial % 3 == 2:        # ties, zeros included: several optima
            macs = np.round(macs, 1)
        ours, scipys = largest_mac_assignment(macs), linear_sum_assignment(macs, maximize=True)
        assert len(set(ours[0])) == len(set(ours[1])) == min(wet, dry)
        assert list(ours[0]) == sorted(ours[0])
        assert macs[tuple(ours)].sum() == pytest.approx(macs[tuple(scipys)].sum(), abs=1e-12)
        if trial % 3 != 2:
            np.testing.assert_array_equal(ours[0], scipys[0])
            np.testing.assert_array_equal(ours[1], scipys[1])


def test_air_radius_barely_moves_coupled_modes():
    """3.5 -> 5 r_o: every out-of-plane mode < 700 Hz moves < 0.5 % (measured < 0.01 %)."""
    frequencies = []
    for factor in (3.5, 5.0):
        study = axisymmetric_study(air={"enabled": True, "domain_radius": factor * 0.0355},
                                   load={"z": "16 mm", "voltage": "2 kV"},
                                   eigen={"f_max": "700 Hz"})
        solution = coupled_modes(study, engine=engine_for(study))
        frequencies.append({mode.label: mode.freq_hz for mode in solution.modes
                            if mode.kind == "out-of-plane"})
    assert frequencies[0].keys() == frequencies[1].keys()
    for label, value in frequencies[0].items():
        assert frequencies[1][label] == pytest.approx(value, rel=5e-3), label


def test_circular_frame_lies_between_none_and_baffle():
    """(0,1)'s added mass grows with the reflecting plane: none < circle (40 mm) < baffle."""
    values = {}
    for frame in ("none", "circle", "baffle"):
        study = axisymmetric_study(geometry={"frame": frame}, air={"enabled": True},
                                   load={"z": "16 mm", "voltage": "2 kV"},
                                   eigen={"f_max": "450 Hz"}, mesh={"membrane_size": "4 mm"})
        solution = coupled_modes(study, engine=engine_for(study))
        values[frame] = next(mode.freq_hz for mode in solution.modes if mode.label == "(0,1)")
    assert values["baffle"] < values["circle"] < values["none"]


def test_disc_on_spring_gives_p1_below_its_dry_partner():
    study = axisymmetric_study(air={"enabled": True}, load={"z": "16 mm", "voltage": "2 kV"},
                               disc={"motion": "spring"}, eigen={"f_max": "450 Hz"},
                               mesh={"membrane_size": "4 mm"})
    solution = coupled_modes(study, engine=engine_for(study))
    pumping = [(k, mode) for k, mode in enumerate(solution.modes) if mode.kind == "pumping"]
    assert pumping and pumping[0][1].label == "P1"
    index, p1 = pumping[0]
    dry = solution.dry_partner_hz[index]
    assert p1.freq_hz < dry
    assert (dry / p1.freq_hz) ** 2 - 1 < 0.2          # a small added mass on a 3 g disc


def test_solve_writes_revolved_paraview_files(tmp_path):
    import meshio

    study = axisymmetric_study(air={"enabled": True}, load={"z": "16 mm", "voltage": "2 kV"},
                               eigen={"f_max": "450 Hz"}, mesh={"membrane_size": "4 mm"})
    result = run_solve(study, engine=engine_for(study))
    Solution(result).write(tmp_path / "out")
    out = tmp_path / "out"
    structural = [mode for mode in result.modes if mode.kind != "air"]
    assert len(list(out.glob("mode_*.vtu"))) == len(structural)
    assert len(list(out.glob("air_*.vtu"))) == len(structural)
    membrane = meshio.read(next(out.glob("mode_000_*.vtu")))
    assert {"displacement_real", "normal_displacement_real", "normal_velocity_abs"} <= set(
        membrane.point_data)
    radii = np.hypot(membrane.points[:, 0], membrane.points[:, 1])
    assert radii.max() <= study.geometry.outer_radius * (1 + 1e-6)
    air = meshio.read(next(out.glob("air_000_*.vtu")))
    assert "pressure_abs" in air.point_data and air.cells[0].type == "wedge"
    assert (out / "prestress.vtu").is_file() and (out / "modes.csv").is_file()


def test_prestressed_dry_modes_match_the_3d_engine_on_a_fast_mesh():
    """G1, z = 16 mm, 2 kV, dry, < 700 Hz: every mode, in-plane ones too (they test the
    hoop and shear terms of the harmonic gradient, which the flat Bessel modes do not),
    with the 3-D engine's label and kind, frequencies within 2e-5 of the 3-D plane mesh at
    4 mm, order 3 (measured 9e-6 out-of-plane, 3.7e-6 in-plane)."""
    over = dict(geometry={"frame": "baffle"}, load={"z": "16 mm", "voltage": "2 kV"},
                eigen={"f_max": "700 Hz"})
    mine = {mode.label: mode for mode in on_its_engine(dry_modes, axisymmetric_study(**over))[1]}
    reference = on_its_engine(dry_modes, parse_study({**over, "mesh": {
        "membrane_size": "4 mm", "order": 3, "engine": "3d"}}))[1]
    assert len(mine) == len(reference) and {mode.kind for mode in reference} >= {"in-plane"}
    for mode in reference:
        assert mine[mode.label].kind == mode.kind, mode.label
        assert mine[mode.label].freq_hz == pytest.approx(mode.freq_hz, rel=2e-5), mode.label


# ------------------------------------------------------------------ against the 3-D quadrant
def _compare(frame, z):
    over = dict(geometry={"frame": frame}, air={"enabled": True},
                load={"z": z, "voltage": "2 kV"})
    axisymmetric = on_its_engine(coupled_modes, axisymmetric_study(**over))
    three_d = on_its_engine(coupled_modes, parse_study({**over, "mesh": {"engine": "3d"}}))
    return axisymmetric, three_d


@pytest.mark.slow
@pytest.mark.parametrize("frame", ["baffle", "none"])
@pytest.mark.parametrize("z", ["0 mm", "16 mm"])
def test_coupled_modes_match_the_3d_quadrant(frame, z):
    """Every out-of-plane mode < 1 kHz: same labels and counts per m, frequency within 0.2 %,
    added-mass ratio within 0.02, damping ratio within 10 % where it exceeds 1e-3.

    Measured (default meshes of both engines, 2026-12-01): frequencies within 0.075 %,
    added-mass ratios within 0.0017, zeta of (0,1) within 1 % (baffle: 3.03e-2 / 3.02e-2
    at z = 16 mm); weakly radiating modes (zeta < 1e-3) differ up to 25 %, where the
    3-D air mesh is the less resolved (a meridian convergence run moves them < 2 %).
    """
    from copdea_fem.output.tables import mode_rows

    axisymmetric, three_d = _compare(frame, z)
    rows = {row["label"]: row for row in mode_rows(axisymmetric.modes,
                                                   axisymmetric.dry_partner_hz)}
    reference = [row for row in mode_rows(three_d.modes, three_d.dry_partner_hz)
                 if row["kind"] == "out-of-plane"]
    assert sorted(row["label"] for row in reference) == sorted(
        label for label, row in rows.items() if row["kind"] == "out-of-plane")
    for row in reference:
        mine = rows[row["label"]]
        assert mine["freq_hz"] == pytest.approx(row["freq_hz"], rel=2e-3), row["label"]
        assert abs(mine["added_mass_ratio"] - row["added_mass_ratio"]) < 0.02, row["label"]
        if row["damping_ratio"] > 1e-3:
            assert mine["damping_ratio"] == pytest.approx(row["damping_ratio"], rel=0.1)


@pytest.mark.slow
def test_prestressed_dry_modes_match_the_3d_engine():
    """G1, z = 16 mm, 2 kV, dry: every mode < 1 kHz (in-plane too) with the 3-D label, within
    3e-5 (measured 1.5e-5); the disc force within 2e-5 (4.902836 / 4.902886 N, 1.0e-5 on
    the octant-mirrored 3-D mesh; 0.8e-5 before it)."""
    over = dict(geometry={"frame": "baffle"}, load={"z": "16 mm", "voltage": "2 kV"})
    axisymmetric = on_its_engine(dry_modes, axisymmetric_study(**over))
    three_d = on_its_engine(dry_modes, parse_study({**over, "mesh": {"engine": "3d"}}))
    assert axisymmetric[0].disc_force == pytest.approx(three_d[0].disc_force, rel=2e-5)
    mine = {mode.label: mode for mode in axisymmetric[1]}
    assert len(mine) == len(three_d[1])
    for mode in three_d[1]:
        assert mine[mode.label].freq_hz == pytest.approx(mode.freq_hz, rel=3e-5), mode.label
        assert mine[mode.label].kind == mode.kind


def test_coupled_modes_converge_with_the_meridian_mesh():
    """G1 in a baffle at z = 16 mm: (0,1), (1,1), (0,2) and the (0,1) damping on the default
    meridian against one refined twice (membrane 1.5 mm, air / 2, pressure order 3).

    Measured: frequencies within 1e-4, zeta of (0,1) within 0.5 %; tested at 5e-4 / 2 %.
    """
    def solve(**mesh):
        study = axisymmetric_study(air={"enabled": True}, load={"z": "16 mm", "voltage": "2 kV"},
                                   eigen={"f_max": "950 Hz"}, mesh=mesh)
        return {mode.label: mode for mode in coupled_modes(study, engine=engine_for(study)).modes}

    default = solve()
    fine = solve(membrane_size="1.5 mm", air_size=0.25 * 0.0355, pressure_order=3)
    for label in ("(0,1)", "(1,1)a", "(0,2)"):
        assert default[label].freq_hz == pytest.approx(fine[label].freq_hz, rel=5e-4), label
    assert default["(0,1)"].damping_ratio == pytest.approx(fine["(0,1)"].damping_ratio, rel=0.02)


def test_fig11b_sweep_on_the_axisymmetric_engine(tmp_path):
    """The bundled baffled Fig. 11b sweep, coarse: every point solved, (0,1) and (0,2)
    tracked along z and rising with it as in Fig. 11b -- (0,2) throughout, (0,1) up to
    16 mm: in air its added mass grows with z too (0.46 flat, 0.80 at 16 mm), and from
    16 to 18 mm (0,1) falls by 0.2 % on this mesh ((0,2) leaves the band at 18 mm)."""
    from pathlib import Path

    from copdea_fem.cli import main
    from copdea_fem.sweeps import read_table

    path = Path(__file__).resolve().parents[2] / "studies" / "sweeps" / \
        "fig11b_g1_z_axisymmetric.yaml"
    code = main(["sweep", str(path), "--out", str(tmp_path / "s"), "--quiet",
                 "--set", "mesh.membrane_size=6 mm", "--set", "mesh.order=2",
                 "--set", "eigen.f_max=950 Hz"])
    assert code == 0
    rows = read_table(tmp_path / "s" / "sweep.csv")
    assert {row["status"] for row in rows} == {"ok"}
    by_track: dict = {}
    for row in rows:
        by_track.setdefault(row["track_label"], []).append(
            (float(row["load.z_m"]), float(row["freq_hz"])))
    for label, points, rising in (("(0,1)", 10, 9), ("(0,2)", 9, 9)):
        values = sorted(by_track[label])
        assert len(values) == points, label
        assert all(b[1] > a[1] for a, b in zip(values[:rising], values[1:rising])), label


def test_order_zero_in_plane_modes_are_drawn_with_their_motion(tmp_path):
    """The ParaView file of each order-0 in-plane mode (radial breathing and torsion, whose
    hoop factor is 1, not sin 0 theta) shows a displacement as large as the mode's own:
    the largest in-plane displacement on the revolved surface equals the largest of its
    meridian amplitudes, the mode being scaled to a largest displacement of 1."""
    import meshio

    from copdea_fem.vtu import safe_name

    study = axisymmetric_study(load={"z": "16 mm", "voltage": "2 kV"},
                               eigen={"f_max": "750 Hz"}, mesh={"membrane_size": "4 mm"})
    result = run_solve(study, engine=engine_for(study))
    Solution(result).write(tmp_path / "out")
    labels = [mode.label for mode in result.modes if mode.label.startswith("ip(0,")]
    assert len(labels) == 2, labels                      # ip(0,1)a and b below 750 Hz
    for label in labels:
        (path,) = (tmp_path / "out").glob(f"mode_*_{safe_name(label)}.vtu")
        data = meshio.read(path).point_data["displacement_real"]
        in_plane = np.hypot(data[:, 0], data[:, 1])
        assert in_plane.max() > 0.5 * np.abs(data).max() > 0, label
