"""The front of the band eigensolver: :func:`solve_band` and its results.

:func:`solve_band` returns *all* eigenpairs of a frequency band; see its
docstring for the covering strategy and why it cannot silently miss a mode.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp

from copdea_fem.fe.eigen.errors import EigenInputError, EigenResidualError, TooManyModesError
from copdea_fem.fe.eigen.factorization import Factorization, check_backend_name, require_backend
from copdea_fem.fe.eigen.frequencies import (
    frequency_from_eigenvalue,
    is_hermitian,
    relative_residuals,
)
from copdea_fem.fe.eigen.krylov import check_krylov
from copdea_fem.fe.eigen.planner import BandSolver
from copdea_fem.fe.eigen.region import BandRegion
from copdea_fem.progress import tagged

logger = logging.getLogger(__name__)


@dataclass(eq=False)
class BandResult:
    """All eigenpairs of one frequency band, sorted by ``Re f`` then ``Im f``.

    Attributes
    ----------
    eigenvalues : numpy.ndarray of complex, shape (k,)
        ``lam = omega**2`` (rad^2/s^2).
    freq_hz : numpy.ndarray, shape (k,)
        ``Re f`` (Hz), ``f = sqrt(lam) / (2 pi)`` with ``Re f >= 0``.
    freq_im_hz : numpy.ndarray, shape (k,)
        ``Im f`` (Hz).  Zero for a stable Hermitian pencil; ``sqrt(-lam)/(2 pi)``
        for a negative ``lam`` (unstable state); radiation damping with a PML.
    vectors : numpy.ndarray, shape (n, k)
        Eigenvectors, normalised (``x^H N x = 1`` with ``N = B`` for a
        Hermitian pencil, the identity for a general one, unless a
        normalisation matrix was given) and phase-fixed (the first component
        whose modulus is within 1e-6 of the largest is real positive).  Real
        for a real symmetric pencil.
    residuals : numpy.ndarray, shape (k,)
        ``||A x - lam B x||_2 / (||A|| ||x||_2)``, ``||A|| = sqrt(||A||_1 ||A||_inf)``.
    shifts : numpy.ndarray, shape (s,)
        Shifts ``sigma`` used (rad^2/s^2), in the order they were placed.
    shift_freq_hz : numpy.ndarray, shape (s,)
        ``Re sqrt(sigma) / (2 pi)`` (Hz) of each shift.
    coverage_radii : numpy.ndarray, shape (s,)
        Certified radius (rad^2/s^2) of each shift: every eigenvalue with
        ``|lam - sigma| < radius`` is in the computed set (``inf`` after a dense solve).
    factorisation_seconds : float
        Wall time spent factorising ``A - sigma B`` (s), all shifts.
    iteration_seconds : float
        Wall time in the Krylov runs, including their solves (s).
    total_seconds : float
        Wall time of the whole call (s).
    n_factorisations : int
    n_solves : int
        Right-hand sides solved with the factorisations, all shifts.
    n_block_solves : int
        Calls to the factorisations' solve (one per block of right-hand sides).
    hermitian : bool
        Whether the Hermitian (Lanczos, B-inner-product) path was used.
    backend : str
    residual_tol : float
        The tolerance the residuals were checked against.
    """

    eigenvalues: np.ndarray
    freq_hz: np.ndarray
    freq_im_hz: np.ndarray
    vectors: np.ndarray
    residuals: np.ndarray
    shifts: np.ndarray
    shift_freq_hz: np.ndarray
    coverage_radii: np.ndarray
    factorisation_seconds: float
    iteration_seconds: float
    total_seconds: float
    n_factorisations: int
    hermitian: bool
    backend: str
    residual_tol: float
    n_solves: int = 0
    n_block_solves: int = 0

    def __len__(self) -> int:
        return int(self.eigenvalues.shape[0])

    @property
    def unknowns(self) -> int:
        """Size n of the pencil."""
        return int(self.vectors.shape[0])

    @property
    def frequencies_hz(self) -> np.ndarray:
        """Complex frequencies ``f`` (Hz), ``freq_hz + 1j * freq_im_hz``."""
        return self.freq_hz + 1j * self.freq_im_hz

    @property
    def residual_ok(self) -> np.ndarray:
        """Boolean mask of the pairs whose residual is within ``residual_tol``."""
        return self.residuals <= self.residual_tol


@dataclass
class SectorBandResults:
    """The :class:`BandResult` of each symmetry sector of one solve (:mod:`copdea_fem.fe.symmetry`),
    with the summary fields of a single result (sums and concatenations)."""

    by_sector: dict        # sector name ("all" on a whole mesh) -> BandResult

    def _parts(self, name: str) -> list:
        return [getattr(result, name) for result in self.by_sector.values()]

    def _joined(name: str):
        """Property: the sectors' arrays ``name`` one after the other."""
        return property(lambda self: np.concatenate([np.asarray(part) for part in
                                                     self._parts(name)])
                        if self.by_sector else np.zeros(0))

    def _summed(name: str):
        """Property: the sum of the sectors' ``name``."""
        return property(lambda self: sum(self._parts(name)))

    eigenvalues, freq_hz, freq_im_hz, residuals = map(
        _joined, ("eigenvalues", "freq_hz", "freq_im_hz", "residuals"))
    shifts, shift_freq_hz = _joined("shifts"), _joined("shift_freq_hz")
    n_factorisations, unknowns = _summed("n_factorisations"), _summed("unknowns")
    n_solves, n_block_solves = _summed("n_solves"), _summed("n_block_solves")
    factorisation_seconds, iteration_seconds, total_seconds = map(
        _summed, ("factorisation_seconds", "iteration_seconds", "total_seconds"))
    del _joined, _summed


