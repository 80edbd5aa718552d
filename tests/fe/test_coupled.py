"""Fully-coupled membrane-air modes (rung 5): air loading, labels, outputs, convergence."""

import csv
from pathlib import Path

import meshio
import numpy as np
import pytest
from helpers import COARSE_AIR, coupled_study, on_its_engine

from copdea_fem.cli import main
from copdea_fem.fe import engine_for
from copdea_fem.fe.pipeline import coupled_modes
from copdea_fem.progress import progress_to

ROOT = Path(__file__).resolve().parents[2]
@pytest.fixture(scope="module")
def flat():
    return on_its_engine(coupled_modes, coupled_study(eigen={"f_max": "450 Hz"}))


def test_air_loading_lowers_every_structural_frequency(flat):
    structural = [(k, mode) for k, mode in enumerate(flat.modes) if mode.kind == "out-of-plane"]
    assert len(structural) >= 5
    for k, mode in structural:
        dry = flat.dry_partner_hz[k]
        assert mode.freq_hz < dry, mode.label
        assert (dry / mode.freq_hz) ** 2 - 1 > 0.05, mode.label   # added mass, not noise
        assert 0.3 < mode.membrane_energy_fraction < 1.0
    # (0,1) pushes the most air: largest added-mass ratio (paper Sect. 5.2)
    ratios = {mode.label: (flat.dry_partner_hz[k] / mode.freq_hz) ** 2 - 1 for k, mode in structural}
    assert max(ratios, key=ratios.get) == "(0,1)"
    assert np.all(np.asarray(flat.eigen.residuals) < 1e-6)


def test_flat_labels_follow_bessel_order(flat):
    """Bessel order, and the square frame's C4v: the (1,1) pair is its two-dimensional class
    E, degenerate on the mesh symmetric under x <-> y (to 1e-6; Netgen's own quadrant mesh
    split it by 0.25 %); the (2,1) pair is the classes B1 (cos 2 theta) and B2 (sin 2 theta),
    which the frame splits: measured sin 0.63 Hz below cos (0.66 Hz at 4 mm)."""
    structural = [mode for mode in flat.modes if mode.kind == "out-of-plane"]
    labels = [mode.label for mode in structural]
    assert labels[0] == "(0,1)"
    assert sorted(labels[1:3]) == ["(1,1)a", "(1,1)b"]
    assert labels[3:5] == ["(2,1)b", "(2,1)a"]
    assert structural[1].freq_hz == pytest.approx(structural[2].freq_hz, rel=1e-6)
    assert 5e-4 < structural[4].freq_hz / structural[3].freq_hz - 1 < 3e-3


def test_radiation_damping_is_small_and_positive(flat):
    (mode,) = [m for m in flat.modes if m.label == "(0,1)"]
    # e^{-i omega t}: a radiating mode decays, Im f < 0, damping ratio > 0 but << 1
    assert mode.freq_im_hz < 0
    assert 0 < mode.damping_ratio < 0.01


@pytest.mark.parametrize("backend", ["umfpack", "pardiso"])
def test_factorisation_backend_is_a_setting_of_the_coupled_solve(flat, backend, monkeypatch):
    """eigen.backend reaches the coupled shift-invert: same modes with every back-end."""
    from copdea_fem.fe import coupled
    from copdea_fem.fe.eigen import backend_available
    if not backend_available(backend):
        pytest.skip(f"{backend} is not installed here (pardiso needs pip install mkl)")
    used = []
    for name in ("Factorization", "NativeShiftedInverse"):
        original = getattr(coupled, name)

        def spy(*args, _original=original, **kwargs):
            factorisation = _original(*args, **kwargs)
            used.append(kwargs.get("backend", args[-1]))
            return factorisation
        monkeypatch.setattr(coupled, name, spy)
    other = on_its_engine(coupled_modes,
                          coupled_study(eigen={"f_max": "450 Hz", "backend": backend}))
    assert used and set(used) == {backend}
    assert [m.label for m in other.modes] == [m.label for m in flat.modes]
    np.testing.assert_allclose([m.freq_hz for m in other.modes],
                               [m.freq_hz for m in flat.modes], rtol=1e-8)
    np.testing.assert_allclose([m.freq_im_hz for m in other.modes],
                               [m.freq_im_hz for m in flat.modes], rtol=1e-5, atol=1e-6)


def test_unavailable_backend_is_rejected_before_meshing(tmp_path, capsys, monkeypatch):
    from copdea_fem.fe import eigen
    monkeypatch.setattr(eigen, "backend_available", lambda name: name != "pardiso")
    out = tmp_path / "run"
    code = main(["solve", str(ROOT / "studies/g1_z16_v2_quick.yaml"), "--out", str(out),
                 "--set", "eigen.backend=pardiso", "--set", "mesh.membrane_size=1 mm"])
    assert code == 2
    err = capsys.readouterr().err
    assert "eigen.backend = 'pardiso' is not available" in err and "pip install mkl" in err
    assert "meshing" not in err and not out.exists()


