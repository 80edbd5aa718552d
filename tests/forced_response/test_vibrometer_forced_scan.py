"""The FE forced response at scan points (copdea_fem.forced_response.scan), checked against
what it did not make.

- **Both engines.**  An imperfect electrode (orders 1-3) drives the same device on the
  axisymmetric engine (the order-m energy's forcing, one 1-D problem per order) and on the
  3-D engine (the weighted co-energy on the whole mesh, or folded into the quadrant's
  sectors): two discretisations sharing no forcing code.  Their FRFs at the scan points
  must agree within the mesh error, and the gap must close as the mesh is refined.
- **The direct path.**  The modal sum with its static correction (no material damping) is
  the direct solve of the forced pencil (``ForcedOrder.direct``, one factorisation per line)
  sampled at the same points.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SCAN_BASE = ROOT / "studies" / "measured_scan_example" / "base_study.yaml"
QUICK = ROOT / "studies" / "g1_z16_v2_quick.yaml"
OPERATING_POINT = {"load.z": "16 mm", "load.voltage": "2 kV", "eigen.f_max": "900 Hz"}
# off resonance: where the engines' few-0.1 % frequency differences do not dominate
LINES = np.array([150.0, 300.0])


def _imperfection():
    from copdea_fem.fe.forced.electrode import ElectrodeImperfection
    return ElectrodeImperfection((1, 2, 3), (0.2, 0.3, 0.1), (0.3, 0.2, 0.5))


def _response(study, imperfection, damping_per_mass=30.0, lines=LINES):
    """(velocity at the scan points, the solve) of ``study`` on a 3 x 8 + 2 point grid."""
    from copdea_fem.diagnosis.synth_scan import ScanOptions, psv_reference_grid
    from copdea_fem.fe import engine_for, run_solve
    from copdea_fem.forced_response.scan import scan_response

    solution = run_solve(study, engine=engine_for(study))
    reference, _ = psv_reference_grid(solution.state.outer_radius,
                                      solution.state.inner_radius,
                                      ScanOptions(rings=3, per_ring=8, disc_points=2))
    positions = solution.engine.prestressed_positions(solution.state, reference,
                                                      study.load.z)
    response = scan_response(solution, study, positions, lines, imperfection,
                             damping_per_mass=lambda mode: damping_per_mass)
    return response, positions


@functools.cache
def _parts(path: Path, engine: str, overrides: tuple):
    """The uniform electrode's response and the imperfection's share, on one engine."""
    from copdea_fem.fe.forced.electrode import ElectrodeImperfection
    from copdea_fem.study import load_study

    study = load_study(path, {**OPERATING_POINT, **dict(overrides), "mesh.engine": engine})
    uniform = _response(study, ElectrodeImperfection())[0].velocity
    total = _response(study, _imperfection())[0].velocity
    return uniform, total - uniform


def _relative(first, second) -> np.ndarray:
    """|first - second| / |first| per line over all points and components."""
    return np.array([np.linalg.norm(first[..., k] - second[..., k])
                     / np.linalg.norm(first[..., k]) for k in range(first.shape[-1])])


def _engine_gap(path, overrides):
    axisymmetric = _parts(path, "axisymmetric", overrides)
    three_d = _parts(path, "3d", overrides)
    return [_relative(a, b) for a, b in zip(axisymmetric, three_d)]


DRY = (("air.enabled", False), ("geometry.frame", "none"))


def test_an_imperfect_electrode_drives_the_same_response_on_both_engines():
    uniform, imperfect = _engine_gap(SCAN_BASE, DRY + (("mesh.membrane_size", "6 mm"),))
    # measured: 0.5-0.6 % (m = 0) and 0.7 % (m >= 1) at 6 mm, 2.3 % at 8 mm, 0.23 % at 4 mm
    # (test below): the mesh error, bounded here at twice the 6 mm figure
    assert np.all(uniform < 0.012), uniform
    assert np.all(imperfect < 0.015), imperfect


def test_the_imperfection_drives_the_orders_it_holds_and_no_other():
    from copdea_fem.fe.forced.electrode import ElectrodeImperfection
    from copdea_fem.study import load_study

    study = load_study(SCAN_BASE, {**OPERATING_POINT, **dict(DRY),
                                   "mesh.engine": "axisymmetric"})
    response, positions = _response(study, ElectrodeImperfection((2,), (0.3,), (0.4,)))
    uniform, _ = _response(study, ElectrodeImperfection())
    share = response.velocity - uniform.velocity            # the order 2 alone
    angle = np.arctan2(positions[:, 1], positions[:, 0])
    # u_z of an order-2 field on a ring: a cos 2(theta - theta_2) pattern, nothing of m = 0
    on_ring = np.isclose(np.hypot(positions[:, 0], positions[:, 1]),
                         np.hypot(*positions[0, :2]), rtol=1e-9)
    axial = share[on_ring, 2, 0]
    pattern = np.cos(2 * (angle[on_ring] - 0.4))
    amplitude = (pattern @ axial) / (pattern @ pattern)
    assert np.linalg.norm(axial - amplitude * pattern) < 1e-6 * np.linalg.norm(axial)
    assert abs(amplitude) > 0


@pytest.mark.slow
def test_the_engines_converge_to_one_imperfect_response():
    gaps = {size: _engine_gap(SCAN_BASE, DRY + (("mesh.membrane_size", f"{size} mm"),))[1]
            for size in (8, 6, 4)}
    # order-2 elements: the gap should fall at least as h^2 (measured: about h^3)
    for coarse, fine in ((8, 6), (6, 4)):
        slope = np.log(gaps[coarse] / gaps[fine]) / math.log(coarse / fine)
        assert np.all(slope > 2.0), (coarse, fine, gaps)


@pytest.mark.slow
def test_the_quadrants_sectors_fold_the_imperfection_as_the_orders_do():
    # coupled with the air, no frame: the 3-D quadrant's four sectors, each forced by its
    # folded weight, against the axisymmetric orders (measured: 0.5-0.9 % at 150-300 Hz)
    uniform, imperfect = _engine_gap(QUICK, (("geometry.frame", "none"),))
    assert np.all(uniform < 0.02), uniform
    assert np.all(imperfect < 0.02), imperfect


def test_the_modal_scan_response_is_the_direct_forced_response():
    from copdea_fem.study import load_study

    study = load_study(QUICK, {"geometry.frame": "circle", "eigen.f_max": "900 Hz"})
    # measured: 3e-5 .. 6e-4 (the static correction's O(omega^4 / lambda^2) of the modes
    # above the band)
    assert np.all(_modal_against_direct(study, np.array([150.0, 300.0, 400.0, 450.0]))
                  < 2e-3)


def test_over_a_sealed_enclosure_the_modal_scan_response_is_the_direct_one():
    # A of a sealed cavity has no inverse (the static pair lambda = 0): the static
    # correction on the other pairs must still give the direct solve's FRFs (before: the
    # singular factorisation's ~1e11 m/s/V)
    from copdea_fem.study import load_study

    study = load_study(ROOT / "studies" / "g1_enclosure_cylinder.yaml",
                       {"eigen.f_max": "1800 Hz"})
    relative = _modal_against_direct(study, np.array([150.0, 300.0, 450.0, 600.0]))
    # measured: 4e-5 .. 9e-4 (with f_max = 900 Hz: 3e-4 .. 3e-2, the modes above the band)
    assert np.all(relative < 2e-3), relative


def _modal_against_direct(study, lines):
    """|modal - direct| / |direct| of the uniform electrode's FRFs at the scan points."""
    from copdea_fem.fe import engine_for
    from copdea_fem.fe.forced.electrode import ElectrodeImperfection
    from copdea_fem.forced_response.run import prepare_order_zero

    response, positions = _response(study, ElectrodeImperfection(), damping_per_mass=0.0,
                                    lines=lines)
    engine = engine_for(study)
    problem = prepare_order_zero(study, engine=engine)
    solutions = problem.forced.direct(lines)
    membrane = problem.forced.membrane(solutions)
    operators = problem.coupled.membrane
    full = operators.to_full(membrane)
    sampler = engine.point_sampler(problem.state, positions)
    displacement = np.stack([sampler.field_displacement(
        full[:, k], membrane[-1, k] if operators.disc_dof else 0.0, operators=operators)
        for k in range(lines.size)], axis=-1)
    direct = np.conj(-1j * 2 * np.pi * lines * displacement)       # e^{+i omega t}
    return _relative(direct, response.velocity)


