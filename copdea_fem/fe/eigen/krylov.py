"""The deflated shift-invert Krylov run: the ``k`` unknown eigenpairs nearest a shift.

At a real shift ``sigma`` with ``A - sigma B`` factorised, the operator is
``OP = (A - sigma B)^-1 B``, whose eigenvalues ``nu = 1/(lam - sigma)`` are
largest for the ``lam`` nearest ``sigma``.  It is *deflated by every pair
already known* (Wielandt: ``OP - X diag(nu_X) Z`` with ``Z X = I``; the known
pairs move to ``nu = 0``), so a run returns only new pairs.

Two Krylov methods, :data:`KRYLOV_METHODS`:

``"krylov-schur"`` (default for general pencils)
    Krylov-Schur (Stewart 2001; in block form Zhou & Saad 2008) on the deflated
    operator, with a basis of :func:`basis_size` vectors (three per wanted pair):
    where air/PML modes crowd the lam-plane in two dimensions the ``|nu|`` of the
    wanted and the next ones lie close together, and ARPACK's default basis
    (``max(2 k + 1, k + 20)``) restarts many times.  Thick restarts keep the
    Schur vectors of the wanted Ritz values.  ``BLOCK_SIZE`` right-hand sides
    per step are possible (one sweep of the factors for ``p`` vectors), but a
    block space of ``m`` vectors has only degree ``m / p``, which costs more
    solves than the block saves (measured, see :data:`BLOCK_SIZE`): the default is
    one vector per step.
``"arpack"``
    ARPACK's implicitly restarted Arnoldi (``eigs``), the method before
    Krylov-Schur; and always for Hermitian pencils (``eigsh``, Lanczos in the
    B-inner product with ARPACK's default basis: the dry membrane, whose runs
    are cheap).

Both stop at ``||OP x - nu x|| <= tol |nu|`` for the ``k`` largest ``|nu|``.
"""

from __future__ import annotations

import math
import time
from typing import Callable

import numpy as np
import scipy.linalg
import scipy.sparse.linalg as spla

from copdea_fem.fe.eigen.errors import EigenInputError, EigenSolverError
from copdea_fem.fe.eigen.frequencies import format_hz

KRYLOV_METHODS: tuple[str, ...] = ("krylov-schur", "arpack")
"""Names accepted by ``krylov`` (:func:`copdea_fem.fe.eigen.solve_band`)."""

PROGRESS_INTERVAL_S = 15.0
"""A long run reports its solve count this often [s] (``progress``)."""

BLOCK_SIZE = 1
"""Right-hand sides per step of a Krylov-Schur run.  A block solve is cheaper per
right-hand side, but the block Krylov space needs more vectors: on G1's coupled sectors and
the drum the solves grow faster with the block size than the time per solve falls, so
one (the measured counts and times are in docs/benchmarks.md)."""


BASIS_FACTOR = 3
"""Basis vectors per wanted eigenvalue before a restart (ARPACK's default is ~2)."""

MIN_BASIS = 80
"""Fewest basis vectors before a restart.  A run restarts only when its basis is full, so
this costs nothing where a run converges early; in a crowded disc it keeps the whole
Krylov space of a first run for the resumed runs after it (:class:`KrylovDecomposition`).
The 0.65 m drum's odd-even sector (first run k = 11, converged after ~71 solves, then 36
more pairs and the certification resumed): 209 solves for the sector with the basis
``3 k + 2`` (35), 190 with at least 45, 172 with 60, 166 with 75, 90 or 120; G1's
sectors unchanged (61)."""


def basis_size(k: int, block: int, n: int) -> int:
    """Most basis vectors before a thick restart: ``BASIS_FACTOR k`` plus ``2 p`` for the
    block, at least ``k + 20 p`` and :data:`MIN_BASIS` (ARPACK's default ``ncv`` is
    ``max(2 k + 1, k + 20)``, too few where air/PML modes crowd the disc: their ``|nu|``
    then lie close together and a small basis restarts many times), below ``n``."""
    return int(min(n - 1, max(BASIS_FACTOR * k + 2 * block, k + 20 * block, MIN_BASIS)))


