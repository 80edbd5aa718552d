"""The reduced-basis forced response (issue 23, ``response.method: reduced``).

Against the direct path (one sparse solve per line, the exact model) on coarse meshes of
both engines, with a loss factor, Rayleigh damping and one Prony term: the reduced path
must be as exact as its residual says; at its shifts it must be exact by construction (the
projection argument of :mod:`copdea_fem.forced_response.reduced_basis`), which pins the
coefficient of every term of T(omega) and the shift set.
"""

from __future__ import annotations

import json
import logging
import types

import numpy as np
import pytest
from helpers import on_its_engine

from copdea_fem.cli import main
from copdea_fem.forced_response.reduced_basis import build_reduced_basis, ritz_modes
from copdea_fem.forced_response.run import (
    forced_response,
    modal_solution,
    prepare_order_zero,
    reduced_modal_solution,
    resolved_method,
)
from copdea_fem.study import StudyError, parse_study

DAMPED = {"rayleigh_alpha": 20.0, "rayleigh_beta": 2e-6, "loss_factor": 0.01,
          "prony": [{"modulus_ratio": 0.3, "relaxation_time": "0.3 ms"}]}
# G1 on a cone (z = 8 mm, 2 kV), baffle: the Prony branch acts on the out-of-plane modes
CONE = {"geometry": {"frame": "baffle"}, "load": {"z": "8 mm", "voltage": "2 kV"},
        "air": {"enabled": True}, "eigen": {"f_min": 10, "f_max": 500}}


def coarse(engine, **membrane):
    raw = {key: dict(value) for key, value in CONE.items()}
    raw["mesh"] = {"membrane_size": "6 mm", "order": 2, "engine": engine}
    raw["membrane"] = membrane
    return parse_study(raw, name="reduced_response")


def membrane_errors(problem, reference, approximation):
    u = problem.forced.membrane
    return np.array([np.linalg.norm(u(reference[:, k] - approximation[:, k]))
                     / np.linalg.norm(u(reference[:, k])) for k in range(reference.shape[1])])


@pytest.fixture(scope="module")
def meridian():
    return on_its_engine(prepare_order_zero, coarse("axisymmetric", **DAMPED))


@pytest.fixture(scope="module")
def quadrant():
    return on_its_engine(prepare_order_zero, coarse("3d", **DAMPED))


LINES = np.arange(4, 401) * 1.25          # 5 .. 500 Hz, the chirp's spacing


@pytest.mark.parametrize("engine", ["meridian", "quadrant"])
def test_reduced_path_matches_the_direct_solve_with_rayleigh_and_prony(engine, request):
    """Loss factor + Rayleigh + one Prony term, adaptive basis on 397 lines: every membrane
    unknown within 1e-6 of the direct solve at 4 lines across the band, one near the (0,1)
    peak (measured <= 1e-10; the issue asks 0.5 %), and the residual the basis
    reports is the one of the direct operator."""
    problem = request.getfixturevalue(engine)
    eta = problem.study.membrane.loss_factor
    model = build_reduced_basis(problem.forced, LINES, eta, tol=1e-8)
    assert model.residuals.max() <= 1e-8
    picks = np.array([0, 140, 287, 396])           # 5, 180, 363.75 (near (0,1)), 500 Hz
    check = LINES[picks]
    direct = problem.forced.direct(check, eta)
    reduced = model.response(check)
    errors = membrane_errors(problem, direct, reduced)
    print(f"{engine}: {model.size} vectors, shifts {np.round(model.shifts_hz, 1)} Hz, "
          f"errors {errors}")
    assert errors.max() < 1e-6, errors
    # the residual of eq. (1) recomputed from the sparse operator
    for k, f in zip(picks[[1, 2]], check[[1, 2]]):
        operator = problem.forced.operator(2 * np.pi * f, eta)
        rho = np.linalg.norm(operator @ (model.vectors @ model.line_coefficients[k])
                             - problem.forced.forcing) / np.linalg.norm(problem.forced.forcing)
        assert rho == pytest.approx(model.residuals[k], rel=1e-3, abs=1e-13)


