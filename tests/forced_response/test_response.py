"""Forced response of the coupled FE (issue 15), on the axisymmetric engine (m = 0).

Closed forms first (baffled piston far field and radiated power; the static limit of the
voltage forcing against the prestress itself), then the two solution paths against each
other, the energy balance, peaks at the eigenfrequencies with an isolated mode's height,
and the FE against the reduced model of Sect. 3.2 with the paper's b/m.
"""

from __future__ import annotations

import math

import ngsolve
import numpy as np
import pytest
from helpers import on_its_engine
from scipy.special import j1

from copdea_fem.cli import main
from copdea_fem.fe import acoustics, engine_for
from copdea_fem.fe.axisymmetric.air import air_forms, screen_coupling
from copdea_fem.fe.axisymmetric.engine import prepare_meridian, solve_axisymmetric_prestress
from copdea_fem.fe.forced.radiation import (
    KIRCHHOFF_FRACTION,
    SphereSampler,
    kirchhoff_kernels,
    radiated_power,
    spl_db,
)
from copdea_fem.forced_response.run import (
    AVERAGE_COLUMNS,
    POINT_COLUMNS,
    forced_response,
    modal_solution,
    parse_microphones,
    prepare_order_zero,
    reduced_spectrum,
)
from copdea_fem.study import StudyError, parse_study

G1_Z16 = {"geometry": {"inner_radius": "17 mm", "frame": "baffle"},
          "load": {"z": "16 mm", "voltage": "2 kV"}, "air": {"enabled": True}}


def study_of(**sections):
    raw = {key: dict(value) for key, value in G1_Z16.items()}
    for section, values in sections.items():
        raw.setdefault(section, {}).update(values)
    return parse_study(raw, name="g1_z16_response")


@pytest.fixture(scope="module")
def held():
    """G1, z = 16 mm, 2 kV, disc held, baffle, default mesh (2332 unknowns)."""
    return on_its_engine(prepare_order_zero, study_of())


@pytest.fixture(scope="module")
def spring():
    """The same with the disc on the spring (P1), as the paper's forced response."""
    return on_its_engine(prepare_order_zero, study_of(disc={"motion": "spring"}))


def _undamped(problem):
    """The modal basis with b/m = 0 (radiation through the PML only)."""
    basis, modes = modal_solution(problem, 1000.0)
    basis.damping_per_mass[:] = 0.0
    return basis, modes


# ------------------------------------------------------------------ forcing
def test_static_response_is_the_prestress_derivative_in_voltage():
    """omega -> 0: A^-1 F = du0/dV_b; the prestress at V_b +- 1 V by central differences
    (exact for the quadratic co-energy up to the Newton tolerance) within 1e-6 (measured
    2e-8 on 60 radii; the Newton tolerance 1e-10 of each prestress over dV = 1 V bounds it)."""
    study = study_of()
    problem = prepare_order_zero(study, engine=engine_for(study))
    static = problem.forced.direct([1e-3])[:, 0]
    u_static = problem.forced.membrane(static).real
    profiles = []
    for voltage in (1999.0, 2001.0):
        shifted = study.replace({"load.voltage": voltage})
        mesh = prepare_meridian(shifted)
        state = solve_axisymmetric_prestress(shifted, mesh)
        profiles.append(state.profile(np.linspace(0.0175, 0.035, 60)))
    derivative = (profiles[1] - profiles[0]) / 2.0            # [m/V]: (u_r, u_z)
    observer_radii = np.linspace(0.0175, 0.035, 60)
    dry = problem.coupled.membrane
    full = dry.to_full(u_static[:, None])[:, 0]
    gf = ngsolve.GridFunction(dry.space)
    gf.vec.FV().NumPy()[:] = full
    from copdea_fem.fe.axisymmetric.meridian import LineSampler
    line = LineSampler(problem.state.mesh)
    a, _, c = dry.amplitudes(gf)
    fe = np.column_stack([line.at(a, observer_radii), line.at(c, observer_radii)])
    error = np.linalg.norm(fe - derivative) / np.linalg.norm(derivative)
    assert problem.forced.equilibrium_residual < 1e-6
    assert error < 1e-6, error


