"""Tests of the shift-invert band eigensolver (copdea_fem.fe.eigen).

Reference problems have closed-form *discrete* spectra, so the comparison is
exact up to the solver's tolerance, independent of mesh size:

* string: linear FE of ``-c^2 u'' = lam u`` on (0, L), u = 0 at both ends,
  ``lam_j = c^2 (6/h^2) (1 - cos t_j) / (2 + cos t_j)``, ``t_j = j pi h / L``;
* square membrane: bilinear (Q1) FE on the unit square, ``K2 = K1 x M1 + M1 x K1``,
  ``M2 = M1 x M1`` (Kronecker), so ``lam_pq = lam_p + lam_q`` exactly and
  ``lam_pq = lam_qp`` gives exact double eigenvalues (the cos/sin pairs of a
  circular membrane in miniature);
* damped membrane: ``((1 + i eta) K2, M2)``, complex symmetric non-Hermitian,
  ``lam = (1 + i eta) lam_pq``.
"""

import os

# Single-threaded BLAS for these small matrices.  On the shared 2-core test
# machine, OpenBLAS worker threads that wait for a core make ARPACK/SuperLU
# calls on n ~ 400 up to 100x slower (measured: 0.003 s vs 0.4-2 s per eigs
# call); one thread is also what small problems want.  Only effective if this
# module is the first to import NumPy/SciPy; an explicit setting wins.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
import scipy.linalg  # noqa: E402
import scipy.sparse as sp  # noqa: E402

from copdea_fem.fe import eigen  # noqa: E402
from copdea_fem.fe.eigen import (
    BACKENDS,
    BackendUnavailableError,
    EigenInputError,
    EigenResidualError,
    Factorization,
    TooManyModesError,
    backend_available,
    frequency_from_eigenvalue,
    planner,  # noqa: E402
    solve_band,
)
from copdea_fem.progress import progress_to  # noqa: E402

WAVE_SPEED = 100.0   # m/s
LENGTH = 1.0         # m

# ARPACK runs at tol = 1e-10 on nu = 1/(lam - sigma), so |d lam| <~ 1e-10 |lam - sigma|
# <= 1e-10 lam_top (top of the covered band).  With f_top / f_min <= 10 in these
# bands, the relative frequency error is <= 0.5e-10 (f_top/f)^2 <= 5e-9.
FREQUENCY_RTOL = 1e-8


# --------------------------------------------------------------------------- reference problems


def string_matrices(n_elements, length=LENGTH, wave_speed=WAVE_SPEED):
    """FE string: stiffness (c^2-scaled, m/s^2), mass (m) and exact lam (rad^2/s^2)."""
    h = length / n_elements
    n = n_elements - 1
    stiffness = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n)) * (wave_speed**2 / h)
    mass = sp.diags([1.0, 4.0, 1.0], [-1, 0, 1], shape=(n, n)) * (h / 6.0)
    theta = np.arange(1, n + 1) * np.pi * h / length
    exact = wave_speed**2 * (6.0 / h**2) * (1.0 - np.cos(theta)) / (2.0 + np.cos(theta))
    return stiffness.tocsr(), mass.tocsr(), exact


def square_matrices(n_elements):
    """Q1 FE of the square membrane; exact lam_pq = lam_p + lam_q (all pairs p, q)."""
    k1, m1, lam1 = string_matrices(n_elements)
    stiffness = (sp.kron(k1, m1) + sp.kron(m1, k1)).tocsr()
    mass = sp.kron(m1, m1).tocsr()
    exact = (lam1[:, None] + lam1[None, :]).ravel()
    return stiffness, mass, np.sort(exact)


def frequencies(lam):
    return np.asarray(frequency_from_eigenvalue(lam))


def band_between(sorted_freqs, first, last):
    """Band edges (Hz) in the gaps around sorted_freqs[first..last], and the frequencies inside.

    ``first``/``last`` are moved outward to the ends of their groups of equal
    frequencies, so each edge lies half-way between two *distinct* values and
    the expected set does not depend on round-off.
    """
    tolerance = 1e-8 * sorted_freqs[-1]
    while first > 0 and sorted_freqs[first] - sorted_freqs[first - 1] <= tolerance:
        first -= 1
    while sorted_freqs[last + 1] - sorted_freqs[last] <= tolerance:
        last += 1
    low = 0.0 if first == 0 else 0.5 * (sorted_freqs[first - 1] + sorted_freqs[first])
    high = 0.5 * (sorted_freqs[last] + sorted_freqs[last + 1])
    return low, high, sorted_freqs[first:last + 1]


def multiplicities(sorted_values, relative=1e-8):
    """Sizes of groups of equal values (relative 1e-8: exact degeneracies here agree to ~1e-14)."""
    groups = [1]
    for previous, current in zip(sorted_values[:-1], sorted_values[1:]):
        if abs(current - previous) <= relative * abs(current):
            groups[-1] += 1
        else:
            groups.append(1)
    return groups


