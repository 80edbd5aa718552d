"""Factorisation back-ends of ``A - sigma B``: one sparse LU, many right-hand sides.

:class:`Factorization` wraps one sparse LU (NGSolve UMFPACK or MKL PARDISO, or
SciPy SuperLU in METIS nested-dissection order) of a SciPy matrix;
:class:`NativeShiftedInverse` factorises the coupled pencil natively complex in
NGSolve.  Both solve a block of right-hand sides at once (``solve(rhs)`` with
``rhs`` of shape (n, m)): SuperLU's triangular solves then sweep the factors
once for all ``m`` columns (level-3 BLAS on the supernodes), which is what makes
the block Krylov runs of :mod:`copdea_fem.fe.eigen.krylov` cheap per vector.

NGSolve 6.2.2608 notes (checked):

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

SciPy's SuperLU (5.x, thread-safe) releases the GIL in its factorisation and
solves (checked on SciPy 1.17: two threads factorising / solving a 13.5k coupled
sector pencil side by side take little more than half the time of one after the
other), so independent pencils can be solved side by side in threads.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import threading
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from copdea_fem.fe.eigen.errors import BackendUnavailableError, EigenInputError, EigenSolverError

BACKENDS: tuple[str, ...] = ("umfpack", "pardiso", "superlu")
"""Names accepted by ``backend``: NGSolve UMFPACK, NGSolve/MKL PARDISO, SciPy SuperLU."""


@functools.lru_cache(maxsize=None)
def backend_available(backend: str) -> bool:
    """Whether ``backend`` (one of :data:`BACKENDS`) can factorise on this machine.

    ``"pardiso"`` needs Intel MKL (``pip install mkl``); it is probed by
    factorising a 1x1 matrix once (result cached).
    """
    check_backend_name(backend)
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


def check_backend_name(backend) -> None:
    if backend not in BACKENDS:
        raise EigenInputError(
            f"backend={backend!r} is not a known factorisation back-end; "
            f"allowed: {', '.join(map(repr, BACKENDS))}"
        )


def require_backend(backend) -> None:
    check_backend_name(backend)
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


def real_equivalent(matrix: sp.csr_matrix) -> sp.csr_matrix:
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


#: SuperLU's diagonal pivot threshold when static pivoting fails its probe
#: (:data:`STATIC_PIVOT_BACKWARD_ERROR`): a diagonal entry at least this share of its
#: column's largest is kept as the pivot.
SUPERLU_PIVOT_THRESHOLD = 0.1
#: First try: threshold 0, i.e. the diagonal is the pivot whenever it is nonzero (static
#: pivoting in the fill-reducing order, as the ordering assumed).  Measured (SciPy 1.17,
#: one BLAS thread), threshold 0.1 -> 0: G1's odd-even coupled sector (n = 12775) nnz(LU)
#: 5.14 -> 3.67 M, the 0.65 m drum's even-even sector (n = 46913) 35.2 -> 25.1 M, the
#: a third to a half less factorisation time, a fifth less a solve (docs/benchmarks.md);
#: the probe's backward error 3.6e-16 and 1.4e-17 (0.1: 3.3e-16, 4.4e-18).  Even threshold 0.001
#: keeps the drum at 33 M: the smallest diagonal of its columns is 1.3e-3 of the largest.
SUPERLU_STATIC_PIVOT_THRESHOLD = 0.0
#: Normwise backward error ``||S x - b||_1 / (||S||_1 ||x||_1 + ||b||_1)`` of a random
#: probe solve above which static pivoting is refused (growth of 1e4 over round-off)
#: and the matrix is factorised again with :data:`SUPERLU_PIVOT_THRESHOLD`.
STATIC_PIVOT_BACKWARD_ERROR = 1e-12
#: Below this size the METIS call costs more than the fill it saves (a 2-D FE-like
#: pattern of 1600 unknowns: factorisation + 20 solves take longer in METIS order than in
#: SuperLU's own; the 3-D pencils here are 9k-14k).  Small matrices take SuperLU's
#: MMD_AT_PLUS_A order with the same diagonal pivoting: a coupled meridian pencil of
#: order m = 2 (1005 unknowns) factorises far faster than with SuperLU's default partial
#: pivoting (nnz(LU) 40k instead of 464k), and solves several times faster.
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
    with _ORDERINGS_LOCK:                # sector threads share the cache
        cached = _ORDERINGS.get(key)
    if cached is not None:               # every shift of a pencil has the same pattern
        return cached
    ordering = _nested_dissection(matrix)
    with _ORDERINGS_LOCK:
        if len(_ORDERINGS) >= 16:
            _ORDERINGS.pop(next(iter(_ORDERINGS)))
        _ORDERINGS[key] = ordering
    return ordering


_ORDERINGS: dict = {}     # sparsity pattern -> METIS permutation (this process)
_ORDERINGS_LOCK = threading.Lock()


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


def factor_memory_estimate(matrix) -> float:
    """Estimated bytes of the SuperLU factors of a 3-D FE pencil ``A - sigma B`` (METIS order).

    ``nnz(L + U) ~ 8.5 nnz(A) (n / 13538)^0.44`` with static pivoting
    (:data:`SUPERLU_STATIC_PIVOT_THRESHOLD`): nested dissection of a 3-D mesh fills like
    ``n^(4/3)`` (George 1973, exponent 1/3 here); the power fitted through G1's odd-even
    coupled sector (n = 12775: 8.3 entries of L + U per entry of A) and the 0.65 m
    drum's even-even one (n = 46913: 14.7).  22.4 bytes per complex entry (values and
    indices: the drum sector's factors take 539 MB for 25.1 M entries), 14.4 real.
    """
    matrix = sp.csr_matrix(matrix)
    n = max(matrix.shape[0], 1)
    entries = 8.5 * matrix.nnz * (n / 13538.0) ** 0.44
    return entries * (22.4 if np.iscomplexobj(matrix.data) else 14.4)


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
        Number of right-hand sides solved so far (a complex right-hand side
        against a real matrix counts two).
    block_solve_count : int
        Number of calls to the back-end's solve (one per block of right-hand sides).

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
        require_backend(backend)
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
        self.block_solve_count = 0
        self.static_pivoting = False
        start = time.perf_counter()
        try:
            if backend == "superlu":
                self._factorise_superlu(matrix)
            else:
                self._factorise_ngsolve(matrix)
        except Exception as error:  # NGSolve's NgException derives from Exception only
            raise EigenSolverError(
                f"{backend} could not factorise the {self.shape[0]}x{self.shape[1]} matrix "
                f"(singular?): {error}"
            ) from error
        self.factorisation_seconds = time.perf_counter() - start

    def _factorise_superlu(self, matrix: sp.csr_matrix) -> None:
        """SuperLU in METIS order (small matrices: SuperLU's minimum degree), static
        diagonal pivots first, threshold pivoting if the probe's backward error says so."""
        self._order = fill_reducing_order(matrix)
        if self._order is None:
            permuted, ordering = matrix.tocsc(), "MMD_AT_PLUS_A"
        else:
            permuted, ordering = matrix[self._order][:, self._order].tocsc(), "NATURAL"
        for threshold in (SUPERLU_STATIC_PIVOT_THRESHOLD, SUPERLU_PIVOT_THRESHOLD):
            self._superlu = None                 # free the refused factors first
            self._superlu = spla.splu(permuted, permc_spec=ordering,
                                      diag_pivot_thresh=threshold,
                                      options={"SymmetricMode": True})
            self.static_pivoting = threshold == SUPERLU_STATIC_PIVOT_THRESHOLD
            if not self.static_pivoting or \
                    self.backward_error(matrix) <= STATIC_PIVOT_BACKWARD_ERROR:
                return

    def backward_error(self, matrix) -> float:
        """Normwise backward error of a solve with a fixed random right-hand side:
        ``||S x - b||_1 / (||S||_1 ||x||_1 + ||b||_1)`` [-] (round-off: ~1e-16)."""
        rng = np.random.default_rng(7)
        rhs = rng.standard_normal(self.shape[0])
        if self.is_complex:
            rhs = rhs + 1j * rng.standard_normal(self.shape[0])
        solution = self._solve_block(rhs[:, None])[:, 0]
        self.solve_count -= 1             # the probe is not one of the caller's solves
        self.block_solve_count -= 1
        norm = float(spla.norm(matrix, 1))
        residual = np.linalg.norm(matrix @ solution - rhs, 1)
        return float(residual / (norm * np.linalg.norm(solution, 1) + np.linalg.norm(rhs, 1)))

    def _factorise_ngsolve(self, matrix: sp.csr_matrix) -> None:
        from ngsolve import la

        real_matrix = real_equivalent(matrix) if self.is_complex else matrix
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
        """Solve with the back-end's own (real for NGSolve) matrix; rhs 2-D (n, m), one block."""
        self.solve_count += rhs.shape[1]
        self.block_solve_count += 1
        if self.backend == "superlu":       # one sweep of the factors for all m columns
            if self._order is None:
                return self._superlu.solve(rhs)
            solution = np.empty_like(rhs)
            solution[self._order] = self._superlu.solve(rhs[self._order])
            return solution
        solution = np.empty_like(rhs)
        for column in range(rhs.shape[1]):
            self._ngsolve_rhs.FV().NumPy()[:] = rhs[:, column]
            self._ngsolve_inverse.Mult(self._ngsolve_rhs, self._ngsolve_solution)
            solution[:, column] = self._ngsolve_solution.FV().NumPy()
        return solution

    def _solve_block(self, rhs: np.ndarray) -> np.ndarray:
        """``matrix^-1 rhs`` for a 2-D ``rhs``, real or complex, in one block solve."""
        rhs_is_complex = np.iscomplexobj(rhs)
        columns = rhs.shape[1]
        if self.backend == "superlu" and self.is_complex:
            return self._solve_real_layout(np.asarray(rhs, dtype=complex))
        if not self.is_complex:              # real factors: Re and Im side by side
            if not rhs_is_complex:
                return self._solve_real_layout(np.asarray(rhs, dtype=float))
            solution = self._solve_real_layout(np.concatenate([rhs.real, rhs.imag], axis=1))
            return solution[:, :columns] + 1j * solution[:, columns:]
        interleaved = np.empty((2 * rhs.shape[0], columns))   # NGSolve, real-equivalent form
        interleaved[0::2] = rhs.real
        interleaved[1::2] = rhs.imag if rhs_is_complex else 0.0
        solution = self._solve_real_layout(interleaved)
        return solution[0::2] + 1j * solution[1::2]

    def solve(self, rhs) -> np.ndarray:
        """Solve ``matrix @ x = rhs``; the columns of a 2-D ``rhs`` in one block solve.

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
        if rhs.ndim == 2 and rhs.shape[1] == 0:
            return np.zeros(rhs.shape, dtype=np.result_type(rhs.dtype, self.dtype))
        if rhs.ndim == 1:
            return self._solve_block(rhs[:, None])[:, 0]
        return self._solve_block(rhs)

    def as_linear_operator(self, dtype=None) -> spla.LinearOperator:
        """``x -> matrix^{-1} x`` as a :class:`scipy.sparse.linalg.LinearOperator`."""
        dtype = np.dtype(dtype) if dtype is not None else self.dtype
        return spla.LinearOperator(self.shape, matvec=self.solve, matmat=self.solve, dtype=dtype)


class NativeShiftedInverse:
    """Complex factorisation of the scaled ``A - sigma B`` on a sector's free DOFs, in NGSolve.

    (A_s - sigma B_s)^-1 = D_r^-1 (A - sigma B)^-1 D_l^-1 for the row/column
    scalings D_l, D_r.  NGSolve factorises the complex matrix natively with
    ``backend`` (``"umfpack"`` or ``"pardiso"``, study key ``eigen.backend``);
    :class:`Factorization` would hand it the twice-as-large real form.
    ``"superlu"`` takes that class (SciPy factorises complex).  The coupled 3-D
    pencil's ``factorize`` hook (:meth:`copdea_fem.fe.coupled.CoupledAssembly.restrict`).
    """

    def __init__(self, stiffness, mass, free_mask, sigma, row_scale, column_scale,
                 backend="umfpack"):
        from copdea_fem.fe.symmetry import bitarray

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
        self.block_solve_count = 0
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
        self.block_solve_count += 1
        if rhs.ndim == 1:
            return self._solve_vector(rhs)
        return np.stack([self._solve_vector(rhs[:, j]) for j in range(rhs.shape[1])], axis=1)