def test_static_disc_displacement_on_the_spring_matches_the_force_derivatives():
    """Disc on the spring, omega -> 0: the disc moves w = -(dF/dV) / (dF/dz + k_d) per volt,
    F(z, V) the prestress's disc force (central differences, dV = 1 V, dz = 1 um): checks
    the disc's share lift . f of the forcing.  Within 1e-6 (measured 6e-10)."""
    study = study_of(disc={"motion": "spring"})
    problem = prepare_order_zero(study, engine=engine_for(study))
    disc = problem.forced.membrane(problem.forced.direct([1e-3])[:, 0])[-1].real

    def force(key, value):
        shifted = study.replace({key: value})
        return solve_axisymmetric_prestress(shifted, prepare_meridian(shifted)).disc_force

    d_voltage = (force("load.voltage", 2001.0) - force("load.voltage", 1999.0)) / 2.0
    d_z = (force("load.z", 0.016 + 1e-6) - force("load.z", 0.016 - 1e-6)) / 2e-6
    expected = -d_voltage / (d_z + study.spring.stiffness)
    assert disc == pytest.approx(expected, rel=1e-6)


# ------------------------------------------------------------------ piston: closed forms
def _piston(frequency):
    """Rigid baffled piston (membrane + disc, radius r_o = 35.5 mm, v0 = 1 m/s) in the
    meridian air of the default study: (pressure GridFunction, a coupled-like record)."""
    study = study_of(load={"z": 0.0, "voltage": 0.0},
                     mesh={"membrane_size": "6 mm"})
    mesh = prepare_meridian(study)
    space = acoustics.pressure_space(mesh, 2, acoustics.screen_faces("baffle"))
    trial, test = space.TnT()
    omega = 2 * math.pi * frequency
    air = study.air
    stiffness, mass = air_forms(0, trial, test, air.density, air.sound_speed,
                                air.domain_radius, air.pml_thickness)
    system = ngsolve.BilinearForm(space)
    system += stiffness - omega ** 2 * mass
    system.Assemble()
    load = ngsolve.LinearForm(space)     # u . n = i v0 / omega (v = -i omega u = v0)
    load += -omega ** 2 * screen_coupling(0, test, 1j / omega, "membrane|disc")
    load.Assemble()
    solution = ngsolve.GridFunction(space)
    solution.vec.data = system.mat.Inverse(space.FreeDofs(), inverse="umfpack") * load.vec

    class Record:
        pressure_space = space
        pressure_free = np.arange(space.ndof)
    return study, solution, Record


@pytest.mark.parametrize("frequency", [200.0, 1000.0])
def test_baffled_piston_far_field_and_power_match_the_closed_form(frequency):
    """Far field at 1 m (on axis, 30 and 60 deg) within 0.02 dB of the exact baffled piston
    (issue: 1 dB; measured <= 0.0053 dB at 200 Hz, 0.003 dB at 1 kHz), radiated power
    through the Kirchhoff sphere within 2 % of Re Z / 2 per face (issue: 2 %; measured
    0.70 % at 200 Hz, 0.13 % at 1 kHz, the PML's error as in test_axisymmetric's impedance),
    and the exterior representation vanishing inside the sphere (extinction, < 1 %)."""
    study, solution, record = _piston(frequency)
    air = study.air
    radius_sphere = KIRCHHOFF_FRACTION * air.domain_radius
    upper = SphereSampler(record, radius_sphere, ("upper",))
    p, dp = upper.sample(solution.vec.FV().NumPy().copy()[:, None])
    a, rho, c = 0.0355, air.density, air.sound_speed
    omega = 2 * math.pi * frequency
    k = omega / c
    for angle in (0.0, 30.0, 60.0):
        theta = math.radians(angle)
        mic = np.array([math.sin(theta), 0.0, math.cos(theta)])
        kp, kg = kirchhoff_kernels(upper, mic, k, baffle=True)
        fe = kp @ p[:, 0] - kg @ dp[:, 0]
        if angle == 0.0:        # exact on the axis
            exact = rho * c * (np.exp(1j * k) - np.exp(1j * k * math.hypot(1.0, a)))
        else:                   # Fraunhofer: -i omega rho a^2 v0 e^{ikr}/(2r) 2 J1(x)/x
            x = k * a * math.sin(theta)
            exact = -1j * omega * rho * a ** 2 / 2 * np.exp(1j * k) * 2 * j1(x) / x
        assert abs(spl_db(fe) - spl_db(exact)) < 0.02, (angle, spl_db(fe), spl_db(exact))
    lower = SphereSampler(record, radius_sphere, ("lower",))
    p_lower, dp_lower = lower.sample(solution.vec.FV().NumPy().copy()[:, None])
    power = (radiated_power(p, dp, upper, omega, rho)
             + radiated_power(p_lower, dp_lower, lower, omega, rho))
    ka = k * a
    resistance = rho * c * math.pi * a ** 2 * (1 - j1(2 * ka) / ka)
    # the lower face radiates the same into z < 0 (the velocity jump drives both halves)
    assert power[0] == pytest.approx(2 * 0.5 * resistance, rel=0.02)
    inside = np.array([0.0, 0.0, 0.5 * radius_sphere])
    kp, kg = kirchhoff_kernels(upper, inside, k, baffle=True)
    local = solution.components[0](study_mesh_point(solution, inside))
    assert abs(kp @ p[:, 0] - kg @ dp[:, 0]) < 0.01 * abs(local)