# --------------------------------------------------------------------------- closed-form spectra


def test_string_band_matches_closed_form():
    stiffness, mass, exact = string_matrices(400)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 3, 24)
    result = solve_band(stiffness, mass, f_min, f_max, backend="superlu")
    assert len(result) == expected.size
    np.testing.assert_allclose(result.freq_hz, expected, rtol=FREQUENCY_RTOL)
    assert result.hermitian
    assert np.all(result.freq_im_hz == 0.0)
    assert np.all(np.isfinite(result.coverage_radii))  # ARPACK path, not the dense fallback
    assert np.max(result.residuals) < 1e-9  # ARPACK tol 1e-10 with ||A - sigma B|| ~ ||A||


def test_long_arpack_runs_report_their_solves(monkeypatch):
    import re

    from copdea_fem.fe.eigen import krylov
    stiffness, mass, exact = string_matrices(400)
    f_min, f_max, _ = band_between(frequencies(exact).real, 3, 24)
    quiet = []
    with progress_to(quiet.append):
        solve_band(stiffness, mass, f_min, f_max, backend="superlu")
    assert not any(message.endswith("s ...") for message in quiet)   # fast: no heartbeat
    monkeypatch.setattr(krylov, "PROGRESS_INTERVAL_S", 0.0)
    messages = []
    with progress_to(messages.append):
        solve_band(stiffness, mass, f_min, f_max, backend="superlu")
    beats = [m for m in messages if re.fullmatch(
        r"shift 1 at .* Hz: \d+ solves, \d+ s \(band \d+ % certified\) \.\.\.", m)]
    counts = [int(re.search(r"(\d+) solves", m).group(1)) for m in beats]
    assert len(beats) > 10 and counts[:3] == [1, 2, 3]


def test_square_membrane_returns_every_member_of_degenerate_pairs():
    stiffness, mass, exact = square_matrices(30)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 0, 39)
    result = solve_band(stiffness, mass, f_min, f_max, backend="superlu")
    assert multiplicities(expected).count(2) >= 10  # the test really has many exact pairs
    assert len(result) == expected.size
    assert multiplicities(result.freq_hz) == multiplicities(expected)
    np.testing.assert_allclose(result.freq_hz, expected, rtol=FREQUENCY_RTOL)
    # Both members of every pair are independent: the vectors are mass-orthonormal.
    gram = result.vectors.T @ (mass @ result.vectors)
    np.testing.assert_allclose(gram, np.eye(len(result)), atol=1e-8)


def test_band_needing_several_shifts_is_complete_and_deduplicated():
    stiffness, mass, exact = square_matrices(30)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 4, 45)
    messages = []
    with progress_to(messages.append):
        result = solve_band(stiffness, mass, f_min, f_max, backend="superlu",
                            max_modes_per_shift=8)
    assert result.n_factorisations >= 3
    assert len(result.shifts) == result.n_factorisations
    assert len(result) == expected.size
    assert multiplicities(result.freq_hz) == multiplicities(expected)
    np.testing.assert_allclose(result.freq_hz, expected, rtol=FREQUENCY_RTOL)
    gram = result.vectors.T @ (mass @ result.vectors)
    np.testing.assert_allclose(gram, np.eye(len(result)), atol=1e-8)
    assert any(message.startswith("shift 2 at") and "Hz" in message for message in messages)


def test_missed_degenerate_partner_is_recovered_by_the_confirmation_run(monkeypatch):
    """Simulate ARPACK returning one copy of each double eigenvalue in its first run."""
    original = planner.BandSolver.nearest_unknown
    calls = []

    def arpack_missing_partners(self, shift, k, tol=None, basis=None):
        values, vectors, exhausted = original(self, shift, k, tol=tol, basis=basis)
        calls.append(values.size)
        if len(calls) == 1:
            keep = np.ones(values.size, dtype=bool)
            order = np.argsort(values.real)
            for previous, current in zip(order[:-1], order[1:]):
                same = abs(values[current] - values[previous]) <= 1e-8 * abs(values[current])
                if same and keep[previous]:
                    keep[current] = False  # drop the second member of the pair
            assert not np.all(keep), "the first run should have contained a pair to drop"
            values, vectors = values[keep], vectors[:, keep]
        return values, vectors, exhausted

    monkeypatch.setattr(planner.BandSolver, "nearest_unknown", arpack_missing_partners)
    stiffness, mass, exact = square_matrices(24)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 0, 15)
    messages = []
    with progress_to(messages.append):
        result = solve_band(stiffness, mass, f_min, f_max, backend="superlu",
                            max_modes_per_shift=expected.size + 10)
    assert len(calls) >= 2
    assert any("missed multiple eigenvalue" in message for message in messages)
    assert multiplicities(result.freq_hz) == multiplicities(expected)
    np.testing.assert_allclose(result.freq_hz, expected, rtol=FREQUENCY_RTOL)