def solve_band(
    A,
    B,
    f_min: float,
    f_max: float,
    *,
    backend: str = "umfpack",
    max_modes: int = 200,
    hermitian: bool | None = None,
    residual_tol: float = 1e-6,
    check: bool = True,
    max_imag_hz: float | None = None,
    normalization_matrix=None,
    max_modes_per_shift: int = 80,
    initial_shifts=None,
    factorize: Callable[[float], "Factorization"] | None = None,
    start_modes: int | None = None,
    krylov: str = "krylov-schur",
) -> BandResult:
    """All eigenpairs of ``A x = lam B x`` whose frequency lies in a band.

    ``lam = omega**2`` (rad^2/s^2); ``f = sqrt(lam) / (2 pi)`` (Hz) with
    ``Re f >= 0``.  The band is ``f_min <= Re f <= f_max`` and
    ``|Im f| <= max_imag_hz``.  For a Hermitian pencil with ``f_min > 0``
    this is just ``(2 pi f_min)^2 <= lam <= (2 pi f_max)^2``; with
    ``f_min = 0`` it also holds the unstable modes ``-(2 pi max_imag_hz)^2
    <= lam < 0``.

    Parameters
    ----------
    A, B : scipy.sparse matrix or numpy.ndarray, shape (n, n)
        Stiffness-like ``A`` (N/m or consistent units) and mass-like ``B``
        (kg or consistent units), so that ``lam`` is in rad^2/s^2.
    f_min, f_max : float
        Band limits on ``Re f`` (Hz), ``0 <= f_min < f_max``.
    backend : {"umfpack", "pardiso", "superlu"}
        Factorisation of ``A - sigma B`` (see :class:`Factorization`).
    max_modes : int
        Largest number of eigenpairs returned; a band holding more raises
        :class:`TooManyModesError` (a ``ValueError``).
    hermitian : bool or None
        ``None``: detected (:func:`is_hermitian` on ``A`` and ``B``).  ``True``
        requires ``B`` Hermitian positive semi-definite.
    residual_tol : float
        Largest accepted relative residual ``||A x - lam B x|| / (||A|| ||x||)``.

    Progress: one line per factorisation and per Krylov run, each saying the share of
    the band certified so far, and a line every ``krylov.PROGRESS_INTERVAL_S`` of a long
    run, to the logger ``copdea_fem.fe.eigen.planner`` at INFO (the summary line to
    ``copdea_fem.fe.eigen.band``).
    check : bool
        If ``True``, a pair above ``residual_tol`` raises
        :class:`EigenResidualError`; if ``False`` it is returned and flagged
        in :attr:`BandResult.residual_ok`.
    max_imag_hz : float or None
        Half-height of the band in ``Im f`` (Hz); default ``0.25 * f_max``.
    normalization_matrix : scipy.sparse matrix or None
        Hermitian positive definite ``N`` for ``x^H N x = 1``; default ``B``
        if Hermitian, else the identity (unit 2-norm).
    max_modes_per_shift : int
        Most eigenpairs computed around one shift before another shift is
        placed (a run keeps about ``2 k`` vectors of length ``n``).
    initial_shifts : sequence of (float, int), optional
        ``(sigma, k)`` pairs (``sigma`` real, rad^2/s^2; ``k >= 1`` modes)
        run first, in order, instead of the first shift at the band's centre
        with ``k = 20`` -- e.g. a neighbouring sweep point's shifts with the
        number of modes found around each (:func:`copdea_fem.sweeps.shift_plan`).
        The planner and the certification then run as usual, so a poor plan
        costs time, never a mode.
    factorize : callable, optional
        ``factorize(sigma)`` returns an object like :class:`Factorization`
        (``solve`` of 1-D and 2-D right-hand sides, ``dtype``, ``solve_count``,
        ``factorisation_seconds``) for
        ``A - sigma B``, used instead of factorising the SciPy matrices -- e.g.
        an NGSolve matrix assembled natively complex (the coupled problem).
    start_modes : int, optional
        ``k`` of the first run at the band's centre (default 20) when no
        ``initial_shifts`` are given: an estimate of the band's count (e.g.
        from the dry modes) saves Krylov vectors; a low one costs another run.
    krylov : {"krylov-schur", "arpack"}
        Krylov method of a general pencil's runs (:mod:`copdea_fem.fe.eigen.krylov`):
        block Krylov-Schur with block solves (default) or ARPACK one vector at a
        time.  Hermitian pencils always use ARPACK's Lanczos.

    Returns
    -------
    BandResult

    Raises
    ------
    EigenInputError
        Bad argument (the message names it and the allowed values).
    TooManyModesError
        More than ``max_modes`` pairs in the band.
    BackendUnavailableError
        ``backend="pardiso"`` without MKL.
    EigenResidualError
        A residual above ``residual_tol`` (unless ``check=False``).
    EigenSolverError
        Krylov failure, singular pencil, or band impossible to cover.

    Notes
    -----
    Strategy: shift-invert with deflation and certified discs.
    Shifts ``sigma`` are real.  At a shift, ``A - sigma B`` is factorised once
    and a Krylov method (ARPACK's ``eigsh`` in mode 3 with the B-inner product
    if Hermitian; block Krylov-Schur on ``(A - sigma B)^-1 B`` otherwise, see
    :mod:`copdea_fem.fe.eigen.krylov`) is asked for the ``k``
    largest ``|nu|``, ``nu = 1/(lam - sigma)`` -- the ``k`` eigenvalues nearest
    ``sigma`` -- of the operator *deflated by every pair already known*
    (Wielandt: ``OP - X diag(nu_X) Z`` with ``Z X = I``; the known pairs move
    to ``nu = 0``).  So every run returns only new pairs, and more modes
    around a shift (extending ``k``) or a new shift never recompute old ones.

    A run at ``sigma`` that returns new eigenvalues at distances
    ``d_1 <= ... <= d_k`` states two things: (i) *certified*: no unknown
    eigenvalue was nearer than ``d_1`` -- every eigenvalue in the open disc
    ``|lam - sigma| < d_1`` was already known; this rests only on the Krylov run
    finding the dominant eigenvalue of the deflated operator, which it does
    for any start vector with a component along it (a random one, almost
    surely); (ii) *trusted*: the disc of radius ``d_k`` is complete if the run
    returned the ``k`` largest, which can fail for a multiple eigenvalue
    (Krylov methods see one copy first).  Discs of trusted radius are used to
    plan: the band's image in the lam-plane is sampled in cells with a slack
    radius that bounds each cell (so a covered sample proves the cell), and
    while a cell is outside every disc the solver either asks the nearest
    shift for more modes (cheap: same LU) when the gap is within 2.5 radii,
    or places a new shift into the gap, 0.75 radii beyond the frontier or at
    the gap's middle (with about as many modes as the neighbour's disc
    held, more if they fill the disc in two dimensions, see
    :meth:`BandSolver.plan_next`).  When the trusted discs cover the band, a *certification* run
    (``k = 2``, tol 1e-8, nothing stored) at a shift whose trusted disc is
    still needed gives the distance of the nearest eigenvalue still unknown
    (a Krylov-Schur run resumes the shift's last decomposition and drops the pairs
    known by now, so it costs a few solves, see :meth:`BandSolver.nearest_unknown`);
    shrunk by 1e-4 for its error, it is the certified radius and must reach
    the trusted one.  If a degenerate partner had been missed, it is nearer
    (the deflated operator no longer contains the found copy), the radius
    shrinks, and the shift is extended, which finds it.  The call returns
    only when the *certified* discs cover the band, enlarged by 0.1 % of its
    width, so a missed mode is impossible unless the Krylov run misses the dominant
    eigenvalue of a deflated operator.  Progress lines say the share of the band
    inside certified discs.

    De-duplication compares vectors, not only eigenvalues: pairs whose
    eigenvalues agree to 1e-6 (relative) are Rayleigh-Ritz'ed together on the
    span of their vectors, which keeps both members of a degenerate pair and
    drops only directions that are numerically the same.

    The guarantee covers the band as defined above: a general pencil's mode
    with ``|Im f| > max_imag_hz`` (a strongly damped PML mode) is outside it
    and is not returned even when it was computed on the way.  The certified
    radius of every shift is returned in :attr:`BandResult.coverage_radii`.
    """
    total_start = time.perf_counter()
    A, B = _validate_matrices(A, B)
    f_min, f_max = _validate_band(f_min, f_max)
    check_backend_name(backend)
    integer = isinstance(max_modes, (int, np.integer)) and not isinstance(max_modes, bool)
    if not (integer and max_modes >= 1):
        raise EigenInputError(f"max_modes={max_modes!r} must be an integer >= 1")
    if not (isinstance(max_modes_per_shift, (int, np.integer)) and max_modes_per_shift >= 4):
        raise EigenInputError(
            f"max_modes_per_shift={max_modes_per_shift!r} must be an integer >= 4")
    if hermitian not in (None, True, False):
        raise EigenInputError(f"hermitian={hermitian!r} must be None, True or False")
    if not (isinstance(residual_tol, (int, float)) and 0 < residual_tol < 1):
        raise EigenInputError(f"residual_tol={residual_tol!r} must be a number in (0, 1)")
    if max_imag_hz is None:
        max_imag_hz = 0.25 * f_max
    if not (np.isfinite(max_imag_hz) and max_imag_hz >= 0):
        raise EigenInputError(f"max_imag_hz={max_imag_hz!r} Hz must be a finite number >= 0")
    check_krylov(krylov)
    require_backend(backend)
    if hermitian is None:
        hermitian = is_hermitian(A) and is_hermitian(B)
    if normalization_matrix is not None:
        normalization_matrix = sp.csr_matrix(normalization_matrix)
        if normalization_matrix.shape != A.shape:
            raise EigenInputError(
                f"normalization_matrix has shape {normalization_matrix.shape}; expected {A.shape}"
            )

    # Band edges are widened by 1e-9 * f_max: computed frequencies carry
    # errors ~1e-12 (relative), so an edge placed on a degenerate pair keeps
    # both partners instead of splitting them by round-off.
    edge_tolerance_hz = 1e-9 * f_max

    def band_contains(values):
        f = frequency_from_eigenvalue(values)
        return ((f.real >= f_min - edge_tolerance_hz) & (f.real <= f_max + edge_tolerance_hz)
                & (np.abs(f.imag) <= max_imag_hz + edge_tolerance_hz))

    margin_hz = 1e-3 * (f_max - f_min)
    region = BandRegion(f_min, f_max, max_imag_hz, margin_hz, hermitian)
    # The Krylov runs stop at ||OP x - nu x|| <= tol |nu|, i.e. ||A x - lam B x|| <=
    # tol ||A - sigma B|| ||x||, and ||A - sigma B|| ~ ||A|| for sigma inside
    # the band (far below the top of an FE spectrum): keep 100x below the
    # requested residual, never looser than 1e-10, never below round-off.
    krylov_tol = max(min(1e-10, 0.01 * residual_tol), 1e-14)  # cannot go below ~eps
    initial_shifts = _validate_initial_shifts(initial_shifts)
    solver = BandSolver(A, B, region, backend=backend, hermitian=hermitian,
                        max_modes=max_modes, max_modes_per_shift=int(max_modes_per_shift),
                        band_contains=band_contains, tol=krylov_tol,
                        initial_shifts=initial_shifts, start_modes=start_modes,
                        factorize=factorize, krylov=krylov)
    solver.solve()

    values, vectors = solver.known.values, solver.known.vectors
    selected = band_contains(values)
    values, vectors = values[selected], vectors[:, selected]
    if values.size > max_modes:
        raise TooManyModesError(
            f"the band holds {values.size} eigenpairs, more than max_modes={max_modes}; "
            "raise max_modes or narrow the band"
        )
    vectors = _normalise(vectors, normalization_matrix if normalization_matrix is not None
                         else (B if hermitian else None))
    frequencies = frequency_from_eigenvalue(values)
    order = np.lexsort((frequencies.imag, frequencies.real))
    values, vectors, frequencies = values[order], vectors[:, order], frequencies[order]
    residuals = relative_residuals(A, B, values, vectors)
    result = BandResult(
        eigenvalues=values.astype(complex),
        freq_hz=frequencies.real.copy(),
        freq_im_hz=frequencies.imag.copy(),
        vectors=vectors,
        residuals=residuals,
        shifts=np.array([s.sigma for s in solver.shifts], dtype=float),
        shift_freq_hz=np.array([frequency_from_eigenvalue(s.sigma).real for s in solver.shifts]),
        coverage_radii=np.array([s.confirmed_radius for s in solver.shifts], dtype=float),
        factorisation_seconds=solver.factorisation_seconds,
        iteration_seconds=solver.iteration_seconds,
        total_seconds=time.perf_counter() - total_start,
        n_factorisations=len(solver.shifts),
        n_solves=sum(s.factorization.solve_count for s in solver.shifts),
        n_block_solves=sum(getattr(s.factorization, "block_solve_count", 0)
                           for s in solver.shifts),
        hermitian=bool(hermitian),
        backend=backend,
        residual_tol=float(residual_tol),
    )
    logger.info(tagged(
        f"band {f_min:g}..{f_max:g} Hz: {len(result)} modes, {result.n_factorisations} "
        f"factorisations ({result.factorisation_seconds:.3g} s), {result.n_solves} solves "
        f"in {result.n_block_solves} blocks, Krylov {result.iteration_seconds:.3g} s"
    ))
    if check and np.any(~result.residual_ok):
        worst = int(np.argmax(result.residuals))
        raise EigenResidualError(
            f"{np.count_nonzero(~result.residual_ok)} eigenpair(s) above "
            f"residual_tol={residual_tol:g}; worst: f = {result.freq_hz[worst]:.6g}"
            f"{result.freq_im_hz[worst]:+.3g}i Hz with relative residual "
            f"{result.residuals[worst]:.3g}"
        )
    return result