def study_mesh_point(solution, position):
    mesh = solution.space.mesh
    return mesh(float(math.hypot(position[0], position[1])), float(position[2]))


# ------------------------------------------------------------------ two paths, energy
def test_modal_superposition_matches_the_direct_solve(held):
    """Same damping model (radiation through the PML only): every membrane unknown within 1 %
    at 50-990 Hz, resonance included (measured 3.4e-3 at 990 Hz, 1e-3 at 800 Hz, 1.4e-8 ..
    1.1e-4 at 50-500 Hz: the omitted modes' O(omega^4/|lambda|^2) with modal_band = 2)."""
    basis, _ = _undamped(held)
    frequencies = np.array([50.0, 200.0, 383.0, 500.0, 800.0, 990.0])
    direct = held.forced.direct(frequencies)
    modal = basis.response(frequencies)
    u = held.forced.membrane
    errors = [np.linalg.norm(u(direct[:, k] - modal[:, k])) / np.linalg.norm(u(direct[:, k]))
              for k in range(frequencies.size)]
    assert max(errors) < 0.01, errors
    assert basis.left_residuals.max() < 1e-8        # y = (lambda u, beta p^ / alpha)


def test_modal_path_keeps_the_loss_factor_close_to_direct(held):
    """With eta = 0.02 the modal path projects the loss diagonally (off-diagonal terms
    neglected): within 0.5 % (measured 0.20 / 0.086 / 0.040 % at 200 / 383 / 700 Hz)."""
    basis, _ = _undamped(held)
    frequencies = np.array([200.0, 383.0, 700.0])
    direct = held.forced.direct(frequencies, loss_factor=0.02)
    modal = basis.response(frequencies, loss_factor=0.02)
    u = held.forced.membrane
    for k in range(frequencies.size):
        error = np.linalg.norm(u(direct[:, k] - modal[:, k])) / np.linalg.norm(u(direct[:, k]))
        assert error < 0.005, (frequencies[k], error)


@pytest.mark.parametrize("loss_factor", [0.0, 0.05])
def test_input_power_is_radiated_plus_dissipated(held, loss_factor):
    """P_in = omega/2 Im(f^H u) against the flux through the Kirchhoff sphere plus
    omega/2 eta u^H K_el u, within 2 % (issue; measured <= 3.1e-4 at 100 / 383 / 800 Hz)."""
    forced, coupled = held.forced, held.coupled
    sphere = SphereSampler(coupled, KIRCHHOFF_FRACTION * held.study.air.domain_radius)
    frequencies = np.array([100.0, 383.0, 800.0])
    solutions = forced.direct(frequencies, loss_factor)
    p, dp = sphere.sample(forced.pressure(solutions))
    n_u = len(coupled.membrane_index)
    k_el = forced.elastic[:n_u][:, :n_u]
    for k, f in enumerate(frequencies):
        omega = 2 * math.pi * f
        u = forced.membrane(solutions[:, k])
        supplied = omega / 2 * np.imag(np.vdot(forced.forcing[:n_u], u))
        dissipated = omega / 2 * loss_factor * np.real(np.vdot(u, k_el @ u))
        radiated = radiated_power(p[:, k], dp[:, k], sphere, omega,
                                  held.study.air.density)
        assert supplied > 0 and radiated > 0
        assert (radiated + dissipated) == pytest.approx(supplied, rel=0.02), (f, radiated,
                                                                               dissipated)