def test_reduced_basis_is_exact_at_its_shifts(meridian):
    """One vector per shift (steps = 1: x(sigma_j) itself): the projection reproduces the
    direct solve at every shift (eq. 2 of the module: exact there), and only there -- a
    shift dropped, a term's coefficient wrong (sign of C, a Prony ratio, the loss factor)
    breaks it."""
    eta = meridian.study.membrane.loss_factor
    shifts = np.array([120.0, 310.0, 455.0])
    model = build_reduced_basis(meridian.forced, shifts, eta, steps=1, shifts_hz=shifts)
    assert model.size == 3
    between = np.array([200.0, 400.0])
    lines = np.concatenate([shifts, between])
    errors = membrane_errors(meridian, meridian.forced.direct(lines, eta),
                             model.response(lines))
    assert errors[:3].max() < 1e-9, errors
    assert errors[3:].min() > 1e-4, errors          # not exact between the shifts
    assert model.residuals.max() < 1e-9             # its residual on its own lines (shifts)


def test_more_moments_per_shift_converge(meridian):
    """Moment matching: at one shift (300 Hz) the error at 330 Hz falls as Arnoldi steps
    (Taylor moments) are added, as the projection argument says."""
    eta = meridian.study.membrane.loss_factor
    line = np.array([330.0])
    direct = meridian.forced.direct(line, eta)
    errors = [membrane_errors(meridian, direct, build_reduced_basis(
        meridian.forced, line, eta, steps=steps, shifts_hz=[300.0]).response(line))[0]
              for steps in (1, 4, 12)]
    assert errors[0] > 10 * errors[1] > 100 * errors[2], errors


def test_modal_path_warns_under_prony_and_reduced_is_exact(meridian, caplog):
    """The modal path under Prony is a few % off (its static correction uses the relaxed
    stiffness): it says so and points to the reduced path, which is exact there."""
    with caplog.at_level(logging.WARNING, logger="copdea_fem"):
        basis, _ = modal_solution(meridian, 500.0)
    assert any("response.method: reduced" in record.getMessage() for record in caplog.records)


def test_auto_method_is_reduced_on_3d_and_modal_on_the_meridian(quadrant, meridian):
    """``response.method: auto`` (the default): reduced on the 3-D engine, modal on the
    axisymmetric one; the spectra of the 3-D reduced path equal the direct ones."""
    assert quadrant.study.response.method == "auto"
    lines = np.array([100.0, 250.0, 400.0])
    volts = np.full(lines.size, 2.0 + 0j)
    reduced = forced_response(quadrant, lines, volts)
    assert reduced.method == "reduced" and reduced.basis.size > 0
    direct_problem = type(quadrant)(quadrant.study.replace({"response.method": "direct"}),
                                    quadrant.state, quadrant.coupled, quadrant.forced,
                                    dict(quadrant.timings), quadrant.sector)
    direct = forced_response(direct_problem, lines, volts)
    for name in ("average_axial", "average_radial"):
        np.testing.assert_allclose(getattr(reduced, name), getattr(direct, name), rtol=1e-6)
    np.testing.assert_allclose(reduced.pressure, direct.pressure, rtol=1e-6)
    assert forced_response(meridian, lines, volts).method == "modal"


def test_auto_method_damps_the_reduced_modes_where_the_damping_is_the_papers_modal_bm(quadrant):
    """Without a loss of its own (no loss factor, Rayleigh or Prony) the study's damping is
    the modal b/m: ``auto`` is ``reduced_modal`` on 3-D (its modes damped per mode), modal
    on the meridian; with a loss of its own, ``reduced`` on 3-D."""
    undamped = coarse("3d")
    assert resolved_method(types.SimpleNamespace(study=undamped,
                                                 sector=quadrant.sector)) == "reduced_modal"
    assert resolved_method(types.SimpleNamespace(study=quadrant.study,
                                                 sector=quadrant.sector)) == "reduced"
    forced = undamped.replace({"response.method": "reduced"})
    assert resolved_method(types.SimpleNamespace(study=forced, sector=None)) == "reduced"
    assert resolved_method(types.SimpleNamespace(study=undamped, sector=None)) == "modal"


