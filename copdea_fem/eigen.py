"""Shift-invert band eigensolver for the pencil ``A x = lam B x``.

The eigenvalue is ``lam = omega**2`` (rad^2/s^2, ``omega`` the angular
frequency in rad/s) and the frequency is ``f = sqrt(lam) / (2 pi)`` (Hz), the
square root with ``Re f >= 0``.  Two kinds of pencil are solved:

* Hermitian (the dry membrane): ``A``, ``B`` real symmetric or complex
  Hermitian, ``B`` positive semi-definite.  ``A`` may be indefinite (an
  unstable prestressed state): negative ``lam`` come out with ``Re f = 0`` and
  ``Im f = sqrt(-lam) / (2 pi) > 0``.
* General (membrane + air with a PML, the unsymmetric u-p form): ``A``, ``B``
  complex and non-Hermitian; ``lam`` complex, ``Im f`` measures the
  radiation damping.

:func:`solve_band` returns *all* eigenpairs of a frequency band; see its
docstring for the covering strategy and why it cannot silently miss a mode.
:class:`Factorization` wraps one sparse LU (NGSolve UMFPACK or MKL PARDISO, or
SciPy SuperLU) so that callers (forced response, sweeps) can factorise once
and solve many right-hand sides.

Everything here works on SciPy sparse matrices; NGSolve is only used as a
factorisation engine.  NGSolve 6.2.2608 notes (checked):

* ``la.SparseMatrixd.CreateFromCOO(rows, cols, values, h, w)`` accepts int32 /
  float64 NumPy arrays.  The complex class (``la.SparseMatrixSt7complexIdE``)
  has a ``CreateFromCOO`` that wants an ``ngcore::Array<complex>``, a type
  ``pyngcore`` does not export, so a complex matrix cannot be built from
  Python.  Complex matrices are therefore factorised by the NGSolve back-ends
  in their real-equivalent form ``[[Re S, -Im S], [Im S, Re S]]`` (2n x 2n,
  interleaved so each complex entry is a 2x2 block); SuperLU factorises them
  natively.
* ``inverse="pardiso"`` is NGSolve's ctypes wrapper around MKL; it exists only
  after ``pip install mkl``.  Installing ``mkl`` also makes PARDISO NGSolve's
  *default* inverse type for every matrix in the process.
* Shifts are handed over as plain Python ``float``/``complex``.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

BACKENDS: tuple[str, ...] = ("umfpack", "pardiso", "superlu")
"""Names accepted by ``backend``: NGSolve UMFPACK, NGSolve/MKL PARDISO, SciPy SuperLU."""

TWO_PI = 2.0 * math.pi
PROGRESS_INTERVAL_S = 15.0
"""A long ARPACK run reports its solve count this often [s] (``progress``)."""


# --------------------------------------------------------------------------- errors


class EigenInputError(ValueError):
    """An argument of the eigensolver is outside what is allowed; the message says which."""


class TooManyModesError(EigenInputError):
    """The band holds more eigenpairs than ``max_modes``."""


class BackendUnavailableError(RuntimeError):
    """The requested factorisation back-end is not installed; the message says how to get it."""


class EigenSolverError(RuntimeError):
    """ARPACK or the factorisation failed, or the band could not be covered."""


class EigenResidualError(RuntimeError):
    """An eigenpair's relative residual is above ``residual_tol``."""


# --------------------------------------------------------------------------- helpers


def frequency_from_eigenvalue(eigenvalue):
    """Complex frequency of ``lam = omega**2``.

    Parameters
    ----------
    eigenvalue : complex or array_like
        ``lam`` (rad^2/s^2).

    Returns
    -------
    complex or numpy.ndarray
        ``f = sqrt(lam) / (2 pi)`` (Hz), principal root (``Re f >= 0``).  A
        negative real ``lam`` gives ``f = +i sqrt(-lam) / (2 pi)``.
    """
    lam = np.asarray(eigenvalue, dtype=complex)
    # ``imag + 0.0`` turns a signed zero (-0.0) into +0.0, so a negative real
    # lam lands on the +i side of the branch cut.
    lam = lam.real + 1j * (lam.imag + 0.0)
    return np.sqrt(lam) / TWO_PI


def eigenvalue_from_frequency(frequency_hz):
    """``lam = (2 pi f)**2`` (rad^2/s^2) of a (complex) frequency ``f`` (Hz)."""
    return (TWO_PI * np.asarray(frequency_hz)) ** 2


def matrix_norm_estimate(matrix) -> float:
    """Cheap upper bound of the spectral norm: ``sqrt(||M||_1 ||M||_inf)``.

    Equals the 1-norm for a symmetric/Hermitian matrix.  Used to scale the
    eigenpair residuals (see :func:`relative_residuals`).
    """
    magnitude = abs(sp.csr_matrix(matrix))
    one_norm = float(magnitude.sum(axis=0).max()) if magnitude.nnz else 0.0
    inf_norm = float(magnitude.sum(axis=1).max()) if magnitude.nnz else 0.0
    return math.sqrt(one_norm * inf_norm)


def relative_residuals(A, B, eigenvalues, vectors) -> np.ndarray:
    """Relative residual of each eigenpair, ``||A x - lam B x||_2 / (||A|| ||x||_2)``.

    ``||A||`` is :func:`matrix_norm_estimate` (``sqrt(||A||_1 ||A||_inf)``, an
    upper bound of the spectral norm, the 1-norm for symmetric ``A``).

    Parameters
    ----------
    A, B : scipy.sparse matrix, shape (n, n)
    eigenvalues : array_like, shape (k,)
        ``lam`` (rad^2/s^2).
    vectors : numpy.ndarray, shape (n, k)

    Returns
    -------
    numpy.ndarray, shape (k,)
        Dimensionless residuals.
    """
    vectors = np.asarray(vectors)
    if vectors.ndim == 1:
        vectors = vectors[:, None]
    eigenvalues = np.atleast_1d(np.asarray(eigenvalues))
    if vectors.shape[1] == 0:
        return np.zeros(0)
    scale = matrix_norm_estimate(A)
    if scale == 0.0:  # A = 0: fall back to the B term so the ratio stays meaningful
        scale = matrix_norm_estimate(B) * float(np.max(np.abs(eigenvalues)) or 1.0)
    lam = eigenvalues
    if not np.iscomplexobj(vectors) and np.all(np.imag(eigenvalues) == 0):
        lam = np.real(eigenvalues)  # keep a real pencil's residual in real arithmetic
    residual = A @ vectors - (B @ vectors) * lam[None, :]
    return np.linalg.norm(residual, axis=0) / (scale * np.linalg.norm(vectors, axis=0))


def is_hermitian(matrix, relative_tolerance: float = 1e-12) -> bool:
    """Whether ``max|M - M^H| <= relative_tolerance * max|M|``.

    The default 1e-12 is far above the round-off of an assembled symmetric
    FE matrix or of ``P^T K P`` reductions (a few ulp, ~1e-15 relative) and
    far below any genuine asymmetry (the u-p coupling blocks are O(1)).
    """
    matrix = sp.csr_matrix(matrix)
    largest = float(abs(matrix).max()) if matrix.nnz else 0.0
    difference = (matrix - matrix.conj().T).tocsr()
    if difference.nnz == 0:
        return True
    return float(abs(difference).max()) <= relative_tolerance * largest


# --------------------------------------------------------------------------- factorisation