# ------------------------------------------------------------------ peaks
def test_peaks_sit_at_the_coupled_eigenfrequencies(spring):
    """Every structural mode of the band with a clear peak: a local maximum of the average
    spectrum within one line (1.25 Hz) of Re f; with complex lambda the peak of
    1/|lambda - omega^2| lies at sqrt(Re lambda), Re f (1 - O(zeta^2)): < 0.3 Hz here."""
    result = forced_response(spring)
    total = result.average_axial + result.average_radial
    spacing = result.frequency_hz[1] - result.frequency_hz[0]
    checked = 0
    for mode in result.modes:
        if mode.kind == "air" or mode.freq_hz > 990 or mode.label.startswith("ip(0,1)a"):
            continue            # ip(0,1)a is the torsion: a uniform voltage does not drive it
        near = np.abs(result.frequency_hz - mode.freq_hz) <= 8 * spacing
        peak = result.frequency_hz[near][np.argmax(total[near])]
        assert abs(peak - mode.freq_hz) <= spacing, (mode.label, peak, mode.freq_hz)
        checked += 1
    assert checked >= 4      # P1, (0,1), ip(0,1)b, (0,2)


def test_isolated_mode_peak_height_matches_its_modal_closed_form(spring):
    """P1 (56 Hz, nearest neighbour 383 Hz) with eta = 0.02, direct solve at Re f: the disc
    amplitude within 2 % of the single-mode term |y^T F / (n (lambda - w^2) - i eta lambda k)|
    |w_d| (issue: 2 %; measured 4e-6: the other modes' share is ~ (56/383)^2 of the force,
    in phase quadrature with the resonant term at Re f, so it enters the modulus squared)."""
    basis, modes = _undamped(spring)
    index = [m.label for m in modes].index("P1")
    f = modes[index].freq_hz
    omega = 2 * math.pi * f
    eta = 0.02
    direct = spring.forced.direct([f], loss_factor=eta)[:, 0]
    lam = basis.eigenvalues[index]
    closed = basis.participation[index] / (basis.norms[index] * (lam - omega ** 2)
                                           - 1j * eta * lam * basis.elastic_modal[index])
    disc = spring.coupled.membrane_index[-1]
    single = abs(closed * basis.vectors[disc, index])
    assert abs(direct[disc]) == pytest.approx(single, rel=0.02)


# ------------------------------------------------------------------ FE vs reduced model
def test_fe_against_the_reduced_model_with_the_papers_damping(spring):
    """G1, z = 16 mm, 2 kV, b/m = 45, 245, 57 1/s.  Peak frequencies: (0,1), (0,2) take
    their added masses from the FE frequencies, so they agree within a line; P1 within the
    8 % the paper reports between model and measurement (measured 2 %: Annex I's spring
    mass vs the FE's lumped M_s/3).  Heights within a factor 2.5 (measured FE/RM: P1 0.85,
    (0,1) 0.47, (0,2) 0.78): the FE adds the PML's radiation damping (zeta 2.9 % for (0,1))
    to b/m, which the paper calibrated on measured peaks that already hold it -- for (0,1)
    the damping about doubles, so its peak halves; P1 and (0,2) radiate little."""
    study = spring.study
    result = forced_response(spring)
    setup, reduced = reduced_spectrum(study, result)
    assert setup is not None
    fe_total = 0.5 * (result.average_axial + result.average_radial)
    rm_total = 0.5 * (reduced.average_axial + reduced.average_radial)
    spacing = result.frequency_hz[1] - result.frequency_hz[0]
    by_label = {m.label: m for m in result.modes}
    for label, frequency in zip(setup.reduced.labels, setup.reduced.frequency_hz):
        window = np.abs(result.frequency_hz - frequency) <= 0.1 * frequency
        fe_peak = result.frequency_hz[window][np.argmax(fe_total[window])]
        rm_peak = result.frequency_hz[window][np.argmax(rm_total[window])]
        tolerance = 0.08 * frequency if label == "P1" else spacing
        assert abs(fe_peak - rm_peak) <= tolerance, (label, fe_peak, rm_peak)
        assert abs(by_label[label].freq_hz - fe_peak) <= spacing
        ratio = fe_total[window].max() / rm_total[window].max()
        assert 1 / 2.5 < ratio < 2.5, (label, ratio)