def test_coupled_solve_writes_contract_files(tmp_path):
    out = tmp_path / "run"
    code = main(["solve", str(ROOT / "studies/g1_z16_v2.yaml"), "--out", str(out), "--quiet",
                 "--set", "air.enabled=true", "--set", "eigen.f_max=480 Hz",
                 "--set", "output.plots=false",
                 *[f"--set=mesh.{key}={value}" for key, value in COARSE_AIR.items()]])
    assert code == 0
    rows = list(csv.DictReader(open(out / "modes.csv")))
    first = rows[0]
    assert first["label"] == "(0,1)" and first["kind"] == "out-of-plane"
    for column in ("freq_hz", "freq_im_hz", "damping_ratio", "membrane_energy_fraction",
                   "modal_mass", "dry_freq_hz", "added_mass_ratio"):
        assert first[column] != "", column
    ratio = float(first["added_mass_ratio"])
    assert ratio == pytest.approx((float(first["dry_freq_hz"]) / float(first["freq_hz"])) ** 2 - 1)
    assert 0.2 < ratio < 1.5
    air_files = sorted(out.glob("air_*.vtu"))
    assert air_files and (out / "air.pvd").is_file()
    grid = meshio.read(air_files[0])
    assert {"pressure_real", "pressure_imag", "pressure_abs"} <= set(grid.point_data)
    assert set(np.unique(grid.cell_data["pml"][0])) == {0, 1}
    np.testing.assert_allclose(grid.point_data["pressure_abs"],
                               np.hypot(grid.point_data["pressure_real"],
                                        grid.point_data["pressure_imag"]), rtol=1e-5)
    # the pressure jumps across the membrane: points written twice (upper and
    # lower copy) carry different pressures, of opposite sign for (0,1)
    keys = [tuple(np.round(point, 7)) for point in grid.points]
    seen, jumps = {}, []
    pressure = grid.point_data["pressure_real"]
    for index, key in enumerate(keys):
        if key in seen:
            jumps.append((pressure[seen[key]], pressure[index]))
        seen[key] = index
    jumps = np.array(jumps)
    assert len(jumps) > 10
    largest = jumps[np.argmax(np.abs(jumps[:, 0] - jumps[:, 1]))]
    assert largest[0] * largest[1] < 0


@pytest.mark.slow
def test_air_radius_does_not_move_the_modes(figures):
    """(0,1), (0,2): < 0.5 % from 3.5 r_o to 5 r_o (issue 3)."""
    results = []
    for radius in ("124.25 mm", "177.5 mm"):
        solution = on_its_engine(coupled_modes,
                                 coupled_study(air={"enabled": True, "domain_radius": radius},
                                               eigen={"f_max": "900 Hz"},
                                               mesh={"membrane_size": "6 mm"}))
        results.append({m.label: m.freq_hz for m in solution.modes})
    figures("air radius 3.5 r_o -> 5 r_o (6 mm, order 2, pressure order 1):",
            [f"{label}: {results[0][label]:.3f} -> {results[1][label]:.3f} Hz "
             f"({results[1][label] / results[0][label] - 1:+.2e})" for label in ("(0,1)", "(0,2)")])
    for label in ("(0,1)", "(0,2)"):
        assert results[1][label] == pytest.approx(results[0][label], rel=5e-3), label