def check_krylov(method) -> None:
    if method not in KRYLOV_METHODS:
        raise EigenInputError(f"krylov={method!r} is not a known Krylov method; "
                              f"allowed: {', '.join(map(repr, KRYLOV_METHODS))}")


class DeflatedOperator:
    """``OP = (A - sigma B)^-1 B`` deflated by the known pairs (Wielandt), on blocks.

    Parameters
    ----------
    B : scipy.sparse matrix, shape (n, n)
    solve : callable
        ``solve(rhs)`` of ``A - sigma B`` for a 1-D or 2-D ``rhs``.
    sigma : float
        The shift (rad^2/s^2).
    values, vectors : numpy.ndarray
        Known eigenvalues ``lam`` (rad^2/s^2) and unit vectors (B-orthonormal
        if ``hermitian``).
    hermitian : bool
    factor_dtype : numpy.dtype
        The factorisation's (``float64`` or ``complex128``).

    Attributes
    ----------
    dtype : numpy.dtype
        Of the operator's products: the factors', ``B``'s and the known vectors'.
    """

    def __init__(self, B, solve, sigma, values, vectors, hermitian, factor_dtype):
        self.B, self.solve, self.sigma, self.hermitian = B, solve, sigma, hermitian
        self.X = vectors
        deflation_dtype = vectors.dtype if vectors.shape[1] else np.dtype(float)
        self.dtype = np.result_type(deflation_dtype, factor_dtype, B.dtype)
        nu = 1.0 / (values - sigma)
        # Z = (X^H X)^-1 X^H (general) or X^H B (Hermitian: X is B-orthonormal, Z X = I) is
        # applied as small k x k factors after X^H x, never stored as another n x k array
        # (the 0.65 m drum: 47 known pairs of 48k unknowns, 36 MB a copy and sector).
        self.nu = nu.real if hermitian else nu
        self._gram = None
        if not hermitian and vectors.shape[1]:
            self._gram = scipy.linalg.lu_factor(vectors.conj().T @ vectors)

    @property
    def deflating(self) -> bool:
        return self.X.shape[1] > 0

    def _adjoint_times(self, y):
        """``X^H y`` for a 1-D or 2-D ``y`` without a copy of ``X``."""
        return (y.T.conj() @ self.X).T.conj() if y.ndim == 2 else (y.conj() @ self.X).conj()

    def _z_times(self, x):
        """``Z x`` (module doc), 1-D or 2-D ``x``."""
        if self.hermitian:
            return self._adjoint_times(self.B @ x)
        return scipy.linalg.lu_solve(self._gram, self._adjoint_times(x))

    def _subtract_deflation(self, result, coefficients):
        """``result - X diag(nu) coefficients``."""
        return result - self.X @ (self.nu[:, None] * coefficients if coefficients.ndim == 2
                                  else self.nu * coefficients)

    def inverse(self, y):
        """Hermitian ``OPinv = (A - sigma B)^-1 - X diag(nu) X^H`` (ARPACK mode 3)."""
        y = np.asarray(y)
        result = self.solve(y)
        if not self.deflating:
            return result
        return self._subtract_deflation(result, self._adjoint_times(y))

    def apply(self, x):
        """``OP x - X diag(nu) Z x`` for a 1-D or 2-D ``x``."""
        x = np.asarray(x)
        result = self.solve(self.B @ x)
        if not self.deflating:
            return result
        return self._subtract_deflation(result, self._z_times(x))

    def eigenvectors(self, nu_new, W):
        """Pencil eigenvectors of the deflated operator's eigenvectors ``W`` (columns).

        Wielandt back-transformation: ``OP x = nu x`` with ``x = w + X c``,
        ``(nu - nu_i) c_i = nu_i (Z w)_i``.  For ``nu = nu_i`` (a degenerate
        partner of a known pair) ``(Z w)_i`` vanishes and ``c_i`` is free: take
        0.  (Hermitian: the deflated operator is B-self-adjoint, so ``w`` is
        B-orthogonal to X and already an eigenvector of the pencil.)
        """
        if not self.deflating or self.hermitian:
            return W
        gap = nu_new[None, :] - self.nu[:, None]
        tiny = np.abs(gap) <= 1e-8 * np.abs(nu_new)[None, :]
        coefficients = (self.nu[:, None] * self._z_times(W)) / np.where(tiny, 1.0, gap)
        coefficients[tiny] = 0.0
        return W + self.X @ coefficients