@functools.lru_cache(maxsize=None)
def backend_available(backend: str) -> bool:
    """Whether ``backend`` (one of :data:`BACKENDS`) can factorise on this machine.

    ``"pardiso"`` needs Intel MKL (``pip install mkl``); it is probed by
    factorising a 1x1 matrix once (result cached).
    """
    _check_backend_name(backend)
    if backend == "superlu":
        return True
    try:
        from ngsolve import la
    except ImportError:
        return False
    if backend == "umfpack":
        return True
    probe = la.SparseMatrixd.CreateFromCOO(
        np.zeros(1, np.int32), np.zeros(1, np.int32), np.ones(1), 1, 1
    )
    try:
        probe.Inverse(inverse=backend)
    except Exception:  # NGSolve raises RuntimeError("MKL Pardiso is not available ...")
        return False
    return True


def available_backends() -> tuple[str, ...]:
    """The entries of :data:`BACKENDS` that work here, in that order."""
    return tuple(name for name in BACKENDS if backend_available(name))


def _check_backend_name(backend) -> None:
    if backend not in BACKENDS:
        raise EigenInputError(
            f"backend={backend!r} is not a known factorisation back-end; "
            f"allowed: {', '.join(map(repr, BACKENDS))}"
        )


def _require_backend(backend) -> None:
    _check_backend_name(backend)
    if not backend_available(backend):
        if backend == "pardiso":
            raise BackendUnavailableError(
                "backend='pardiso' needs Intel MKL, which is not installed: run "
                "`pip install mkl` (or `pip install copdea-fem[pardiso]`), or choose "
                "backend='umfpack' or backend='superlu'"
            )
        raise BackendUnavailableError(
            f"backend={backend!r} needs NGSolve (`pip install ngsolve`), which is not "
            "importable; choose backend='superlu'"
        )


def _real_equivalent(matrix: sp.csr_matrix) -> sp.csr_matrix:
    """Real 2n x 2n form of a complex matrix, unknowns interleaved (Re x0, Im x0, Re x1, ...).

    Entry ``a + ib`` becomes the block ``[[a, -b], [b, a]]``, so that
    ``[[a, -b], [b, a]] [Re x, Im x] = [Re(s x), Im(s x)]``.  Interleaving
    keeps each complex entry a dense 2x2 block, which lets the fill-reducing
    ordering treat the pair like one node.
    """
    real_part = sp.csr_matrix((matrix.data.real, matrix.indices, matrix.indptr), shape=matrix.shape)
    imag_part = sp.csr_matrix((matrix.data.imag, matrix.indices, matrix.indptr), shape=matrix.shape)
    identity_block = sp.csr_matrix(np.eye(2))
    rotation_block = sp.csr_matrix(np.array([[0.0, -1.0], [1.0, 0.0]]))
    return (sp.kron(real_part, identity_block) + sp.kron(imag_part, rotation_block)).tocsr()


#: SuperLU's diagonal pivot threshold in nested-dissection order: a diagonal
#: entry at least this share of its column's largest is kept as the pivot.
#: Coupled sector pencil (13.5k unknowns, sigma inside the band): 0 -> nnz(LU)
#: 4.1 M, solve 0.018 s; 0.01 -> 5.4 M, 0.021 s; 0.1 -> 5.7 M, 0.020 s; SuperLU's
#: own MMD_AT_PLUS_A order at 0.1: 6.1 M, 0.051 s; UMFPACK 0.055 s.
SUPERLU_PIVOT_THRESHOLD = 0.1
#: Below this size the METIS call costs more than the fill it saves (a 2-D FE-like
#: pattern of 1600 unknowns: factorisation + 20 solves 0.019 s in METIS order,
#: 0.013 s in SuperLU's own; the 3-D pencils here are 9k-14k).  Small matrices take
#: SuperLU's MMD_AT_PLUS_A order with the same diagonal pivoting: a coupled meridian
#: pencil of order m = 2 (1005 unknowns) factorises in 0.005 s instead of 0.094 s with
#: SuperLU's default partial pivoting (nnz(LU) 40k instead of 464k), solves in
#: 0.24 ms instead of 1.6 ms.
NESTED_DISSECTION_MIN = 2000


def fill_reducing_order(matrix) -> np.ndarray | None:
    """METIS nested-dissection permutation of a structurally symmetric matrix (pymetis).

    ``None`` when pymetis is missing or the matrix is small: the caller uses
    SuperLU's minimum-degree ordering then.  3-D FE matrices fill far less in
    nested-dissection order (George 1973): the LU has 1.5x fewer entries and
    solves 2.5x faster than with minimum degree (numbers at
    :data:`SUPERLU_PIVOT_THRESHOLD`).
    """
    if matrix.shape[0] < NESTED_DISSECTION_MIN:
        return None
    if importlib.util.find_spec("pymetis") is None:
        return None
    matrix = sp.csr_matrix(matrix)
    matrix.sort_indices()
    key = (matrix.shape, hashlib.sha1(matrix.indptr.tobytes()).hexdigest(),
           hashlib.sha1(matrix.indices.tobytes()).hexdigest())
    if key not in _ORDERINGS:            # every shift of a pencil has the same pattern
        if len(_ORDERINGS) >= 16:
            _ORDERINGS.pop(next(iter(_ORDERINGS)))
        _ORDERINGS[key] = _nested_dissection(matrix)
    return _ORDERINGS[key]


_ORDERINGS: dict = {}     # sparsity pattern -> METIS permutation (this process)


def _nested_dissection(matrix) -> np.ndarray:
    import pymetis

    pattern = sp.csr_matrix(matrix, copy=True)
    pattern.data = np.ones_like(pattern.data, dtype=float)
    graph = (pattern + pattern.T).tocsr()
    graph.setdiag(0)
    graph.eliminate_zeros()
    if hasattr(pymetis, "CSRAdjacency"):
        ordering = pymetis.nested_dissection(pymetis.CSRAdjacency(graph.indptr, graph.indices))
    else:
        ordering = pymetis.nested_dissection(xadj=graph.indptr, adjncy=graph.indices)
    permutation = ordering[0]       # (perm, iperm): row perm[k] of the matrix goes k-th
    return np.asarray(permutation, dtype=np.int64)