@pytest.mark.parametrize("krylov", ["krylov-schur", "arpack"])
def test_certification_finds_an_eigenvalue_a_crippled_run_missed(monkeypatch, krylov):
    """A general pencil with a known eigenvalue in the band; every Krylov run before the
    first certification is made to lose it (and to claim discs that hold it).  The
    certification run must see the unknown eigenvalue inside the trusted disc, and the
    band must hold it."""
    loss_factor = 0.05
    stiffness, mass, exact = square_matrices(20)
    exact_complex = np.sort_complex(frequencies((1 + 1j * loss_factor) * exact))
    f_min, f_max, _ = band_between(exact_complex.real, 2, 25)
    expected = exact_complex[(exact_complex.real >= f_min) & (exact_complex.real <= f_max)]
    single = [f for f in expected
              if np.count_nonzero(np.abs(expected - f) <= 1e-8 * abs(f)) == 1]
    planted = single[len(single) // 2]   # a simple eigenvalue, the one the crippled run loses
    original = planner.BandSolver.nearest_unknown
    calls = []

    def crippled(self, shift, k, tol=None, basis=None):
        values, vectors, exhausted = original(self, shift, k, tol=tol, basis=basis)
        certifying = tol is not None               # certification runs pass their tol
        calls.append(certifying)
        if not any(calls):                         # no certification yet: lose it
            lost = np.abs(frequencies(values) - planted) <= 1e-6 * abs(planted)
            values, vectors = values[~lost], vectors[:, ~lost]
        return values, vectors, exhausted

    monkeypatch.setattr(planner.BandSolver, "nearest_unknown", crippled)
    messages = []
    with progress_to(messages.append):
        result = solve_band((1 + 1j * loss_factor) * stiffness, mass, f_min, f_max,
                            backend="superlu", krylov=krylov)
    assert any("an unknown eigenvalue lies inside the trusted radius" in message
               for message in messages)
    assert len(result) == expected.size
    assert np.min(np.abs(result.frequencies_hz - planted)) <= FREQUENCY_RTOL * abs(planted)
    np.testing.assert_allclose(result.frequencies_hz, expected, rtol=FREQUENCY_RTOL)
    assert re_certified(messages)


def re_certified(messages):
    """The last progress line of the band solve says it is 100 % certified."""
    shift_lines = [m for m in messages if "% certified" in m]
    return bool(shift_lines) and shift_lines[-1].endswith("band 100 % certified")


def certification_solves(messages):
    """Solves of each certification run, from its progress line."""
    return [int(m.split("(")[-1].split(" solves")[0]) for m in messages
            if "certified radius" in m]


def test_certification_resumes_the_runs_krylov_decomposition():
    """Krylov-Schur keeps its decomposition on the shift: the certification continues it
    (the next Ritz values are half converged already) instead of building a new Krylov
    space, so it costs a few solves where a fresh run (ARPACK's path) takes tens; the band
    is the same."""
    loss_factor = 0.05
    stiffness, mass, exact = square_matrices(24)
    exact_complex = np.sort_complex(frequencies((1 + 1j * loss_factor) * exact))
    f_min, f_max, _ = band_between(exact_complex.real, 3, 40)
    messages = {"krylov-schur": [], "arpack": []}
    results = {}
    for method in messages:
        with progress_to(messages[method].append):
            results[method] = solve_band((1 + 1j * loss_factor) * stiffness, mass, f_min,
                                         f_max, backend="superlu", krylov=method)
    resumed, fresh = (certification_solves(messages[m]) for m in ("krylov-schur", "arpack"))
    assert resumed and fresh
    assert max(resumed) <= 10 < min(fresh)          # measured 6 against 43
    np.testing.assert_allclose(results["krylov-schur"].frequencies_hz,
                               results["arpack"].frequencies_hz, rtol=FREQUENCY_RTOL)


def test_known_pairs_tell_a_degenerate_partner_from_a_copy():
    """KnownPairs.contains: the same eigenvalue with a direction in the known span is known,
    the partner of a double eigenvalue (same value, independent direction) is not."""
    from copdea_fem.fe.eigen.pairs import KnownPairs
    stiffness, mass, exact = square_matrices(12)
    values, vectors = scipy.linalg.eigh(stiffness.toarray(), mass.toarray())
    double = int(np.flatnonzero(np.abs(np.diff(values)) <= 1e-9 * values[1:])[0])
    known = KnownPairs(stiffness, mass, hermitian=True, real_arithmetic=True,
                       scale=float(values[-1]))
    known.add(values[[double, double + 3]], vectors[:, [double, double + 3]])
    candidates = vectors[:, [double, double + 1, double + 2]] * np.array([-2.0, 1.0, 1.0])
    mask = known.contains(values[[double, double + 1, double + 2]], candidates)
    assert mask.tolist() == [True, False, False]


@pytest.mark.parametrize("krylov", ["krylov-schur", "arpack"])
def test_block_and_arpack_runs_give_the_same_general_band(krylov):
    """Both Krylov methods on the damped membrane: the same modes, residual-checked."""
    loss_factor = 0.05
    stiffness, mass, exact = square_matrices(24)
    exact_complex = np.sort_complex(frequencies((1 + 1j * loss_factor) * exact))
    f_min, f_max, _ = band_between(exact_complex.real, 3, 40)
    expected = exact_complex[(exact_complex.real >= f_min) & (exact_complex.real <= f_max)]
    result = solve_band((1 + 1j * loss_factor) * stiffness, mass, f_min, f_max,
                        backend="superlu", krylov=krylov)
    assert len(result) == expected.size
    np.testing.assert_allclose(result.frequencies_hz, expected, rtol=FREQUENCY_RTOL)
    assert result.n_solves > 0 and result.n_block_solves > 0
    if krylov == "krylov-schur" and eigen.krylov.BLOCK_SIZE > 1:   # blocks of right-hand sides
        assert result.n_solves >= 4 * result.n_block_solves
    else:
        assert result.n_solves == result.n_block_solves


def test_wide_band_with_default_settings_uses_more_than_one_shift():
    stiffness, mass, exact = string_matrices(1500)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 10, 109)  # 100 modes > max_modes_per_shift = 80
    result = solve_band(stiffness, mass, f_min, f_max, backend="superlu")
    assert result.n_factorisations >= 2
    np.testing.assert_allclose(result.freq_hz, expected, rtol=FREQUENCY_RTOL)