# --------------------------------------------------------------------------- validation


def _validate_matrices(A, B):
    matrices = []
    for name, matrix in (("A", A), ("B", B)):
        if not (sp.issparse(matrix) or isinstance(matrix, np.ndarray)):
            raise EigenInputError(f"{name} must be a scipy.sparse matrix or a numpy array; "
                                  f"got {type(matrix).__name__}")
        matrix = sp.csr_matrix(matrix)
        if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1] or matrix.shape[0] < 2:
            raise EigenInputError(f"{name} must be square with n >= 2; got shape {matrix.shape}")
        if matrix.dtype.kind not in "fciu":
            raise EigenInputError(f"{name} must be real or complex; got dtype {matrix.dtype}")
        if matrix.dtype.kind in "iu":
            matrix = matrix.astype(float)
        if not np.all(np.isfinite(matrix.data)):
            raise EigenInputError(f"{name} has non-finite entries")
        matrices.append(matrix)
    if matrices[0].shape != matrices[1].shape:
        raise EigenInputError(f"A and B must have the same shape; got {matrices[0].shape} "
                              f"and {matrices[1].shape}")
    return matrices


def _validate_initial_shifts(initial_shifts):
    """``[(sigma, k), ...]`` as plain (float, int) pairs, or an EigenInputError."""
    if initial_shifts is None:
        return None
    allowed = "a sequence of (sigma [rad^2/s^2], k) pairs, sigma finite real, k an integer >= 1"
    try:
        pairs = [(sigma, k) for sigma, k in initial_shifts]
    except (TypeError, ValueError):
        raise EigenInputError(f"initial_shifts={initial_shifts!r} is not allowed; allowed: "
                              f"{allowed}") from None
    for sigma, k in pairs:
        if isinstance(sigma, (bool, complex, np.complexfloating)) or \
                not isinstance(sigma, (int, float, np.integer, np.floating)) or \
                not np.isfinite(sigma) or isinstance(k, bool) or \
                not isinstance(k, (int, np.integer)) or k < 1:
            raise EigenInputError(f"initial_shifts entry {(sigma, k)!r} is not allowed; "
                                  f"allowed: {allowed}")
    return [(float(sigma), int(k)) for sigma, k in pairs]