class Factorization:
    """Sparse LU factorisation of one square matrix, reusable for many right-hand sides.

    Parameters
    ----------
    matrix : scipy.sparse matrix or numpy.ndarray, shape (n, n)
        Real or complex; any sparse format (converted to CSR/CSC).
    backend : {"umfpack", "pardiso", "superlu"}
        ``"umfpack"`` / ``"pardiso"``: NGSolve ``SparseMatrixd.Inverse``
        (complex matrices in their real-equivalent 2n x 2n form, see the
        module notes); ``"superlu"``: :func:`scipy.sparse.linalg.splu` on the
        matrix permuted to METIS nested-dissection order (:func:`fill_reducing_order`),
        with threshold pivoting that prefers the diagonal.

    Attributes
    ----------
    backend : str
    shape : tuple of int
    dtype : numpy.dtype
        ``float64`` or ``complex128``, the matrix's.
    factorisation_seconds : float
        Wall time of the factorisation (s), including the conversion to the
        back-end's matrix type.
    solve_count : int
        Number of single right-hand-side solves done so far (a complex
        right-hand side against a real matrix counts two).

    Raises
    ------
    EigenInputError
        Unknown back-end or non-square matrix.
    BackendUnavailableError
        ``"pardiso"`` without MKL.
    EigenSolverError
        The matrix is (numerically) singular.
    """

    def __init__(self, matrix, backend: str = "umfpack"):
        _require_backend(backend)
        matrix = sp.csr_matrix(matrix)
        if matrix.shape[0] != matrix.shape[1]:
            raise EigenInputError(f"matrix must be square; got shape {matrix.shape}")
        self.backend = backend
        self.shape = matrix.shape
        self.is_complex = bool(np.iscomplexobj(matrix.data))
        self.dtype = np.dtype(complex if self.is_complex else float)
        if not self.is_complex:
            matrix = matrix.astype(float)
        self.solve_count = 0
        start = time.perf_counter()
        try:
            if backend == "superlu":
                self._order = fill_reducing_order(matrix)
                if self._order is None:     # small: minimum degree, the same diagonal pivoting
                    self._superlu = spla.splu(matrix.tocsc(), permc_spec="MMD_AT_PLUS_A",
                                              diag_pivot_thresh=SUPERLU_PIVOT_THRESHOLD,
                                              options={"SymmetricMode": True})
                else:
                    permuted = matrix[self._order][:, self._order].tocsc()
                    self._superlu = spla.splu(permuted, permc_spec="NATURAL",
                                              diag_pivot_thresh=SUPERLU_PIVOT_THRESHOLD,
                                              options={"SymmetricMode": True})
            else:
                self._factorise_ngsolve(matrix)
        except Exception as error:  # NGSolve's NgException derives from Exception only
            raise EigenSolverError(
                f"{backend} could not factorise the {self.shape[0]}x{self.shape[1]} matrix "
                f"(singular?): {error}"
            ) from error
        self.factorisation_seconds = time.perf_counter() - start

    def _factorise_ngsolve(self, matrix: sp.csr_matrix) -> None:
        from ngsolve import la

        real_matrix = _real_equivalent(matrix) if self.is_complex else matrix
        coo = real_matrix.tocoo()
        size = real_matrix.shape[0]
        ngsolve_matrix = la.SparseMatrixd.CreateFromCOO(
            np.ascontiguousarray(coo.row, dtype=np.int32),
            np.ascontiguousarray(coo.col, dtype=np.int32),
            np.ascontiguousarray(coo.data, dtype=np.float64),
            size,
            size,
        )
        self._ngsolve_matrix = ngsolve_matrix  # the inverse may refer to it
        self._ngsolve_inverse = ngsolve_matrix.Inverse(inverse=self.backend)
        self._ngsolve_rhs = ngsolve_matrix.CreateColVector()
        self._ngsolve_solution = ngsolve_matrix.CreateColVector()

    def _solve_real_layout(self, rhs: np.ndarray) -> np.ndarray:
        """One solve with the back-end's own (real for NGSolve) matrix; rhs 1-D."""
        self.solve_count += 1
        if self.backend == "superlu":
            if self._order is None:
                return self._superlu.solve(rhs)
            solution = np.empty_like(rhs)
            solution[self._order] = self._superlu.solve(rhs[self._order])
            return solution
        self._ngsolve_rhs.FV().NumPy()[:] = rhs
        self._ngsolve_inverse.Mult(self._ngsolve_rhs, self._ngsolve_solution)
        return np.array(self._ngsolve_solution.FV().NumPy())

    def _solve_vector(self, rhs: np.ndarray) -> np.ndarray:
        rhs_is_complex = np.iscomplexobj(rhs)
        if self.backend == "superlu":
            if self.is_complex:
                return self._solve_real_layout(rhs.astype(complex))
            if rhs_is_complex:
                return self._solve_real_layout(rhs.real.copy()) + 1j * self._solve_real_layout(
                    rhs.imag.copy()
                )
            return self._solve_real_layout(rhs.astype(float))
        if self.is_complex:
            interleaved = np.empty(2 * rhs.shape[0])
            interleaved[0::2] = rhs.real
            interleaved[1::2] = rhs.imag if rhs_is_complex else 0.0
            solution = self._solve_real_layout(interleaved)
            return solution[0::2] + 1j * solution[1::2]
        if rhs_is_complex:
            return self._solve_real_layout(rhs.real) + 1j * self._solve_real_layout(rhs.imag)
        return self._solve_real_layout(rhs)

    def solve(self, rhs) -> np.ndarray:
        """Solve ``matrix @ x = rhs``.

        Parameters
        ----------
        rhs : array_like, shape (n,) or (n, m)
            Real or complex.

        Returns
        -------
        numpy.ndarray
            Same shape as ``rhs``; complex if the matrix or ``rhs`` is.
        """
        rhs = np.asarray(rhs)
        if rhs.shape[0] != self.shape[0] or rhs.ndim > 2:
            raise EigenInputError(
                f"rhs must have shape ({self.shape[0]},) or ({self.shape[0]}, m); got {rhs.shape}"
            )
        if rhs.ndim == 1:
            return self._solve_vector(rhs)
        columns = [self._solve_vector(rhs[:, j]) for j in range(rhs.shape[1])]
        if not columns:
            return np.zeros(rhs.shape, dtype=np.result_type(rhs.dtype, self.dtype))
        return np.stack(columns, axis=1)

    def as_linear_operator(self, dtype=None) -> spla.LinearOperator:
        """``x -> matrix^{-1} x`` as a :class:`scipy.sparse.linalg.LinearOperator`."""
        dtype = np.dtype(dtype) if dtype is not None else self.dtype
        return spla.LinearOperator(self.shape, matvec=self.solve, matmat=self.solve, dtype=dtype)


# --------------------------------------------------------------------------- result


class NativeShiftedInverse:
    """Complex factorisation of the scaled ``A - sigma B`` on a sector's free DOFs, in NGSolve.

    (A_s - sigma B_s)^-1 = D_r^-1 (A - sigma B)^-1 D_l^-1 for the row/column
    scalings D_l, D_r.  NGSolve factorises the complex matrix natively with
    ``backend`` (``"umfpack"`` or ``"pardiso"``, study key ``eigen.backend``);
    :class:`Factorization` would hand it the twice-as-large real form.
    ``"superlu"`` takes that class (SciPy factorises complex).  The coupled 3-D
    pencil's ``factorize`` hook (:meth:`copdea_fem.coupled.CoupledAssembly.restrict`).
    """

    def __init__(self, stiffness, mass, free_mask, sigma, row_scale, column_scale,
                 backend="umfpack"):
        from .symmetry import bitarray

        start = time.perf_counter()
        shifted = stiffness.CreateMatrix()
        shifted.AsVector().data = stiffness.AsVector() - float(sigma) * mass.AsVector()
        try:
            self._inverse = shifted.Inverse(bitarray(free_mask), inverse=backend)
        except Exception as error:  # NGSolve's NgException derives from Exception only
            raise EigenSolverError(f"{backend} could not factorise A - sigma B at sigma = "
                                   f"{sigma:.6g} rad^2/s^2 (singular?): {error}") from error
        self._matrix = shifted
        self._rhs = shifted.CreateColVector()
        self._solution = shifted.CreateColVector()
        self._free = np.flatnonzero(free_mask)
        self._rows, self._columns = row_scale, column_scale
        self.dtype = np.dtype(complex)
        self.is_complex = True
        self.solve_count = 0
        self.factorisation_seconds = time.perf_counter() - start

    def _solve_vector(self, rhs):
        self.solve_count += 1
        values = self._rhs.FV().NumPy()
        values[:] = 0
        values[self._free] = rhs / self._rows
        self._solution.data = self._inverse * self._rhs
        return self._solution.FV().NumPy()[self._free] / self._columns

    def solve(self, rhs):
        rhs = np.asarray(rhs)
        if rhs.ndim == 1:
            return self._solve_vector(rhs)
        return np.stack([self._solve_vector(rhs[:, j]) for j in range(rhs.shape[1])], axis=1)


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
        Wall time in ARPACK, including its solves (s).
    total_seconds : float
        Wall time of the whole call (s).
    n_factorisations : int
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


# --------------------------------------------------------------------------- band geometry