@pytest.mark.slow
def test_mesh_convergence_of_coupled_modes(figures):
    """(0,1), (1,1)a, (0,2) at 4 / 3 (the default) / 2.5 mm: the changes shrink, and the
    default mesh's error estimate is < 1 %.

    (Not 9 / 6 / 4 mm: with the air at air_size = r_o, 9 -> 6 mm adds only 9 % of
    unknowns on the quadrant mesh, so it is no refinement.)
    The estimate takes the observed order p of the three meshes, floored at 0.5
    (the pressure jump has a square-root singularity at the screens' free edges,
    so the asymptotic rate is low and the pre-asymptotic one erratic):
    error(3 mm) = |f_3 - f_2.5| 3^p / (3^p - 2.5^p).
    """
    from scipy.optimize import brentq
    labels = ("(0,1)", "(1,1)a", "(0,2)")
    sizes = np.array([4.0, 3.0, 2.5])
    frequencies = []
    for size in sizes:
        solution = on_its_engine(coupled_modes,
                                 coupled_study(eigen={"f_max": "900 Hz"},
                                               mesh={"membrane_size": f"{size} mm", "order": 3,
                                                     "pressure_order": 2}))
        found = {m.label: m.freq_hz for m in solution.modes}
        frequencies.append([found[label] for label in labels])
    frequencies = np.array(frequencies)
    change = np.abs(np.diff(frequencies, axis=0)) / frequencies[1:]
    errors, orders = [], []
    for j in range(len(labels)):
        ratio = abs(frequencies[0, j] - frequencies[1, j]) / abs(frequencies[1, j] -
                                                                 frequencies[2, j])

        def mismatch(p):
            return (sizes[0]**p - sizes[1]**p) / (sizes[1]**p - sizes[2]**p) - ratio

        p = brentq(mismatch, 0.5, 6.0) if mismatch(0.5) < 0 < mismatch(6.0) else 0.5
        orders.append(p)
        errors.append(abs(frequencies[1, j] - frequencies[2, j]) * sizes[1]**p
                      / (sizes[1]**p - sizes[2]**p) / frequencies[1, j])
    figures("coupled mesh convergence (order 3, pressure order 2), f [Hz] at 4/3/2.5 mm:",
            [f"{label}: " + " / ".join(f"{f:.3f}" for f in frequencies[:, j])
             + f"  changes {change[0, j]:.2e}, {change[1, j]:.2e}; order {orders[j]:.2f}, "
             f"error of the 3 mm mesh {errors[j]:.2e}"
             for j, label in enumerate(labels)])
    # the slack: on the octant-mirrored mesh the (0,2) changes by 2.0e-4 then 3.2e-4 (its
    # 790.9 Hz to 0.03 %: pre-asymptotic, as the docstring says); Netgen's own mesh fell
    assert np.all(change[1] < change[0] + 2e-4), frequencies
    assert np.all(np.array(errors) < 0.01), errors


@pytest.mark.slow
def test_m1_pair_stays_degenerate_under_the_square_frame(figures):
    """C4v symmetry: m = 1 stays a degenerate pair, m = 2 splits."""
    solution = on_its_engine(coupled_modes,
                             coupled_study(eigen={"f_max": "480 Hz"},
                                           mesh={"membrane_size": "4 mm", "order": 3,
                                                 "pressure_order": 2}))
    found = {m.label: m.freq_hz for m in solution.modes}
    split_1 = abs(found["(1,1)a"] - found["(1,1)b"]) / found["(1,1)a"]
    split_2 = abs(found["(2,1)a"] - found["(2,1)b"]) / found["(2,1)a"]
    figures("square frame, 4 mm order 3: relative splitting of the pairs",
            [f"(1,1): {split_1:.2e}", f"(2,1): {split_2:.2e}"])
    assert split_1 < 0.2 * split_2, (split_1, split_2)


def test_crowded_air_sphere_krylov_schur_finds_every_mode_with_fewer_solves():
    """A 0.5 m air sphere around G1 (coarse): the band's disc also holds many lightly and
    strongly damped air/PML modes.  Krylov-Schur with its larger basis finds exactly the
    modes ARPACK's default basis finds (the method before it), with fewer solves
    (measured 127 against 391 since the certification resumes the run's decomposition,
    245 before: the ratio 0.45 leaves room for round-off in the restarts)."""
    from copdea_fem.fe.coupled import assemble_coupled
    from copdea_fem.fe.eigen import solve_band
    from copdea_fem.fe.linearise import linearised_operators, membrane_matrices
    from copdea_fem.fe.pipeline import prepare_mesh
    from copdea_fem.fe.prestress import solve_prestress

    study = coupled_study(air={"enabled": True, "domain_radius": "0.5 m"},
                          mesh={"air_size": "50 mm"}, eigen={"f_max": "1000 Hz"})
    mesh = prepare_mesh(study, with_air=True, engine=engine_for(study))
    state = solve_prestress(study, mesh)
    sector = state.symmetry.sectors[0]
    coupled = assemble_coupled(study, mesh, state).restrict(
        linearised_operators(state, study, sector, membrane_matrices(state)))
    eigen = study.eigen
    messages = {"arpack": [], "krylov-schur": []}
    results = {}
    for method in messages:
        with progress_to(messages[method].append):
            results[method] = solve_band(
                coupled.stiffness, coupled.mass, eigen.f_min, eigen.f_max,
                hermitian=False, factorize=coupled.factorize,
                max_imag_hz=eigen.max_damping_ratio * eigen.f_max,
                backend=eigen.backend, krylov=method)
    old, new = results["arpack"], results["krylov-schur"]
    known = max(int(line.split(" known")[0].split()[-1]) for line in messages["krylov-schur"]
                if " known" in line)
    assert known >= 2 * len(new)             # crowded: most pairs in the disc are outside the band
    assert len(new) == len(old) >= 10
    np.testing.assert_allclose(new.freq_hz, old.freq_hz, rtol=1e-8)
    np.testing.assert_allclose(new.freq_im_hz, old.freq_im_hz, rtol=1e-5, atol=1e-6)
    assert np.all(new.residuals < 1e-6)
    assert new.n_solves < 0.45 * old.n_solves