def test_unstable_state_reports_negative_eigenvalues():
    stiffness, mass, exact = string_matrices(300)
    softening = 0.5 * (exact[1] + exact[2])  # two eigenvalues pushed below zero
    shifted = (stiffness - softening * mass).tocsr()
    shifted_exact = exact - softening
    f_max = 0.5 * (frequencies(shifted_exact[6]).real + frequencies(shifted_exact[7]).real)
    result = solve_band(shifted, mass, 0.0, f_max, backend="superlu",
                        max_imag_hz=2.0 * frequencies(-shifted_exact[0]).real)
    assert len(result) == 7
    # Sorted by (Re f, Im f): the unstable pair first, slower growth (smaller Im f) first.
    expected = np.concatenate([np.sort(shifted_exact[:2])[::-1], shifted_exact[2:7]])
    np.testing.assert_allclose(result.eigenvalues.real, expected,
                               rtol=1e-8, atol=1e-10 * shifted_exact[6])
    unstable = result.eigenvalues.real < 0
    assert np.count_nonzero(unstable) == 2
    assert np.all(result.freq_hz[unstable] == 0.0)
    growth_hz = np.sqrt(-result.eigenvalues.real[unstable]) / (2 * np.pi)
    np.testing.assert_allclose(result.freq_im_hz[unstable], growth_hz, rtol=1e-12)


# --------------------------------------------------------------------------- non-Hermitian


def test_damped_membrane_complex_pairs():
    loss_factor = 0.05
    stiffness, mass, exact = square_matrices(20)
    exact_complex = np.sort_complex(frequencies((1 + 1j * loss_factor) * exact))
    real_parts = exact_complex.real
    f_min, f_max, _ = band_between(real_parts, 2, 25)
    result = solve_band((1 + 1j * loss_factor) * stiffness, mass, f_min, f_max, backend="superlu")
    expected = exact_complex[(real_parts >= f_min) & (real_parts <= f_max)]
    assert not result.hermitian
    assert len(result) == expected.size
    assert multiplicities(result.freq_hz) == multiplicities(expected.real)
    # Non-Hermitian: eigenvalue error is first order in the residual, |d lam| <~
    # 1e-10 |lam - sigma|; same bound as FREQUENCY_RTOL.
    np.testing.assert_allclose(result.frequencies_hz, expected, rtol=FREQUENCY_RTOL)
    assert np.all(result.freq_im_hz > 0)
    # Degenerate partners are independent vectors (rank of each pair is 2).
    for group_start in np.flatnonzero(np.diff(result.freq_hz) <= 1e-8 * result.freq_hz[1:]):
        pair = result.vectors[:, group_start:group_start + 2]
        singular_values = np.linalg.svd(pair, compute_uv=False)
        assert singular_values[-1] > 0.1 * singular_values[0]