def _project(V, W):
    """``V^H W`` without forming ``V^H`` (``V`` is the large basis: no copy of it)."""
    return (W.conj().T @ V).conj().T


def _orthogonalise(V, W):
    """``W = V C + Q R`` with ``Q`` orthonormal and orthogonal to ``V`` (classical
    Gram-Schmidt twice, then a QR); columns of ``W`` that lie in ``span V`` (an
    invariant subspace reached) are replaced by random directions with ``R = 0``."""
    norms = np.linalg.norm(W, axis=0)
    C = np.zeros((V.shape[1], W.shape[1]), dtype=W.dtype)
    if V.shape[1]:
        for _ in range(2):
            coefficients = _project(V, W)
            W = W - V @ coefficients
            C += coefficients
    if W.shape[1] == 1:              # one vector (the default block): QR is its norm
        length = float(np.linalg.norm(W))
        R = np.array([[length]], dtype=W.dtype)
        Q = W / length if length > 0 else W.copy()
    else:
        Q, R = np.linalg.qr(W)
    lost = np.abs(np.diag(R)) <= 1e-12 * max(float(norms.max(initial=0.0)), 1e-300)
    if np.any(lost):
        rng = np.random.default_rng(W.shape[0] + V.shape[1])
        for column in np.flatnonzero(lost):
            R[column, :] = 0.0
            fresh = rng.standard_normal(W.shape[0]).astype(W.dtype)
            basis = np.concatenate([V, Q[:, :column]], axis=1)
            for _ in range(2):
                fresh = fresh - basis @ _project(basis, fresh[:, None])[:, 0]
            Q[:, column] = fresh / np.linalg.norm(fresh)
    return C, Q, R


class KrylovDecomposition:
    """A Krylov decomposition ``OP V[:, :m] = V[:, :m + p] H[:m + p, :m]`` kept between runs.

    ``m`` (``expanded``) columns are expanded, ``p`` (``block``) more hold the residual
    block still to expand.  :func:`block_krylov_schur` returns it at convergence, and a
    later run at the same shift resumes it
    (:meth:`copdea_fem.fe.eigen.planner.BandSolver.nearest_unknown`): the Ritz values beyond
    those already converged are then partly
    converged, so asking for more pairs, or for the nearest one still unknown (the
    certification), costs a few solves instead of a new Krylov space.
    """

    def __init__(self, start: np.ndarray, capacity: int):
        n, block = start.shape
        self.block = block
        self.basis = np.zeros((n, capacity + 2 * block), dtype=start.dtype, order="F")
        self.H = np.zeros((capacity + 2 * block,) * 2, dtype=start.dtype)
        _, first, _ = _orthogonalise(self.basis[:, :0], start)
        self.basis[:, :block] = first
        self.expanded, self.size = 0, block

    @property
    def capacity(self) -> int:
        return self.basis.shape[1] - 2 * self.block

    def reserve(self, capacity: int) -> None:
        """Room for ``capacity`` basis vectors (the content is kept)."""
        if capacity <= self.capacity:
            return
        rows = capacity + 2 * self.block
        basis = np.zeros((self.basis.shape[0], rows), dtype=self.basis.dtype, order="F")
        basis[:, :self.size] = self.basis[:, :self.size]
        H = np.zeros((rows, rows), dtype=self.H.dtype)
        H[:self.size, :self.expanded] = self.H[:self.size, :self.expanded]
        self.basis, self.H = basis, H