# ------------------------------------------- reduced_modal: the paper's b/m on the basis
def with_method(problem, method):
    """The same prepared problem with another ``response.method``."""
    return type(problem)(problem.study.replace({"response.method": method}), problem.state,
                         problem.coupled, problem.forced, dict(problem.timings),
                         problem.sector)


@pytest.fixture(scope="module")
def plain_meridian():
    """The cone on the meridian with the paper's modal b/m only (no loss of its own)."""
    return on_its_engine(prepare_order_zero, coarse("axisymmetric"))


def test_reduced_modal_without_bm_is_the_reduced_path(plain_meridian):
    """Eq. (3) of reduced_basis with every b/m = 0 is the Galerkin solution of eq. (2),
    exactly: the k Ritz modes diagonalise the projected pencil (round-off: < 1e-8)."""
    forced = plain_meridian.forced
    reduced = build_reduced_basis(forced, LINES)
    ritz = ritz_modes(forced, reduced)
    assert ritz.size == reduced.size and not np.any(ritz.damping)
    errors = membrane_errors(plain_meridian, reduced.response(LINES), ritz.response(LINES))
    assert errors.max() < 1e-8


def test_reduced_modal_matches_the_modal_path_with_the_papers_bm(plain_meridian):
    """The same modes, labels and b/m as the modal path; the velocity spectra within 0.5 %
    on every line (measured <= 0.15 %: the modal path's truncation and residual correction,
    0.4 % of the direct path by its own test) and the (0,1) peak within 1e-4 (measured
    4e-6: there both are the one damped mode).  Without the kinetic share s_i of eq. (3) the
    peak would be m/(m + m_ad) ~ 0.6 off."""
    volts = np.ones(LINES.size, complex)
    mine = forced_response(with_method(plain_meridian, "reduced_modal"), LINES, volts)
    modal = forced_response(with_method(plain_meridian, "modal"), LINES, volts)
    assert mine.method == "reduced_modal"
    structural = [(m.label, m.freq_hz) for m in mine.modes if m.kind != "air"]
    reference = [(m.label, m.freq_hz) for m in modal.modes
                 if m.kind != "air" and m.freq_hz <= 2 * LINES.max()]
    assert [label for label, _ in structural] == [label for label, _ in reference]
    np.testing.assert_allclose([f for _, f in structural], [f for _, f in reference],
                               rtol=1e-6)
    damping = dict(zip([m.label for m in mine.modes], mine.basis.damping_per_mass))
    assert damping["(0,1)"] == plain_meridian.study.reduced.damping_01 > 0
    for name in ("average_axial", "average_radial"):
        np.testing.assert_allclose(getattr(mine, name), getattr(modal, name), rtol=5e-3)
    peak = int(np.argmax(modal.average_axial))
    assert mine.average_axial[peak] == pytest.approx(modal.average_axial[peak], rel=1e-4)


def test_reduced_modal_shifts_to_an_unconverged_structural_mode(plain_meridian, monkeypatch,
                                                               caplog):
    """A basis too small to converge its structural Ritz modes in the lines (6 Arnoldi steps
    per shift): each such mode gets a shift of its own and the basis is built again, until
    every structural mode it damps is converged (residual <= eigen.residual_tol)."""
    from copdea_fem.forced_response import reduced_basis
    original = reduced_basis.build_reduced_basis
    monkeypatch.setattr(reduced_basis, "build_reduced_basis",
                        lambda *args, **kwargs: original(*args, steps=6, **kwargs))
    with caplog.at_level(logging.INFO, logger="copdea_fem"):
        ritz, modes = reduced_modal_solution(plain_meridian, LINES)
    assert any("not converged; shifts added" in r.getMessage() for r in caplog.records)
    first = original(plain_meridian.forced, LINES, steps=6).shifts_hz
    assert len(ritz.reduced.shifts_hz) > len(first)
    damped = ritz.mode_index[ritz.damping_per_mass > 0]
    assert damped.size and np.all(ritz.residuals[damped]
                                  <= plain_meridian.study.eigen.residual_tol)
    assert "(0,1)" in [m.label for m in modes]