@pytest.mark.parametrize("perturbation_kind", ["complex", "real"])
def test_random_non_normal_pencil_matches_dense_qz(perturbation_kind):
    rng = np.random.default_rng(7)
    stiffness, mass, _ = string_matrices(301)  # n = 300
    n = stiffness.shape[0]
    stiffness_scale = np.linalg.norm(stiffness.toarray(), 1)
    perturbation = sp.random(n, n, density=0.02, random_state=rng, data_rvs=rng.standard_normal)
    if perturbation_kind == "complex":
        perturbation = perturbation + 1j * sp.random(n, n, density=0.02, random_state=rng,
                                                     data_rvs=rng.standard_normal)
    perturbation = perturbation * (0.02 * stiffness_scale / abs(perturbation).sum(axis=0).max())
    pencil_a = (stiffness + perturbation).tocsr()
    pencil_b = (mass + 0.1 * sp.diags(rng.uniform(0, 1, n)) * mass.diagonal().mean()).tocsr()
    alpha_beta, _ = scipy.linalg.eig(pencil_a.toarray(), pencil_b.toarray(),
                                     homogeneous_eigvals=True)
    dense_f = frequencies(alpha_beta[0] / alpha_beta[1])
    f_min, f_max, imag_max = 150.0, 1200.0, 60.0
    # The reference set must not depend on round-off: no eigenvalue near an edge.
    distances = np.concatenate([np.abs(dense_f.real - f_min), np.abs(dense_f.real - f_max),
                                np.abs(np.abs(dense_f.imag) - imag_max)])
    assert distances.min() > 1e-6 * f_max, "test pencil has an eigenvalue on the band edge"
    inside = (dense_f.real >= f_min) & (dense_f.real <= f_max) & (np.abs(dense_f.imag) <= imag_max)
    expected = dense_f[inside]
    expected = expected[np.lexsort((expected.imag, expected.real))]
    # Real perturbation: real pencil, eigenvalues real or in conjugate pairs.
    assert expected.size >= 10 and np.any(np.abs(expected.imag) > 1.0)
    result = solve_band(pencil_a, pencil_b, f_min, f_max, backend="superlu", max_imag_hz=imag_max)
    assert not result.hermitian
    assert np.all(np.isfinite(result.coverage_radii))
    assert len(result) == expected.size
    # A 2 % perturbation keeps eigenvalue condition numbers O(10): both solvers'
    # backward errors (~1e-12 dense, ~1e-10 ARPACK) give < 1e-8 relative.
    np.testing.assert_allclose(result.frequencies_hz, expected, rtol=1e-7)


def test_complex_hermitian_pencil_uses_lanczos_and_matches_dense():
    rng = np.random.default_rng(5)
    stiffness, mass, _ = square_matrices(20)
    n = stiffness.shape[0]
    skew = sp.random(n, n, density=0.01, random_state=rng, data_rvs=rng.standard_normal)
    skew = skew - skew.T
    skew = skew * (0.05 * eigen.matrix_norm_estimate(stiffness) / eigen.matrix_norm_estimate(skew))
    pencil_a = (stiffness + 1j * skew).tocsr()  # Hermitian, not real
    dense_lam = scipy.linalg.eigh(pencil_a.toarray(), mass.toarray(), eigvals_only=True)
    dense = np.sort(frequencies(dense_lam).real)
    f_min, f_max, expected = band_between(dense, 3, 20)
    result = solve_band(pencil_a, mass, f_min, f_max, backend="superlu")
    assert result.hermitian and result.vectors.dtype == np.complex128
    np.testing.assert_allclose(result.freq_hz, expected, rtol=FREQUENCY_RTOL)
    gram = result.vectors.conj().T @ (mass @ result.vectors)
    np.testing.assert_allclose(gram, np.eye(len(result)), atol=1e-8)


# --------------------------------------------------------------------------- back-ends


def _skip_if_unavailable(backend):
    if not backend_available(backend):
        assert backend == "pardiso", f"{backend} must always be available"
        pytest.skip("pardiso needs Intel MKL, which is not installed (pip install mkl)")


@pytest.mark.parametrize("backend", BACKENDS)
def test_factorization_solves_real_and_complex_systems(backend):
    _skip_if_unavailable(backend)
    stiffness, mass, exact = square_matrices(20)
    n = stiffness.shape[0]
    rng = np.random.default_rng(3)
    shift = float(0.37 * exact[5] + 0.63 * exact[6])  # between eigenvalues: indefinite, regular
    real_matrix = (stiffness - shift * mass).tocsr()
    unsymmetric = 0.01j * sp.triu(stiffness, 1)
    complex_matrix = ((1 + 0.05j) * stiffness - shift * mass + unsymmetric).tocsr()
    for matrix in (real_matrix, complex_matrix):
        factorization = Factorization(matrix, backend=backend)
        rhs = rng.standard_normal((n, 3)) + 1j * rng.standard_normal((n, 3))
        for right_hand_side in (rhs[:, 0].real.copy(), rhs[:, 1], rhs):
            solution = factorization.solve(right_hand_side)
            assert solution.shape == right_hand_side.shape
            residual = np.linalg.norm(matrix @ solution - right_hand_side) / (
                eigen.matrix_norm_estimate(matrix) * np.linalg.norm(solution))
            assert residual < 1e-12  # backward stable LU: ~eps * growth
        operator = factorization.as_linear_operator(dtype=complex)
        np.testing.assert_array_equal(operator.matvec(rhs[:, 2]), factorization.solve(rhs[:, 2]))