def test_the_sectors_weights_unfold_to_the_electrodes_weight():
    # eq. (2) of copdea_fem.fe.forced.electrode inverted: w(q x) = sum_s s(q) W_s(x)
    from copdea_fem.fe.symmetry import QUADRANTS, SECTORS

    imperfection = _imperfection()
    rng = np.random.default_rng(3)
    x, y = rng.uniform(0.001, 0.03, 20), rng.uniform(0.001, 0.03, 20)
    for qx, qy in QUADRANTS:
        unfolded = sum(float(sector.sign(qx, qy)) * imperfection.sector_weight(sector, x, y)
                       for sector in SECTORS)
        assert np.allclose(unfolded, imperfection.weight(qx * x, qy * y), atol=1e-14)
    # the uniform electrode: 1 in the even-even sector, 0 in the others
    from copdea_fem.fe.forced.electrode import ElectrodeImperfection
    uniform = ElectrodeImperfection()
    assert np.allclose(uniform.sector_weight(SECTORS[0], x, y), 1.0)
    for sector in SECTORS[1:]:
        assert np.allclose(uniform.sector_weight(sector, x, y), 0.0)


def test_an_imperfection_refuses_what_is_not_one():
    from copdea_fem.fe.forced.electrode import ElectrodeImperfection

    with pytest.raises(ValueError, match="order m = 0 is not allowed"):
        ElectrodeImperfection((0,), (0.1,), (0.0,))
    with pytest.raises(ValueError, match="same length"):
        ElectrodeImperfection((1, 2), (0.1,), (0.0,))
    with pytest.raises(ValueError, match="order m = 1.5 is not allowed"):
        ElectrodeImperfection((1.5,), (0.1,), (0.0,))
    imperfection = ElectrodeImperfection.random((1, 2, 3), 0.1, np.random.default_rng(0))
    assert imperfection.family_weights(0) == (1.0, 0.0)
    assert imperfection.family_weights(7) == (0.0, 0.0)
    cos_part, sin_part = imperfection.family_weights(2)
    assert math.hypot(cos_part, sin_part) == pytest.approx(imperfection.amplitudes[1])