def _validate_band(f_min, f_max):
    for name, value in (("f_min", f_min), ("f_max", f_max)):
        number = (isinstance(value, (int, float, np.integer, np.floating))
                  and not isinstance(value, bool))
        if not number or not np.isfinite(value):
            raise EigenInputError(f"{name}={value!r} Hz must be a finite number")
    f_min, f_max = float(f_min), float(f_max)
    if f_min < 0:
        raise EigenInputError(f"f_min={f_min:g} Hz must be >= 0 (Re f >= 0 by convention)")
    if not f_max > f_min:
        raise EigenInputError(f"f_max={f_max:g} Hz must be > f_min={f_min:g} Hz")
    return f_min, f_max


def _normalise(vectors: np.ndarray, weight) -> np.ndarray:
    """Scale to ``x^H W x = 1`` (or unit 2-norm) and fix the phase.

    Phase: the first component whose modulus is within a relative 1e-6 of the
    largest is made real positive.  The 1e-6 window makes the choice robust
    to round-off between back-ends when two components tie by symmetry (a
    symmetric mesh), while a genuine maximum still wins.
    """
    if vectors.shape[1] == 0:
        return vectors
    if weight is None:
        norms = np.linalg.norm(vectors, axis=0)
    else:
        norms = np.sqrt(np.abs(np.einsum("ij,ij->j", vectors.conj(), weight @ vectors)))
    vectors = vectors / norms[None, :]
    moduli = np.abs(vectors)
    largest = moduli.max(axis=0)
    pivot = np.argmax(moduli >= (1 - 1e-6) * largest[None, :], axis=0)
    pivot_values = vectors[pivot, np.arange(vectors.shape[1])]
    if np.iscomplexobj(vectors):
        phase = np.conj(pivot_values) / np.abs(pivot_values)
    else:
        phase = np.sign(pivot_values)
    return vectors * phase[None, :]