@pytest.mark.parametrize("backend", BACKENDS)
def test_each_backend_gives_the_same_band(backend):
    _skip_if_unavailable(backend)
    stiffness, mass, exact = square_matrices(16)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 1, 14)
    result = solve_band(stiffness, mass, f_min, f_max, backend=backend)
    assert result.backend == backend and result.n_factorisations >= 1
    np.testing.assert_allclose(result.freq_hz, expected, rtol=FREQUENCY_RTOL)
    complex_result = solve_band((1 + 0.02j) * stiffness, mass, f_min, f_max, backend=backend)
    damped = np.sort_complex(frequencies((1 + 0.02j) * exact))
    damped = damped[(damped.real >= f_min) & (damped.real <= f_max)]
    np.testing.assert_allclose(complex_result.frequencies_hz, damped, rtol=FREQUENCY_RTOL)


def test_static_pivoting_falls_back_to_threshold_pivoting_when_unstable():
    """SuperLU first takes the diagonal as pivot (less fill in the fill-reducing order) and
    keeps it only if a probe solve is backward stable; 2x2 blocks [[1e-14, 1], [1, 1e-14]]
    make diagonal pivots grow by 1e14, so the matrix is factorised again with threshold
    pivoting and solves to round-off.  An FE matrix keeps its static pivots."""
    blocks = 2000
    tiny = sp.kron(sp.identity(blocks), sp.csr_matrix([[1e-14, 1.0], [1.0, 1e-14]]))
    chain = sp.diags([0.01 * np.ones(2 * blocks - 3)], [3], shape=(2 * blocks,) * 2)
    matrix = (tiny + chain + chain.T).tocsr()
    unstable = Factorization(matrix, "superlu")
    assert not unstable.static_pivoting
    rhs = np.random.default_rng(5).standard_normal(2 * blocks)
    solution = unstable.solve(rhs)
    assert np.linalg.norm(matrix @ solution - rhs) < 1e-12 * np.linalg.norm(rhs)
    assert unstable.solve_count == 1           # the probe is not counted
    stiffness, mass, exact = square_matrices(60)
    shift = float(0.5 * (exact[10] + exact[11]))
    regular = Factorization((stiffness - shift * mass).tocsr(), "superlu")
    assert regular.static_pivoting and regular.backward_error(stiffness - shift * mass) < 1e-14


def test_pardiso_without_mkl_names_the_fix():
    if backend_available("pardiso"):
        pytest.skip("MKL is installed here, so the missing-MKL error cannot occur")
    stiffness, mass, _ = string_matrices(20)
    with pytest.raises(BackendUnavailableError, match=r"pardiso.*pip install mkl"):
        Factorization(stiffness, backend="pardiso")
    with pytest.raises(BackendUnavailableError, match="pip install mkl"):
        solve_band(stiffness, mass, 10.0, 100.0, backend="pardiso")


# --------------------------------------------------------------------------- residuals, inputs


def test_residual_check_raises_and_can_flag_instead():
    stiffness, mass, exact = string_matrices(200)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 0, 5)
    # 1e-17 is below double round-off of ||A x|| (~1e-16 ||A|| ||x||): unreachable.
    with pytest.raises(EigenResidualError, match=r"residual_tol=1e-17.*Hz.*residual") as raised:
        solve_band(stiffness, mass, f_min, f_max, backend="superlu", residual_tol=1e-17)
    assert isinstance(raised.value, RuntimeError)
    flagged = solve_band(stiffness, mass, f_min, f_max, backend="superlu", residual_tol=1e-17,
                         check=False)
    assert len(flagged) == expected.size and not np.all(flagged.residual_ok)
    recomputed = eigen.relative_residuals(stiffness, mass, flagged.eigenvalues, flagged.vectors)
    np.testing.assert_allclose(flagged.residuals, recomputed)


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (dict(f_min=100.0, f_max=100.0), r"f_max=100 Hz must be > f_min=100 Hz"),
        (dict(f_min=200.0, f_max=100.0), r"f_max=100 Hz must be > f_min=200 Hz"),
        (dict(f_min=-1.0, f_max=100.0), r"f_min=-1 Hz must be >= 0"),
        (dict(backend="mumps"), r"backend='mumps'.*allowed: 'umfpack', 'pardiso', 'superlu'"),
        (dict(max_modes=0), r"max_modes=0 must be an integer >= 1"),
        (dict(residual_tol=0.0), r"residual_tol=0.0 must be a number in \(0, 1\)"),
        (dict(max_imag_hz=-5.0), r"max_imag_hz=-5.0 Hz must be a finite number >= 0"),
        (dict(hermitian="yes"), r"hermitian='yes' must be None, True or False"),
    ],
)
def test_bad_arguments_name_the_argument_and_allowed_values(arguments, message):
    stiffness, mass, _ = string_matrices(50)
    call = dict(f_min=10.0, f_max=500.0, backend="superlu")
    call.update(arguments)
    with pytest.raises(EigenInputError, match=message) as raised:
        solve_band(stiffness, mass, call.pop("f_min"), call.pop("f_max"), **call)
    assert isinstance(raised.value, ValueError)