# ------------------------------------------------------------------ inputs, CLI
def test_microphones_are_parsed_with_units_and_checked():
    study = study_of(response={"microphones": "side = 50 cm, 0 m, 0.5 m; back = 0, 0, -2 m"})
    names = [name for name, _ in parse_microphones(study)]
    assert names == ["axis", "side", "back"]
    assert parse_microphones(study)[1][1] == pytest.approx([0.5, 0.0, 0.5])
    with pytest.raises(StudyError, match="response.microphones"):
        parse_microphones(study_of(response={"microphones": "side = 1 m, 2 m"}))
    with pytest.raises(StudyError, match="repeated"):
        parse_microphones(study_of(response={"microphones": "axis = 1 m, 0 m, 1 m"}))


def test_response_refuses_zero_bias(tmp_path):
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    assert main(["response", str(root / "studies/g1_z16_v2_response.yaml"), "--set",
                 "load.voltage=0 V", "--out", str(tmp_path / "r"), "--quiet"]) == 2
    assert not (tmp_path / "r").exists()


@pytest.mark.slow
def test_quadrant_engine_matches_the_axisymmetric_response():
    """G1, z = 16 mm, 2 kV, baffle, disc held, direct path at 100 / 383 / 700 Hz: the 3-D
    quadrant's even-even sector against the meridian's m = 0 -- average axial and radial
    velocity and the pressure at 1 m on the axis within 1 % (measured <= 0.34 %, 0.34 %,
    0.36 %; the engines' coupled frequencies differ by <= 0.075 %, README)."""
    from copdea_fem.fe.forced.radiation import MembraneObserver
    from copdea_fem.fe.quadrant.forced import QuadrantObserver, QuadrantSphere, prepare_quadrant
    from copdea_fem.reduced.chirp_response import scan_fractions
    quadrant = prepare_quadrant(study_of(mesh={"engine": "3d"}))
    meridian = on_its_engine(prepare_order_zero, study_of())
    frequencies = [100.0, 383.0, 700.0]
    results = []
    for problem, observer, sphere in ((quadrant, QuadrantObserver, QuadrantSphere),
                                      (meridian, MembraneObserver, SphereSampler)):
        x = problem.forced.direct(frequencies)
        axial, radial = observer(problem.state, problem.coupled.membrane,
                                 scan_fractions(5)).observe(problem.forced.membrane(x))
        sampler = sphere(problem.coupled, KIRCHHOFF_FRACTION * problem.study.air.domain_radius,
                         ("upper",))
        p, dp = sampler.sample(problem.forced.pressure(x))
        far = []
        for k, f in enumerate(frequencies):
            kp, kg = sampler.kernels([0.0, 0.0, 1.0], 2 * math.pi * f / 343.0, True)
            far.append(kp @ p[:, k] - kg @ dp[:, k])
        results.append((np.abs(axial).mean(axis=0), np.abs(radial).mean(axis=0),
                        np.array(far)))
    for three_d, axisymmetric in zip(*results):
        assert np.max(np.abs(three_d - axisymmetric) / np.abs(axisymmetric)) < 0.01


def test_cli_response_writes_the_contract_files(tmp_path):
    """Coarse, direct path on a short chirp: the files, their columns and grid."""
    import csv
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    out = tmp_path / "r"
    code = main(["response", str(root / "studies/g1_z16_v2_response.yaml"), "--out", str(out),
                 "--quiet", "--set", "mesh.membrane_size=6 mm", "--set", "excitation.f_end=100 Hz",
                 "--set", "excitation.duration=0.2 s", "--set", "response.method=direct",
                 "--set", "membrane.loss_factor=0.05", "--set",
                 "response.microphones=side = 0.5 m, 0 m, 0.5 m"])
    assert code == 0
    for name in ("response_average.csv", "response_points.csv", "spl.csv", "response.json",
                 "study.resolved.yaml", "response_average.png", "spl.png", "ods.pvd",
                 "air_ods.pvd"):
        assert (out / name).is_file(), name
    rows = list(csv.reader((out / "response_average.csv").open()))
    assert tuple(rows[0]) == AVERAGE_COLUMNS
    assert [float(r[0]) for r in rows[1:]] == pytest.approx(5.0 * np.arange(1, 21))
    assert tuple(next(csv.reader((out / "response_points.csv").open()))) == POINT_COLUMNS
    assert next(csv.reader((out / "spl.csv").open())) == ["freq_hz", "spl_axis", "spl_side"]