def block_krylov_schur(apply: Callable, start: np.ndarray, k: int, tol: float,
                       max_basis: int, max_restarts: int = 60,
                       resume: KrylovDecomposition | None = None,
                       excluded: Callable | None = None):
    """The ``k`` largest-``|theta|`` eigenpairs of the operator ``apply`` (block Krylov-Schur).

    Parameters
    ----------
    apply : callable
        ``apply(V)`` for ``V`` of shape (n, p).
    start : numpy.ndarray, shape (n, p)
        Start block (any full-rank block; random here).  A real block and a real
        operator keep the basis real (complex eigenvalues in exact conjugate pairs).
    k : int
        Wanted eigenvalues.
    tol : float
        Stop when every wanted Ritz pair has ``||apply(x) - theta x|| <= tol |theta|``
        (``||x|| = 1``), ARPACK's criterion.
    max_basis : int
        Thick restart beyond this many vectors (:func:`basis_size`).
    resume : KrylovDecomposition or None
        Continue this decomposition of the same operator (``start`` unused) instead
        of starting afresh.
    excluded : callable or None
        ``excluded(theta)`` -> boolean mask of Ritz values that are never wanted (neither
        returned nor kept at a restart): e.g. the relaxation spectrum of a Prony series,
        outside the band (:mod:`copdea_fem.fe.eigen.damped`).

    Returns
    -------
    theta : numpy.ndarray, shape (k,)
    vectors : numpy.ndarray, shape (n, k)
        Unit Ritz vectors.
    decomposition : KrylovDecomposition
        The decomposition at convergence, to resume.

    Notes
    -----
    The Krylov decomposition ``OP V_m = V_m S + V_+ E`` (``V_+`` the ``p``
    unexpanded vectors, ``E`` a ``p x m`` block) holds throughout.  Expanding
    ``V_+`` appends its image orthogonalised against the basis; the residual of
    a Ritz pair ``(theta, V_m y)`` of ``S`` is ``||E y||``.  A restart keeps the
    Schur vectors of the ``keep`` largest Ritz values (``S = U T U^H`` reordered,
    ``V_m <- V_m U_keep``, ``S <- T_keep``, ``E <- E U_keep``), which keeps the
    decomposition exact.  The basis lives in one preallocated array, so a step
    costs the block solve plus two passes over the basis.  Resuming continues
    the same decomposition: the pairs it had converged stay converged and the
    next ones start from what the earlier run already built.
    """
    n = start.shape[0]
    if resume is None:
        decomposition = KrylovDecomposition(np.asarray(start), max_basis)
    else:
        decomposition = resume
        decomposition.reserve(max_basis)
    block, dtype = decomposition.block, decomposition.basis.dtype
    basis, H = decomposition.basis, decomposition.H
    expanded, size = decomposition.expanded, decomposition.size
    restarts = 0
    # The Ritz values cost an eig of the m x m projection, measured at about 0.02 m^3 / n
    # solves' time (SuperLU, coupled sectors of 5k-48k unknowns): check convergence
    # every ceil(0.02 m^3 / n) steps (m the basis now) so the eig never costs more than
    # the solves it watches (and at every restart point).
    steps = 0
    while True:
        W = apply(basis[:, expanded:expanded + block])
        steps += 1
        C, Q, R = _orthogonalise(basis[:, :size], W)
        H[:size, expanded:expanded + block] = C
        H[size:size + block, expanded:expanded + block] = R
        basis[:, size:size + block] = Q
        size += block
        expanded += block
        full = size + block > max_basis
        if expanded < k or (steps < math.ceil(0.02 * expanded ** 3 / n) and not full):
            continue
        steps = 0
        S = H[:expanded, :expanded]
        theta, Y = np.linalg.eig(S)
        magnitude = np.abs(theta)
        if excluded is not None:
            magnitude = np.where(excluded(theta), -1.0, magnitude)
        order = np.argsort(-magnitude, kind="stable")
        theta, Y, magnitude = theta[order], Y[:, order], magnitude[order]
        Y = Y / np.linalg.norm(Y, axis=0)
        residual = np.linalg.norm(H[expanded:size, :expanded] @ Y[:, :k], axis=0)
        if np.all(residual <= tol * np.abs(theta[:k])) and np.all(magnitude[:k] >= 0):
            decomposition.expanded, decomposition.size = expanded, size
            return theta[:k], basis[:, :expanded] @ Y[:, :k], decomposition
        if not full:
            continue
        restarts += 1
        if restarts > max_restarts:
            raise EigenSolverError(f"block Krylov-Schur did not converge for k={k} in "
                                   f"{max_restarts} restarts of {max_basis} vectors")
        keep = min(k + (expanded - k) // 2, expanded - block)
        cutoff = abs(theta[keep - 1]) * (1.0 - 1e-12)
        if excluded is not None:
            cutoff = max(magnitude[keep - 1], 0.0) * (1.0 - 1e-12)

            def wanted(x):
                return abs(x) >= cutoff and not bool(excluded(np.array([x]))[0])
        else:
            def wanted(x):
                return abs(x) >= cutoff
        if dtype.kind == "c":
            T, U, kept = scipy.linalg.schur(S, output="complex", sort=wanted)
        else:                    # real Schur form: a conjugate pair stays in one 2x2 block
            T, U, kept = scipy.linalg.schur(S, output="real",
                                            sort=lambda re, im: wanted(complex(re, im)))
        kept = int(min(max(kept, 1), expanded - block))
        if kept < expanded and T[kept, kept - 1] != 0:    # never split a real 2x2 block
            kept -= 1 if kept > 1 else -1
        coupling = H[expanded:size, :expanded] @ U[:, :kept]
        residual_block = basis[:, expanded:size].copy()
        basis[:, :kept] = basis[:, :expanded] @ U[:, :kept]
        basis[:, kept:kept + block] = residual_block
        H[:] = 0.0
        H[:kept, :kept] = T[:kept, :kept]
        H[kept:kept + block, :kept] = coupling
        expanded, size = kept, kept + block


def counting(solve: Callable, say: Callable[[int, float], None]) -> Callable:
    """``solve`` that calls ``say(solves, seconds)`` every ``PROGRESS_INTERVAL_S``."""
    start = last = time.perf_counter()
    count = 0

    def counted(rhs):
        nonlocal last, count
        count += 1 if np.ndim(rhs) == 1 else np.shape(rhs)[1]
        now = time.perf_counter()
        if now - last >= PROGRESS_INTERVAL_S:
            last = now
            say(count, now - start)
        return solve(rhs)

    return counted


def nearest_unknown(operator: DeflatedOperator, k: int, tol: float, start: np.ndarray,
                    method: str, real_arithmetic: bool, basis: int | None = None,
                    resume: KrylovDecomposition | None = None,
                    excluded: Callable | None = None):
    """The ``k`` eigenpairs of the pencil nearest ``operator.sigma`` that are not known.

    Parameters
    ----------
    operator : DeflatedOperator
    k : int
    tol : float
        Relative tolerance on ``nu`` (see the module doc).
    start : numpy.ndarray, shape (n, p)
        Deterministic start block; the ARPACK paths use its first column.
    method : {"krylov-schur", "arpack"}
        Hermitian pencils always take ARPACK's Lanczos.
    real_arithmetic : bool
        Real symmetric pencil: vectors returned real.
    basis : int or None
        Least basis of a Krylov-Schur run (default :func:`basis_size`); ARPACK
        runs keep ARPACK's default ``max(2 k + 1, k + 20)``.
    resume : KrylovDecomposition or None
        A Krylov-Schur decomposition of this same ``operator`` to continue.
    excluded : callable or None
        ``excluded(lam)`` -> mask of eigenvalues a Krylov-Schur run never wants (they
        lie outside the band; :func:`block_krylov_schur`).

    Returns
    -------
    values : numpy.ndarray of complex
        ``lam`` (rad^2/s^2), at most ``k``.
    vectors : numpy.ndarray
    exhausted : bool
        The run reached the deflated (``nu ~ 0``) directions: no finite
        eigenvalue is left unknown.
    decomposition : KrylovDecomposition or None
        The Krylov-Schur run's decomposition, to resume (None for ARPACK).
    """
    sigma, B = operator.sigma, operator.B
    n = B.shape[0]
    operator_dtype = operator.dtype
    start_vector = start[:, 0] if np.dtype(operator_dtype).kind == "c" else start[:, 0].real
    ncv = min(n, max(2 * k + 1, k + 20))       # ARPACK's default, as before Krylov-Schur
    if operator.hermitian:
        # eigsh, generalised shift-invert (ARPACK mode 3, B-inner product):
        # OP = OPinv B with OPinv Hermitian, so the deflated problem stays a
        # Lanczos problem.  The known pairs move to nu = 0 (lam = inf).
        inverse_operator = spla.LinearOperator((n, n), matvec=operator.inverse,
                                               dtype=operator_dtype)
        a_placeholder = spla.LinearOperator((n, n), matvec=lambda y: y, dtype=operator_dtype)

        def call(ncv, maxiter):
            return spla.eigsh(a_placeholder, k=k, M=B, sigma=sigma, which="LM",
                              OPinv=inverse_operator, v0=start_vector, ncv=ncv,
                              maxiter=maxiter, tol=tol)
    elif method == "arpack":
        linear = spla.LinearOperator((n, n), matvec=operator.apply, dtype=operator_dtype)

        def call(ncv, maxiter):
            nu, W = spla.eigs(linear, k=k, which="LM", v0=start_vector, ncv=ncv,
                              maxiter=maxiter, tol=tol)
            with np.errstate(divide="ignore"):
                return sigma + 1.0 / nu, W
    else:
        block = start if np.dtype(operator_dtype).kind == "c" else start.real.copy()
        skip = None
        if excluded is not None:
            def skip(theta):
                with np.errstate(divide="ignore", invalid="ignore"):
                    return np.asarray(excluded(sigma + 1.0 / theta), dtype=bool)
        theta, W, decomposition = block_krylov_schur(
            operator.apply, block, k, tol,
            min(n - 1, max(basis or 0, basis_size(k, start.shape[1], n))), resume=resume,
            excluded=skip)
        with np.errstate(divide="ignore"):
            values = sigma + 1.0 / theta
        return (*_finish(operator, values, W, real_arithmetic), decomposition)
    try:
        try:
            values, W = call(ncv, None)
        except spla.ArpackNoConvergence:
            values, W = call(min(n, 2 * ncv), 20 * n)
    except spla.ArpackNoConvergence as error:
        raise EigenSolverError(
            f"ARPACK did not converge at shift {format_hz(sigma)} for k={k} "
            f"(ncv={min(n, 2 * ncv)}): {error}"
        ) from error
    return (*_finish(operator, values, W, real_arithmetic), None)


def _finish(operator: DeflatedOperator, values, W, real_arithmetic: bool):
    """Drop the deflated directions, back-transform, and say whether the run was exhausted."""
    sigma = operator.sigma
    values = np.asarray(values, dtype=complex)
    with np.errstate(divide="ignore", invalid="ignore"):
        nu_new = 1.0 / (values - sigma)
    # Deflated directions come back with |nu| at round-off level (lam ~ inf);
    # they carry no information and are dropped.
    largest = np.max(np.abs(nu_new[np.isfinite(nu_new)]), initial=0.0)
    keep = np.isfinite(values) & (np.abs(nu_new) > 1e-10 * largest)
    exhausted = not np.all(keep)
    values, W, nu_new = values[keep], W[:, keep], nu_new[keep]
    if operator.hermitian:
        values = values.real + 0j
    W = operator.eigenvectors(nu_new, W)
    if real_arithmetic:
        W = W.real
    return values, W, exhausted