def test_mismatched_shapes_are_rejected():
    stiffness, _, _ = string_matrices(50)
    _, small_mass, _ = string_matrices(40)
    with pytest.raises(EigenInputError, match=r"same shape"):
        solve_band(stiffness, small_mass, 10.0, 500.0)


def test_too_many_modes_raises_naming_max_modes():
    stiffness, mass, exact = string_matrices(300)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 0, 9)  # 10 modes
    with pytest.raises(TooManyModesError, match=r"more than max_modes=4") as raised:
        solve_band(stiffness, mass, f_min, f_max, backend="superlu", max_modes=4)
    assert isinstance(raised.value, ValueError)
    exactly_enough = solve_band(stiffness, mass, f_min, f_max, backend="superlu",
                                max_modes=expected.size)
    assert len(exactly_enough) == expected.size


# --------------------------------------------------------------------------- determinism, norms


def test_two_runs_give_identical_output():
    stiffness, mass, exact = square_matrices(20)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 0, 19)
    # Hermitian over several shifts (de-duplication, Ritz), complex on one.
    for pencil_a, per_shift in ((stiffness, 10), ((1 + 0.03j) * stiffness, 80)):
        first, second = (solve_band(pencil_a, mass, f_min, f_max, backend="superlu",
                                    max_modes_per_shift=per_shift) for _ in range(2))
        assert np.array_equal(first.eigenvalues, second.eigenvalues)
        assert np.array_equal(first.vectors, second.vectors)
        assert np.array_equal(first.shifts, second.shifts)


def _assert_phase_fixed(vectors):
    for column in vectors.T:
        moduli = np.abs(column)
        pivot = np.flatnonzero(moduli >= (1 - 1e-6) * moduli.max())[0]
        assert column[pivot].real > 0
        assert abs(np.imag(column[pivot])) <= 1e-12 * abs(column[pivot])


def test_vectors_are_normalised_and_phase_fixed():
    stiffness, mass, exact = square_matrices(16)
    exact_f = frequencies(exact).real
    f_min, f_max, expected = band_between(exact_f, 0, 11)
    hermitian_result = solve_band(stiffness, mass, f_min, f_max, backend="superlu")
    assert hermitian_result.vectors.dtype == np.float64
    vectors = hermitian_result.vectors
    np.testing.assert_allclose(np.einsum("ij,ij->j", vectors, mass @ vectors), 1.0, rtol=1e-12)
    _assert_phase_fixed(hermitian_result.vectors)

    complex_result = solve_band((1 + 0.03j) * stiffness, mass, f_min, f_max, backend="superlu")
    assert complex_result.vectors.dtype == np.complex128
    np.testing.assert_allclose(np.linalg.norm(complex_result.vectors, axis=0), 1.0, rtol=1e-12)
    _assert_phase_fixed(complex_result.vectors)

    weighted = solve_band((1 + 0.03j) * stiffness, mass, f_min, f_max, backend="superlu",
                          normalization_matrix=mass)
    mass_norms = np.einsum("ij,ij->j", weighted.vectors.conj(), mass @ weighted.vectors)
    np.testing.assert_allclose(mass_norms, 1.0, rtol=1e-12)


# --------------------------------------------------------------------------- edge cases


def test_empty_band_and_tiny_problem():
    stiffness, mass, exact = string_matrices(400)
    exact_f = frequencies(exact).real
    spacing = exact_f[5] - exact_f[4]
    gap_low, gap_high = exact_f[4] + 0.2 * spacing, exact_f[4] + 0.8 * spacing
    empty = solve_band(stiffness, mass, gap_low, gap_high, backend="superlu")
    assert len(empty) == 0 and empty.vectors.shape == (stiffness.shape[0], 0)

    small_stiffness, small_mass, small_exact = string_matrices(12)  # n = 11: dense QZ
    small_f = frequencies(small_exact).real
    f_min, f_max, expected = band_between(small_f, 2, 8)
    tiny = solve_band(small_stiffness, small_mass, f_min, f_max, backend="superlu")
    np.testing.assert_allclose(tiny.freq_hz, expected, rtol=1e-12)
    assert np.all(np.isinf(tiny.coverage_radii))