@pytest.mark.slow
def test_reduced_modal_matches_the_modal_path_on_the_square_frame():
    """The 3-D quadrant in the square frame (the cone, coarse), the case ``auto`` sends to
    reduced_modal: the structural modes below the last line as the modal path labels them,
    velocity spectra within 1 % on every line (measured <= 0.33 %) and the (0,1) peak within
    1e-4 (measured 3e-6); the modal path costs minutes here, the reduced one seconds."""
    problem = on_its_engine(prepare_order_zero, coarse("3d").replace({"geometry.frame": "square"}))
    volts = np.ones(LINES.size, complex)
    mine = forced_response(problem, LINES, volts)
    modal = forced_response(with_method(problem, "modal"), LINES, volts)
    assert mine.method == "reduced_modal"

    def structural(result):
        return [m.label for m in result.modes if m.kind != "air" and m.freq_hz <= LINES.max()]
    assert structural(mine) == structural(modal) and "(0,1)" in structural(mine)
    for name in ("average_axial", "average_radial"):
        np.testing.assert_allclose(getattr(mine, name), getattr(modal, name), rtol=1e-2)
    peak = int(np.argmax(modal.average_axial))
    assert mine.average_axial[peak] == pytest.approx(modal.average_axial[peak], rel=1e-4)


@pytest.mark.parametrize("loss", [{"loss_factor": 0.01}, {"rayleigh_beta": 1e-6},
                                  {"prony": DAMPED["prony"]}], ids=["eta", "beta", "prony"])
def test_reduced_modal_refuses_a_loss_of_its_own(loss):
    """reduced_modal with a loss factor, Rayleigh or Prony: the one-line StudyError as the
    study is read (``check`` says it too)."""
    with pytest.raises(StudyError, match="response.method = 'reduced_modal' is not allowed"):
        coarse("axisymmetric", **loss).replace({"response.method": "reduced_modal"})


@pytest.mark.parametrize("command", ["check", "response"])
def test_cli_refuses_reduced_modal_with_a_loss_of_its_own(tmp_path, capsys, command):
    """Exit 2, one line naming the key, no folder."""
    out = tmp_path / "r"
    argv = [command, "studies/g1_z16_v2_quick.yaml", "--set", "response.method=reduced_modal",
            "--set", "membrane.rayleigh_alpha=10"]
    assert main(argv + (["--out", str(out), "--quiet"] if command == "response" else [])) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "response.method" in error[0] and "Traceback" not in error[0]
    assert not out.exists()


def test_cli_reduced_response_writes_its_basis(tmp_path):
    """The CLI with ``response.method=reduced`` on a short chirp: response.json says how
    the basis was built; every line met the tolerance."""
    out = tmp_path / "r"
    code = main(["response", "studies/g1_z16_v2_response.yaml", "--out", str(out),
                 "--set", "mesh.membrane_size=6 mm", "--set", "mesh.order=2",
                 "--set", "excitation.duration=0.2 s", "--set", "excitation.f_end=500 Hz",
                 "--set", "response.method=reduced", "--set", "output.plots=false",
                 "--set", "output.paraview=false"])
    assert code == 0
    document = json.loads((out / "response.json").read_text())
    assert document["method"] == "reduced"
    basis = document["reduced_basis"]
    assert basis["max_residual"] <= basis["tolerance"] == 1e-7
    assert basis["vectors"] > 0 and len(basis["shifts_hz"]) >= 1