@dataclass
class SectorBandResults:
    """The :class:`BandResult` of each symmetry sector of one solve (:mod:`copdea_fem.symmetry`),
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
    factorisation_seconds, iteration_seconds, total_seconds = map(
        _summed, ("factorisation_seconds", "iteration_seconds", "total_seconds"))
    del _joined, _summed


class _BandRegion:
    """The band as a compact region of the lam-plane, with a sampled cover test.

    In the frequency plane the band is the rectangle ``[f_lo, f_hi] x
    [-h, h]`` (``Re f`` x ``Im f``, Hz), enlarged by ``margin_hz``.  Its image
    under ``lam = (2 pi f)^2`` is what the shifts' discs must cover.  For a
    Hermitian pencil only the real axis matters: the segment
    ``[(2 pi f_lo)^2, (2 pi f_hi)^2]``, extended down to ``-(2 pi h)^2`` when
    ``f_min = 0`` (unstable modes, ``Re f = 0``).

    The region is sampled by cells; each cell is stored as the lam of its
    centre and a radius ``slack`` that bounds the distance from the centre to
    any lam of the cell (``|dlam/df| = 2 (2 pi)^2 |f|``), so "centre + slack
    inside an open disc" proves the whole cell is inside.
    """

    SEGMENT_CELLS = 4000  # 1-D: cell width (lam_hi - lam_lo) / 4000
    GRID_CELLS_RE = 240   # 2-D: cells along Re f
    GRID_CELLS_IM = 60    # 2-D: cells along Im f (both signs)

    def __init__(self, f_min, f_max, imag_max_hz, margin_hz, hermitian):
        self.hermitian = hermitian
        f_lo = max(f_min - margin_hz, 0.0)
        f_hi = f_max + margin_hz
        h = imag_max_hz + margin_hz
        if hermitian:
            lam_lo = (TWO_PI * f_lo) ** 2 if f_min > 0 else -((TWO_PI * h) ** 2)
            lam_hi = (TWO_PI * f_hi) ** 2
            edges = np.linspace(lam_lo, lam_hi, self.SEGMENT_CELLS + 1)
            self.centres = 0.5 * (edges[1:] + edges[:-1]) + 0j
            self.slack = np.full(self.centres.shape, 0.5 * (edges[1] - edges[0]))
        else:
            re_edges = np.linspace(f_lo, f_hi, self.GRID_CELLS_RE + 1)
            im_count = self.GRID_CELLS_IM if h > 0 else 1
            im_edges = np.linspace(-h, h, im_count + 1) if h > 0 else np.array([0.0, 0.0])
            re_c = 0.5 * (re_edges[1:] + re_edges[:-1])
            im_c = 0.5 * (im_edges[1:] + im_edges[:-1])
            f_centre = (re_c[:, None] + 1j * im_c[None, :]).ravel()
            half_diagonal = 0.5 * math.hypot(re_edges[1] - re_edges[0], im_edges[1] - im_edges[0])
            self.centres = (TWO_PI * f_centre) ** 2
            # |lam(f) - lam(fc)| = (2 pi)^2 |f - fc| |f + fc| <= (2 pi)^2 d (2|fc| + d)
            self.slack = TWO_PI**2 * half_diagonal * (2.0 * np.abs(f_centre) + half_diagonal)
        self.real_extent = (float(self.centres.real.min() - self.slack.max()),
                            float(self.centres.real.max() + self.slack.max()))
        self.scale = max(abs(self.real_extent[0]), abs(self.real_extent[1]),
                         float(np.max(np.abs(self.centres))))

    def uncovered(self, shifts: np.ndarray, radii: np.ndarray) -> np.ndarray:
        """Shortfall of every cell: ``min_j (|c - sigma_j| + slack - r_j)``; > 0 = not covered."""
        if shifts.size == 0:
            return np.full(self.centres.shape, np.inf)
        distance = np.abs(self.centres[:, None] - shifts[None, :]) + self.slack[:, None]
        with np.errstate(invalid="ignore"):
            shortfall = distance - radii[None, :]
        shortfall[:, np.isinf(radii)] = -np.inf
        return shortfall.min(axis=1)

    def first_shift(self) -> float:
        """Real shift nearest the farthest point of the region (Chebyshev centre on the axis)."""
        lo, hi = self.real_extent

        def farthest(sigma):
            return float(np.max(np.abs(self.centres - sigma) + self.slack))

        for _ in range(100):  # ternary search on a convex function; 100 steps shrink by 1e-17
            third = (hi - lo) / 3.0
            if third <= 1e-12 * self.scale:
                break
            if farthest(lo + third) <= farthest(hi - third):
                hi = hi - third
            else:
                lo = lo + third
        return 0.5 * (lo + hi)


# --------------------------------------------------------------------------- solver state


@dataclass(eq=False)
class _Shift:
    sigma: float
    factorization: Factorization
    trusted_radius: float = 0.0      # |lam - sigma| of the farthest pair of the latest run
    confirmed_radius: float = 0.0    # |lam - sigma| of the nearest *new* pair of the latest run
    modes_found: int = 0             # pairs added by runs at this shift
    runs: int = 0


@dataclass
class _KnownPairs:
    """Eigenpairs found so far (de-duplicated), the deflation set."""

    n: int
    dtype: np.dtype
    values: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))
    vectors: np.ndarray = None

    def __post_init__(self):
        if self.vectors is None:
            self.vectors = np.zeros((self.n, 0), dtype=self.dtype)

    @property
    def count(self) -> int:
        return int(self.values.shape[0])


class _BandSolver:
    """Bookkeeping of one :func:`solve_band` call (see its docstring for the strategy)."""

    START_MODES = 20           # k of the first run at a new shift
    CERTIFY_MODES = 2          # k of a certification run (only the dominant is used)
    CERTIFY_TOL = 1e-8         # ARPACK tol of a certification run
    CERTIFY_MARGIN = 1e-4      # certified radius = (1 - margin) * nearest unknown distance
    EXTEND_RATIO = 2.5         # extend a shift (reuse its LU) if the gap is within 2.5 radii
    NEW_SHIFT_OVERLAP = 0.75   # a new shift sits 0.75 radii beyond the frontier
    MAX_SHIFTS = 60
    MAX_RUNS = 400
    DENSE_DOFS = 64            # below this, a dense QZ is cheaper and exact
    DENSE_MAX_DOFS = 4000      # dense QZ beyond this costs minutes (n^3 ~ 1e11 flops)
    # Duplicate directions: normalised vectors whose Gram matrix has an
    # eigenvalue below 1e-6 of its largest are treated as one (an angle below
    # ~1e-3 rad).  Eigenvector errors at converged tolerances are ~residual/gap
    # (<< 1e-3) while distinct eigenvectors of a Hermitian pencil are
    # B-orthogonal (angle pi/2).
    DUPLICATE_GRAM_RATIO = 1e-6
    # Eigenvalues closer than 1e-6 (relative) are grouped and Rayleigh-Ritz'ed
    # together; grouping too much is harmless (Ritz separates them), grouping
    # too little could keep a duplicate.
    CLUSTER_RELATIVE = 1e-6

    def __init__(self, A, B, region, backend, hermitian, max_modes, max_modes_per_shift,
                 band_contains, arpack_tol, progress, initial_shifts=None, start_modes=None):
        self.A = A
        self.start_modes = int(start_modes) if start_modes else self.START_MODES
        self.initial_shifts = list(initial_shifts or [])
        self.B = B
        self.n = A.shape[0]
        self.region = region
        self.backend = backend
        self.hermitian = hermitian
        complex_pencil = np.iscomplexobj(A.data) or np.iscomplexobj(B.data)
        self.real_arithmetic = hermitian and not complex_pencil
        self.max_modes = max_modes
        self.max_modes_per_shift = max_modes_per_shift
        self.band_contains = band_contains
        self.arpack_tol = arpack_tol
        self.progress = progress or (lambda message: None)
        dtype = np.dtype(float) if self.real_arithmetic else np.dtype(complex)
        self.known = _KnownPairs(self.n, dtype)
        self.shifts: list[_Shift] = []
        self.factorisation_seconds = 0.0
        self.iteration_seconds = 0.0
        self.runs = 0
        self.exhaustive = False
        rng = np.random.default_rng(20240611)  # fixed seed: deterministic ARPACK start
        start = rng.standard_normal(self.n)
        if dtype.kind == "c":
            start = start + 1j * rng.standard_normal(self.n)
        self.start_vector = start

    # ---------------------------------------------------------------- shifts

    def add_shift(self, sigma: float, radius_hint: float) -> _Shift:
        """Factorise ``A - sigma B`` at a real shift, nudged off known eigenvalues / singularity."""
        scale = radius_hint if np.isfinite(radius_hint) and radius_hint > 0 else self.region.scale
        last_error = None
        for attempt in range(4):
            # Deflation divides by (lam_known - sigma): keep sigma at least 1e-6
            # radii away from any known eigenvalue (relative cancellation error
            # eps * radius / distance stays below 1e-10).
            while self.known.count and np.min(np.abs(self.known.values - sigma)) < 1e-6 * scale:
                sigma += 1e-5 * scale
            sigma = float(sigma)  # plain Python float (see module notes)
            start = time.perf_counter()
            try:
                if getattr(self, "factorize", None) is not None:
                    factorization = self.factorize(sigma)
                else:
                    factorization = Factorization((self.A - sigma * self.B).tocsr(), self.backend)
                self._check_factorization(factorization)
            except EigenSolverError as error:
                self.factorisation_seconds += time.perf_counter() - start
                self.progress(f"shift at {_format_hz(sigma)} is singular ({error}); moving it")
                sigma += 1e-4 * scale * 10.0**attempt
                last_error = error
                continue
            self.factorisation_seconds += time.perf_counter() - start
            shift = _Shift(sigma, factorization)
            self.shifts.append(shift)
            self.progress(
                f"shift {len(self.shifts)} at {_format_hz(sigma)}: factorised n={self.n} "
                f"with {self.backend} in {factorization.factorisation_seconds:.3g} s"
            )
            return shift
        raise EigenSolverError(
            f"A - sigma B stays singular near sigma = {sigma:.6g} rad^2/s^2 ({_format_hz(sigma)}) "
            f"after 4 nudges: is the pencil singular (a DOF with zero rows in both A and B)? "
            f"last error: {last_error}"
        )

    def _check_factorization(self, factorization: Factorization) -> None:
        """UMFPACK/SuperLU raise on an exactly singular matrix; catch a silent inf/nan too."""
        probe = self.start_vector.real
        solution = factorization.solve(probe)
        if not np.all(np.isfinite(solution)):
            raise EigenSolverError("the solve returned non-finite values")

    # ---------------------------------------------------------------- ARPACK runs

    def run(self, shift: _Shift, k: int) -> int:
        """Find the ``k`` unknown eigenpairs nearest ``shift.sigma``; return how many were added."""
        if self.n <= self.DENSE_DOFS or self.known.count + k >= self.n // 3:
            # ARPACK needs k < n - 1 and works badly when the deflated operator
            # is mostly null; a problem this small is cheaper dense.
            if self.n > self.DENSE_MAX_DOFS:
                raise EigenSolverError(
                    f"{self.known.count + k} eigenpairs requested of an n={self.n} pencil: "
                    "too many for ARPACK and too large for a dense solve; narrow the band"
                )
            self.solve_dense()
            return 0
        self.runs += 1
        shift.runs += 1
        sigma = shift.sigma
        start = time.perf_counter()
        solves_before = shift.factorization.solve_count
        values, vectors, exhausted = self._arpack(shift, k)
        run_seconds = time.perf_counter() - start
        self.iteration_seconds += run_seconds
        solves = shift.factorization.solve_count - solves_before
        distance = np.abs(values - sigma)
        order = np.argsort(distance, kind="stable")
        values, vectors, distance = values[order], vectors[:, order], distance[order]
        # Certified: nothing unknown was nearer than d_1 (shrunk by 1e-6 for the
        # Ritz value's error, ~tol times the eigenvalue's condition number).
        shift.confirmed_radius = float(distance[0]) * (1.0 - 1e-6) if distance.size else math.inf
        # "exhausted": ARPACK's set ran into the deflated (nu ~ 0) directions,
        # so no finite eigenvalue is left unknown.
        shift.trusted_radius = math.inf if exhausted or not distance.size else float(distance[-1])
        shift.modes_found += int(values.size)
        self._add(values, vectors)
        in_band = int(np.count_nonzero(self.band_contains(self.known.values)))
        self.progress(
            f"shift {self.shifts.index(shift) + 1} at {_format_hz(sigma)}: {values.size} new modes "
            f"(k={k}, {solves} solves, {run_seconds:.3g} s), {self.known.count} known, "
            f"{in_band} in band; radius {_format_radius(sigma, shift.trusted_radius)}"
        )
        if in_band > self.max_modes:
            raise TooManyModesError(
                f"the band holds more than max_modes={self.max_modes} eigenpairs "
                f"({in_band} found so far); raise max_modes or narrow the band"
            )
        return int(values.size)

    def certify(self, shift: _Shift) -> None:
        """Nearest eigenvalue still unknown at ``shift``: sets its certified radius.

        Only the dominant eigenvalue of the deflated operator is needed and
        nothing is stored, so two Ritz values at ``CERTIFY_TOL`` suffice.  The
        radius is shrunk by ``CERTIFY_MARGIN`` to absorb the Ritz value's
        error (relative ~tol for Hermitian pencils, ~condition * tol otherwise:
        the margin covers condition numbers up to 1e4).  A nearer unknown
        eigenvalue than the trusted radius (a missed multiple eigenvalue)
        shrinks the trusted radius too, so the planner extends this shift.
        """
        if self.n <= self.DENSE_DOFS or self.known.count + self.CERTIFY_MODES >= self.n // 3:
            self.run(shift, self.CERTIFY_MODES)
            return
        self.runs += 1
        start = time.perf_counter()
        solves_before = shift.factorization.solve_count
        values, _, exhausted = self._arpack(shift, self.CERTIFY_MODES, tol=self.CERTIFY_TOL)
        run_seconds = time.perf_counter() - start
        self.iteration_seconds += run_seconds
        distance = np.abs(values - shift.sigma)
        nearest = float(distance.min()) if distance.size else math.inf
        previous = shift.trusted_radius
        shift.confirmed_radius = nearest * (1.0 - self.CERTIFY_MARGIN)
        if shift.confirmed_radius < previous:
            shift.trusted_radius = shift.confirmed_radius
            self.progress(
                f"shift {self.shifts.index(shift) + 1}: an unknown eigenvalue lies inside the "
                f"trusted radius (a missed multiple eigenvalue); extending"
            )
        self.progress(
            f"shift {self.shifts.index(shift) + 1} at {_format_hz(shift.sigma)}: certified radius "
            f"{_format_radius(shift.sigma, shift.confirmed_radius)} "
            f"({shift.factorization.solve_count - solves_before} solves, {run_seconds:.3g} s)"
        )

    def _deflation(self, sigma):
        """Known vectors X, nu_i = 1/(lam_i - sigma) and Z with Z X = I (Wielandt deflation)."""
        X = self.known.vectors
        nu = 1.0 / (self.known.values - sigma)
        if self.hermitian:
            nu = nu.real
            Z = (self.B @ X).conj().T  # X is B-orthonormal: Z X = X^H B X = I
        else:
            gram = X.conj().T @ X
            Z = np.linalg.solve(gram, X.conj().T)
        return X, nu, Z

    def _reporting(self, shift: _Shift, solve):
        """``solve`` that says every PROGRESS_INTERVAL_S how many solves a run has done."""
        start = last = time.perf_counter()
        count = 0

        def counted(rhs):
            nonlocal last, count
            count += 1
            now = time.perf_counter()
            if now - last >= PROGRESS_INTERVAL_S:
                last = now
                self.progress(f"shift {self.shifts.index(shift) + 1} at "
                              f"{_format_hz(shift.sigma)}: {count} solves, "
                              f"{now - start:.0f} s ...")
            return solve(rhs)

        return counted

    def _arpack(self, shift: _Shift, k: int, tol: float | None = None):
        """ARPACK on the operator deflated by all known pairs: (values, vectors, exhausted)."""
        tol = self.arpack_tol if tol is None else tol
        sigma = shift.sigma
        n = self.n
        X, nu_known, Z = self._deflation(sigma)
        solve = self._reporting(shift, shift.factorization.solve)
        deflation_dtype = X.dtype if X.shape[1] else np.dtype(float)
        operator_dtype = np.result_type(deflation_dtype, shift.factorization.dtype, self.B.dtype)
        start_vector = self.start_vector if operator_dtype.kind == "c" else self.start_vector.real
        if self.hermitian:
            # eigsh, generalised shift-invert (ARPACK mode 3, B-inner product):
            # OP = OPinv B with OPinv = (A - sigma B)^-1 - X diag(nu) X^H, which is
            # Hermitian, so the deflated problem stays a Lanczos problem.  The
            # known pairs move to nu = 0 (lam = inf) and are never "largest".
            X_adjoint = np.ascontiguousarray(X.conj().T)  # formed once, not per product

            def deflated_inverse(y):
                y = np.asarray(y).ravel()
                return solve(y) - X @ (nu_known * (X_adjoint @ y)) if X.shape[1] else solve(y)

            inverse_operator = spla.LinearOperator((n, n), matvec=deflated_inverse,
                                                   dtype=operator_dtype)
            a_placeholder = spla.LinearOperator((n, n), matvec=lambda y: y, dtype=operator_dtype)
            ncv = min(n, max(2 * k + 1, k + 20))

            def call(ncv, maxiter):
                return spla.eigsh(
                    a_placeholder, k=k, M=self.B, sigma=sigma, which="LM", OPinv=inverse_operator,
                    v0=start_vector, ncv=ncv,
                    maxiter=maxiter, tol=tol,
                )
        else:
            # eigs, standard mode on OP = (A - sigma B)^-1 B - X diag(nu) Z:
            # no B-inner product (B may be complex non-Hermitian).  Wielandt:
            # with Z X = I the spectrum is {0 for known} U {unknown nu}.
            def deflated_operator(x):
                x = np.asarray(x).ravel()
                result = solve(self.B @ x)
                return result - X @ (nu_known * (Z @ x)) if X.shape[1] else result

            operator = spla.LinearOperator((n, n), matvec=deflated_operator, dtype=operator_dtype)
            ncv = min(n, max(2 * k + 1, k + 20))

            def call(ncv, maxiter):
                nu, W = spla.eigs(
                    operator, k=k, which="LM", v0=start_vector,
                    ncv=ncv, maxiter=maxiter, tol=tol,
                )
                with np.errstate(divide="ignore"):
                    return sigma + 1.0 / nu, W

        try:
            try:
                values, W = call(ncv, None)
            except spla.ArpackNoConvergence:
                values, W = call(min(n, 2 * ncv), 20 * n)
        except spla.ArpackNoConvergence as error:
            raise EigenSolverError(
                f"ARPACK did not converge at shift {_format_hz(sigma)} for k={k} "
                f"(ncv={min(n, 2 * ncv)}): {error}"
            ) from error
        values = np.asarray(values, dtype=complex)
        nu_new = 1.0 / (values - sigma)
        # Deflated directions come back with |nu| at round-off level (lam ~ inf);
        # they carry no information and are dropped.
        largest = np.max(np.abs(nu_new[np.isfinite(nu_new)]), initial=0.0)
        keep = np.isfinite(values) & (np.abs(nu_new) > 1e-10 * largest)
        exhausted = not np.all(keep)
        values, W, nu_new = values[keep], W[:, keep], nu_new[keep]
        if self.hermitian:
            values = values.real + 0j
        if X.shape[1] and not self.hermitian:
            # Wielandt back-transformation: OP x = nu x with x = w + X c,
            # (nu - nu_i) c_i = nu_i (Z w)_i.  For nu = nu_i (a degenerate
            # partner of a known pair) (Z w)_i vanishes and c_i is free: take 0.
            # (Hermitian: the deflated operator is B-self-adjoint, so w is
            # B-orthogonal to X and already an eigenvector of the pencil.)
            gap = nu_new[None, :] - nu_known[:, None]
            tiny = np.abs(gap) <= 1e-8 * np.abs(nu_new)[None, :]
            coefficients = (nu_known[:, None] * (Z @ W)) / np.where(tiny, 1.0, gap)
            coefficients[tiny] = 0.0
            W = W + X @ coefficients
        if self.real_arithmetic:
            W = W.real
        return values, W, exhausted

    # ---------------------------------------------------------------- dense fallback

    def solve_dense(self) -> None:
        """All finite eigenpairs by dense QZ / eigh: the problem is tiny."""
        start = time.perf_counter()
        a, b = self.A.toarray(), self.B.toarray()
        values = vectors = None
        if self.hermitian:
            try:
                values, vectors = scipy.linalg.eigh(a, b)
                values = values.astype(complex)
            except np.linalg.LinAlgError:  # B only semi-definite
                values = None
        if values is None:
            alpha_beta, vectors = scipy.linalg.eig(a, b, homogeneous_eigvals=True)
            alpha, beta = alpha_beta
            finite = np.abs(beta) > 1e-13 * np.abs(alpha)  # |lam| < 1e13 |alpha|/|alpha|: finite
            values = alpha[finite] / beta[finite]
            vectors = vectors[:, finite]
            if self.hermitian:
                values = values.real + 0j
        self.iteration_seconds += time.perf_counter() - start
        self.known = _KnownPairs(self.n, self.known.dtype)
        if self.real_arithmetic:
            if np.iscomplexobj(vectors):  # real and imaginary parts span the eigenspace
                vectors = np.concatenate([vectors.real, vectors.imag], axis=1)
                values = np.concatenate([values, values])
        self._add(values, vectors)
        self.exhaustive = True
        for shift in self.shifts:
            shift.trusted_radius = shift.confirmed_radius = math.inf
        self.progress(f"dense solve (n={self.n}): {self.known.count} finite eigenpairs")

    # ---------------------------------------------------------------- de-duplication

    def _add(self, values, vectors) -> None:
        """Append pairs, then Rayleigh-Ritz every cluster of close eigenvalues.

        Inside a cluster the stacked vectors are reduced to an orthonormal
        (B-orthonormal if Hermitian) basis of their span, dropping directions
        that are duplicates (Gram eigenvalue below ``DUPLICATE_GRAM_RATIO``), and
        the pencil is solved on that basis.  Degenerate partners (cos m theta /
        sin m theta) are independent directions and are both kept; a pair found
        twice spans one direction and is kept once.
        """
        values = np.asarray(values, dtype=complex)
        vectors = np.asarray(vectors)
        if vectors.ndim == 1:
            vectors = vectors[:, None]
        if self.real_arithmetic and np.iscomplexobj(vectors):
            vectors = vectors.real
        all_values = np.concatenate([self.known.values, values])
        vectors = vectors.astype(self.known.dtype, copy=False)
        all_vectors = np.concatenate([self.known.vectors, vectors], axis=1)
        clusters = self._clusters(all_values)
        new_values, new_vectors = [], []
        for members in clusters:
            if len(members) == 1:
                index = members[0]
                vector = all_vectors[:, index]
                norm = self._norm(vector[:, None])[0]
                new_values.append(all_values[index:index + 1])
                new_vectors.append((vector / norm)[:, None])
                continue
            ritz_values, ritz_vectors = self._ritz(all_vectors[:, members])
            new_values.append(ritz_values)
            new_vectors.append(ritz_vectors)
        self.known.values = np.concatenate(new_values) if new_values else np.zeros(0, complex)
        self.known.vectors = (np.concatenate(new_vectors, axis=1) if new_vectors
                              else np.zeros((self.n, 0), self.known.dtype))

    def _clusters(self, values: np.ndarray) -> list[list[int]]:
        """Groups of indices whose eigenvalues are within ``CLUSTER_RELATIVE`` (transitively)."""
        count = values.size
        parent = list(range(count))

        def root(i):
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        floor = 1e-6 * self.region.scale  # absolute floor so that lam ~ 0 still clusters
        order = np.argsort(values.real, kind="stable")
        for position, i in enumerate(order):
            for j in order[position + 1:]:
                tolerance = self.CLUSTER_RELATIVE * (max(abs(values[i]), abs(values[j])) + floor)
                if values[j].real - values[i].real > tolerance:
                    break
                if abs(values[j] - values[i]) <= tolerance:
                    parent[root(j)] = root(i)
        groups: dict[int, list[int]] = {}
        for i in range(count):
            groups.setdefault(root(i), []).append(i)
        return [sorted(members) for _, members in sorted(groups.items())]

    def _norm(self, vectors: np.ndarray) -> np.ndarray:
        if self.hermitian:
            return np.sqrt(np.abs(np.einsum("ij,ij->j", vectors.conj(), self.B @ vectors)))
        return np.linalg.norm(vectors, axis=0)

    def _ritz(self, vectors: np.ndarray):
        """Rayleigh-Ritz of the pencil on span(vectors), duplicates removed."""
        weighted = self.B @ vectors if self.hermitian else vectors
        gram = vectors.conj().T @ weighted
        gram = 0.5 * (gram + gram.conj().T)
        gram_values, gram_vectors = np.linalg.eigh(gram)
        keep = gram_values > self.DUPLICATE_GRAM_RATIO * gram_values[-1]
        basis = vectors @ (gram_vectors[:, keep] / np.sqrt(gram_values[keep]))
        projected_a = basis.conj().T @ (self.A @ basis)
        projected_b = basis.conj().T @ (self.B @ basis)
        if self.hermitian:
            projected_a = 0.5 * (projected_a + projected_a.conj().T)
            projected_b = 0.5 * (projected_b + projected_b.conj().T)
            ritz_values, coefficients = scipy.linalg.eigh(projected_a, projected_b)
            ritz_values = ritz_values.astype(complex)
        else:
            ritz_values, coefficients = scipy.linalg.eig(projected_a, projected_b)
        ritz_vectors = basis @ coefficients
        ritz_vectors = ritz_vectors / self._norm(ritz_vectors)[None, :]
        if self.real_arithmetic:
            ritz_vectors = ritz_vectors.real
        return ritz_values, ritz_vectors

    # ---------------------------------------------------------------- planning

    def covered(self, use_confirmed: bool) -> np.ndarray:
        sigmas = np.array([s.sigma for s in self.shifts], dtype=complex)
        radii = np.array([s.confirmed_radius if use_confirmed else s.trusted_radius
                          for s in self.shifts])
        return self.region.uncovered(sigmas, radii)

    def count_within(self, shift: _Shift, radius: float) -> int:
        return int(np.count_nonzero(np.abs(self.known.values - shift.sigma) < radius))

    def plan_next(self, shortfall: np.ndarray) -> None:
        """Extend a shift (more modes from its LU) or place a new one, toward the nearest gap."""
        uncovered = np.flatnonzero(shortfall > 0)
        frontier = uncovered[np.argmin(shortfall[uncovered])]
        point = self.region.centres[frontier]
        reach = np.array([abs(point - s.sigma) + self.region.slack[frontier] - s.trusted_radius
                          for s in self.shifts])
        nearest = self.shifts[int(np.argmin(reach))]
        distance = abs(point - nearest.sigma) + self.region.slack[frontier]
        radius = max(nearest.trusted_radius, 1e-300)
        room = self.max_modes_per_shift - nearest.modes_found
        tall = abs(point.imag) > 0.5 * radius  # a real shift beside it would not help
        if room > 0 and (distance <= self.EXTEND_RATIO * radius or tall):
            # Aim at every gap this shift can reach, not only the nearest cell.
            reach_all = (np.abs(self.region.centres[uncovered] - nearest.sigma)
                         + self.region.slack[uncovered])
            reachable = reach_all[reach_all <= self.EXTEND_RATIO * radius]
            if reachable.size:
                distance = max(distance, float(reachable.max()))
            # Count grows ~linearly with the radius for FE spectra (Weyl: a
            # membrane's eigenvalue density in lam is uniform, and damped
            # structural modes stay near the real axis).  Under-estimating only
            # costs another run: the pairs found are kept (deflation).
            inside = max(self.count_within(nearest, radius), 1)
            expected = inside * (distance / radius - 1.0)
            k = int(np.clip(math.ceil(1.25 * expected) + 4, 4, room))
            self.run(nearest, k)
            return
        # New shift: into the gap that holds the frontier cell, by 0.75 of the
        # neighbour's radius (similar density -> similar disc, overlapping by a
        # quarter) but no further than the middle of the gap.
        gap_low, gap_high = self._gap_extent(uncovered, frontier)
        lo, hi = self.region.real_extent
        direction = 1.0 if point.real >= nearest.sigma else -1.0
        step = 0.5 * (gap_high - gap_low)
        if np.isfinite(radius):
            step = min(step, self.NEW_SHIFT_OVERLAP * radius)
        sigma = float(np.clip(point.real + direction * step, lo, hi))
        duplicate = any(abs(s.sigma - sigma) <= 1e-12 * self.region.scale for s in self.shifts)
        if duplicate or len(self.shifts) >= self.MAX_SHIFTS:
            raise EigenSolverError(
                f"cannot cover the band near f = {_format_hz(point)}: {len(self.shifts)} shifts, "
                f"max_modes_per_shift={self.max_modes_per_shift} reached at the nearest one; "
                "raise max_modes_per_shift or lower max_imag_hz"
            )
        inside = self.count_within(nearest, radius)
        smallest = min(self.START_MODES, self.max_modes_per_shift)
        k = int(np.clip(inside, smallest, self.max_modes_per_shift))
        shift = self.add_shift(sigma, radius)
        self.run(shift, k)

    def _gap_extent(self, uncovered: np.ndarray, frontier: int) -> tuple[float, float]:
        """Real-axis extent of the run of uncovered cells that contains ``frontier``.

        Cells are chained along Re lam when their centres are closer than 2.5
        slack radii (neighbouring cells are at most 2 slack radii apart).
        """
        real_parts = self.region.centres[uncovered].real
        order = np.argsort(real_parts, kind="stable")
        sorted_real = real_parts[order]
        link = 2.5 * float(self.region.slack.max())
        breaks = np.flatnonzero(np.diff(sorted_real) > link)
        starts = np.concatenate([[0], breaks + 1])
        ends = np.concatenate([breaks, [sorted_real.size - 1]])
        position = int(np.flatnonzero(uncovered[order] == frontier)[0])
        run = int(np.searchsorted(starts, position, side="right") - 1)
        return float(sorted_real[starts[run]]), float(sorted_real[ends[run]])

    def confirm_one(self) -> None:
        missing = self.covered(use_confirmed=True) > 0
        best_shift, best_count = None, 0
        for shift in self.shifts:
            if shift.confirmed_radius >= shift.trusted_radius:
                continue
            distance = np.abs(self.region.centres - shift.sigma) + self.region.slack
            inside = distance < shift.trusted_radius
            count = int(np.count_nonzero(missing & inside))
            if count > best_count:
                best_shift, best_count = shift, count
        if best_shift is None:  # cannot happen while trusted covers and confirmed does not
            raise EigenSolverError("internal: no shift left to confirm the band cover")
        self.certify(best_shift)

    def solve(self) -> None:
        # --- sweep start plan (see solve_band's initial_shifts) ---
        plan = self.initial_shifts or [(self.region.first_shift(), self.start_modes)]
        for sigma, k in plan:
            if self.exhaustive:
                break
            shift = self.add_shift(float(sigma), self.region.scale)
            self.run(shift, int(min(k, self.max_modes_per_shift)))
        # --- end of sweep start plan ---
        while not self.exhaustive:
            if self.runs > self.MAX_RUNS:
                raise EigenSolverError(f"band not covered after {self.MAX_RUNS} ARPACK runs")
            if np.all(self.covered(use_confirmed=True) <= 0):
                return
            shortfall = self.covered(use_confirmed=False)
            if np.all(shortfall <= 0):
                # Covered if ARPACK found the k nearest at every shift.  Prove
                # it: at the unconfirmed shift whose trusted disc holds most of
                # what the certified discs miss, one more run gives the nearest
                # *unknown* eigenvalue, which must lie outside that disc.
                self.confirm_one()
                continue
            self.plan_next(shortfall)


def _format_hz(value) -> str:
    """``f = sqrt(lam)/(2 pi)`` of a lam-plane point, as text (Hz)."""
    f = complex(frequency_from_eigenvalue(value))
    if abs(f.imag) <= 1e-9 * abs(f):
        return f"{f.real:.6g} Hz"
    return f"{f.real:.6g}{f.imag:+.4g}i Hz"


def _format_radius(sigma, radius) -> str:
    if not np.isfinite(radius):
        return "inf"
    low = complex(frequency_from_eigenvalue(sigma - radius))
    high = complex(frequency_from_eigenvalue(sigma + radius))
    low_text = f"{low.real:.4g}" if abs(low.imag) <= abs(low.real) else f"{low.imag:.4g}i"
    return f"{radius:.4g} rad^2/s^2 (real axis {low_text}..{high.real:.4g} Hz)"


# --------------------------------------------------------------------------- public solver


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
    progress: Callable[[str], None] | None = None,
    check: bool = True,
    max_imag_hz: float | None = None,
    normalization_matrix=None,
    max_modes_per_shift: int = 80,
    initial_shifts=None,
    factorize: Callable[[float], "Factorization"] | None = None,
    start_modes: int | None = None,
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
    progress : callable(str) or None
        Receives one line per factorisation and per ARPACK run.
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
        placed (ARPACK keeps ``2 k + 1`` vectors of length ``n``).
    initial_shifts : sequence of (float, int), optional
        ``(sigma, k)`` pairs (``sigma`` real, rad^2/s^2; ``k >= 1`` modes)
        run first, in order, instead of the first shift at the band's centre
        with ``k = 20`` -- e.g. a neighbouring sweep point's shifts with the
        number of modes found around each (:func:`copdea_fem.sweep.shift_plan`).
        The planner and the certification then run as usual, so a poor plan
        costs time, never a mode.
    factorize : callable, optional
        ``factorize(sigma)`` returns an object like :class:`Factorization`
        (``solve``, ``dtype``, ``solve_count``, ``factorisation_seconds``) for
        ``A - sigma B``, used instead of factorising the SciPy matrices -- e.g.
        an NGSolve matrix assembled natively complex (the coupled problem).
    start_modes : int, optional
        ``k`` of the first run at the band's centre (default 20) when no
        ``initial_shifts`` are given: an estimate of the band's count (e.g.
        from the dry modes) saves Krylov vectors; a low one costs another run.

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
        ARPACK failure, singular pencil, or band impossible to cover.

    Notes
    -----
    Strategy: shift-invert with deflation and certified discs.
    Shifts ``sigma`` are real.  At a shift, ``A - sigma B`` is factorised once
    and ARPACK (``eigsh`` in mode 3 with the B-inner product if Hermitian,
    ``eigs`` on ``(A - sigma B)^-1 B`` otherwise) is asked for the ``k``
    largest ``|nu|``, ``nu = 1/(lam - sigma)`` -- the ``k`` eigenvalues nearest
    ``sigma`` -- of the operator *deflated by every pair already known*
    (Wielandt: ``OP - X diag(nu_X) Z`` with ``Z X = I``; the known pairs move
    to ``nu = 0``).  So every run returns only new pairs, and more modes
    around a shift (extending ``k``) or a new shift never recompute old ones.

    A run at ``sigma`` that returns new eigenvalues at distances
    ``d_1 <= ... <= d_k`` states two things: (i) *certified*: no unknown
    eigenvalue was nearer than ``d_1`` -- every eigenvalue in the open disc
    ``|lam - sigma| < d_1`` was already known; this rests only on ARPACK
    finding the dominant eigenvalue of the deflated operator, which it does
    for any start vector with a component along it (a random one, almost
    surely); (ii) *trusted*: the disc of radius ``d_k`` is complete if ARPACK
    returned the ``k`` largest, which can fail for a multiple eigenvalue
    (Krylov methods see one copy first).  Discs of trusted radius are used to
    plan: the band's image in the lam-plane is sampled in cells with a slack
    radius that bounds each cell (so a covered sample proves the cell), and
    while a cell is outside every disc the solver either asks the nearest
    shift for more modes (cheap: same LU) when the gap is within 2.5 radii,
    or places a new shift into the gap, 0.75 radii beyond the frontier or at
    the gap's middle (with about as many modes as the neighbour's disc
    held).  When the trusted discs cover the band, a *certification* run
    (``k = 2``, tol 1e-8, nothing stored) at a shift whose trusted disc is
    still needed gives the distance of the nearest eigenvalue still unknown;
    shrunk by 1e-4 for its error, it is the certified radius and must reach
    the trusted one.  If a degenerate partner had been missed, it is nearer
    (the deflated operator no longer contains the found copy), the radius
    shrinks, and the shift is extended, which finds it.  The call returns
    only when the *certified* discs cover the band, enlarged by 0.1 % of its
    width, so a missed mode is impossible unless ARPACK misses the dominant
    eigenvalue of a deflated operator.

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
    _check_backend_name(backend)
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
    if progress is not None and not callable(progress):
        raise EigenInputError("progress must be a callable taking one str, or None")
    _require_backend(backend)
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
    region = _BandRegion(f_min, f_max, max_imag_hz, margin_hz, hermitian)
    # ARPACK stops at ||OP x - nu x|| <= tol |nu|, i.e. ||A x - lam B x|| <=
    # tol ||A - sigma B|| ||x||, and ||A - sigma B|| ~ ||A|| for sigma inside
    # the band (far below the top of an FE spectrum): keep 100x below the
    # requested residual, never looser than 1e-10, never below round-off.
    arpack_tol = max(min(1e-10, 0.01 * residual_tol), 1e-14)  # ARPACK cannot go below ~eps
    initial_shifts = _validate_initial_shifts(initial_shifts)
    solver = _BandSolver(A, B, region, backend, hermitian, max_modes, int(max_modes_per_shift),
                         band_contains, arpack_tol, progress, initial_shifts, start_modes)
    solver.factorize = factorize
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
        hermitian=bool(hermitian),
        backend=backend,
        residual_tol=float(residual_tol),
    )
    if progress is not None:
        progress(
            f"band {f_min:g}..{f_max:g} Hz: {len(result)} modes, {result.n_factorisations} "
            f"factorisations ({result.factorisation_seconds:.3g} s), "
            f"ARPACK {result.iteration_seconds:.3g} s"
        )
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