def test_frequency_branch():
    f = frequency_from_eigenvalue(np.array([4 * np.pi**2, -4 * np.pi**2, -4 * np.pi**2 - 1e-9j]))
    np.testing.assert_allclose(f[:2], [1.0, 1.0j])
    assert f[2].real >= 0 and f[2].imag < 0


def test_superlu_factorises_large_matrices_in_nested_dissection_order():
    """A 3-D seven-point Laplacian (3375 unknowns, shifted complex): METIS order, exact solves,
    less fill than SuperLU's own minimum-degree order."""
    import scipy.sparse.linalg as spla
    n = 15
    line = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    eye = sp.identity(n)
    laplacian = (sp.kron(sp.kron(line, eye), eye) + sp.kron(sp.kron(eye, line), eye)
                 + sp.kron(sp.kron(eye, eye), line)).tocsr()
    matrix = (laplacian - (0.5 + 0.1j) * sp.identity(n**3)).tocsr()
    order = eigen.fill_reducing_order(matrix)
    assert order is not None and np.array_equal(np.sort(order), np.arange(n**3))
    factorisation = Factorization(matrix, "superlu")
    rhs = np.random.default_rng(1).standard_normal(n**3) + 1j
    solution = factorisation.solve(rhs)
    assert np.linalg.norm(matrix @ solution - rhs) < 1e-10 * np.linalg.norm(rhs)
    nested = factorisation._superlu.L.nnz + factorisation._superlu.U.nnz
    own = spla.splu(matrix.tocsc(), permc_spec="MMD_AT_PLUS_A")
    assert nested < own.L.nnz + own.U.nnz
    assert eigen.fill_reducing_order(matrix[:100, :100]) is None     # small: SuperLU's own


def test_shift_inverted_dense_matches_qz_with_infinite_eigenvalues():
    """The dense fallback above DENSE_DOFS (a crowded band): the standard problem
    (A - sigma B)^-1 B x = nu x gives QZ's finite eigenpairs (a damped string, n = 99, with
    three massless unknowns: three infinite eigenvalues, dropped as QZ's beta = 0)."""
    stiffness, mass, _ = string_matrices(100)
    n = stiffness.shape[0]
    mass = mass.tolil()
    for k in (10, 50, 90):          # massless: B singular
        mass[k, :] = 0.0
        mass[:, k] = 0.0
    a = ((1 + 0.05j) * stiffness).toarray()
    b = mass.toarray()
    alpha_beta, _ = scipy.linalg.eig(a, b, homogeneous_eigvals=True)
    finite = np.abs(alpha_beta[1]) > 1e-13 * np.abs(alpha_beta[0])
    expected = np.sort_complex(alpha_beta[0][finite] / alpha_beta[1][finite])
    sigma = float(np.median(expected.real))
    values, vectors = planner.BandSolver.shift_inverted_dense(a, b, sigma)
    assert values.size == n - 3 == expected.size
    np.testing.assert_allclose(np.sort_complex(values), expected, rtol=1e-9)
    residual = np.linalg.norm(a @ vectors - b @ vectors * values[None, :], axis=0)
    assert residual.max() < 1e-9 * np.linalg.norm(a) * np.abs(vectors).max()
    # sigma on an eigenvalue: numerically singular, (None, None): the caller's QZ
    assert planner.BandSolver.shift_inverted_dense(np.eye(3), np.eye(3), 1.0) == (None, None)


def test_crowded_band_goes_dense_by_shift_invert_and_matches_qz(monkeypatch):
    """A general pencil of n = 99 > DENSE_DOFS whose band holds more than a third of it:
    the planner's dense fallback (shift-invert standard problem) returns QZ's band."""
    calls = []
    original = planner.BandSolver.shift_inverted_dense
    monkeypatch.setattr(planner.BandSolver, "shift_inverted_dense", staticmethod(
        lambda a, b, sigma: calls.append(sigma) or original(a, b, sigma)))
    stiffness, mass, exact = string_matrices(100)
    eta = 0.02
    f = frequencies((1 + 1j * eta) * exact)
    f_max = float(np.sort(f.real)[60])              # 60 modes in the band: > n / 3
    f_max = 0.5 * (f_max + float(np.sort(f.real)[61]))
    result = solve_band((1 + 1j * eta) * stiffness, mass, 0.0, f_max, backend="superlu",
                        max_imag_hz=f_max, hermitian=False)
    assert np.all(np.isinf(result.coverage_radii)) and len(calls) == 1  # shift-invert
    expected = np.sort(f.real[f.real <= f_max])
    np.testing.assert_allclose(result.freq_hz, expected, rtol=1e-10)
