"""The region cover / certification planner of :func:`copdea_fem.fe.eigen.solve_band`.

:class:`BandSolver` places shifts, asks each for the eigenpairs nearest it
(:func:`copdea_fem.fe.eigen.krylov.nearest_unknown`, deflated by every pair in
:class:`copdea_fem.fe.eigen.pairs.KnownPairs`), grows or adds discs until their
*trusted* radii cover the band's :class:`copdea_fem.fe.eigen.region.BandRegion`,
then certifies them (see :func:`copdea_fem.fe.eigen.solve_band` for the strategy
and why a missed mode is impossible).  Progress lines say what share of the band
is certified so far.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.linalg

from copdea_fem.fe.eigen import krylov as krylov_module
from copdea_fem.fe.eigen.errors import EigenSolverError, TooManyModesError
from copdea_fem.fe.eigen.factorization import Factorization
from copdea_fem.fe.eigen.krylov import DeflatedOperator, basis_size, counting, nearest_unknown
from copdea_fem.fe.eigen.pairs import KnownPairs
from copdea_fem.fe.eigen.region import BandRegion
from copdea_fem.progress import tagged

logger = logging.getLogger(__name__)


def _say(message: str) -> None:
    """A progress line with the thread's prefix (:func:`copdea_fem.progress.tagging`)."""
    logger.info(tagged(message))


@dataclass(eq=False)
class Shift:
    sigma: float
    factorization: Factorization
    trusted_radius: float = 0.0      # |lam - sigma| of the farthest pair of the latest run
    confirmed_radius: float = 0.0    # |lam - sigma| of the nearest *new* pair of the latest run
    modes_found: int = 0             # pairs added by runs at this shift
    runs: int = 0
    session: tuple | None = None     # (operator, Krylov decomposition, pairs it converged)


class BandSolver:
    """Bookkeeping of one :func:`solve_band` call (see its docstring for the strategy).

    Parameters
    ----------
    A, B : scipy.sparse.csr_matrix
    region : BandRegion
    backend : str
        Factorisation back-end when ``factorize`` is None.
    hermitian : bool
    max_modes, max_modes_per_shift : int
    band_contains : callable
        ``band_contains(lam)``: boolean mask of the eigenvalues in the band.
    tol : float
        Krylov tolerance of a run (relative, on ``nu``).
    initial_shifts : list of (float, int) or None
    start_modes : int or None
    factorize : callable or None
        ``factorize(sigma)`` -> an object like :class:`Factorization` for ``A - sigma B``.
    krylov : {"krylov-schur", "arpack"}
        Krylov method of a general pencil's runs (:mod:`copdea_fem.fe.eigen.krylov`).
    block_size : int or None
        Right-hand sides per block solve of the ``"krylov-schur"`` method (default
        :data:`copdea_fem.fe.eigen.krylov.BLOCK_SIZE`).
    excluded : callable or None
        ``excluded(values)`` -> mask of eigenvalues that no Krylov-Schur run wants: they
        must lie outside the band, and the discs then certify every eigenvalue but them
        (the Prony relaxation spectrum of :mod:`copdea_fem.fe.eigen.damped`).
    """

    START_MODES = 20           # k of the first run at a new shift
    CERTIFY_MODES = 2          # k of a certification run (only the dominant is used)
    CERTIFY_TOL = 1e-8         # ARPACK tol of a certification run
    CERTIFY_MARGIN = 1e-4      # certified radius = (1 - margin) * nearest unknown distance
    CERTIFY_BASIS_PER_PAIR = 1.5   # certification basis per pair in the trusted disc
    EXTEND_RATIO = 2.5         # extend a shift (reuse its LU) if the gap is within 2.5 radii
    NEW_SHIFT_OVERLAP = 0.75   # a new shift sits 0.75 radii beyond the frontier
    MAX_SHIFTS = 60
    MAX_RUNS = 400
    DENSE_DOFS = 64            # below this, a dense QZ is cheaper and exact
    DENSE_MAX_DOFS = 4000      # dense QZ beyond this costs minutes (n^3 ~ 1e11 flops)
    def __init__(self, A, B, region: BandRegion, *, backend: str, hermitian: bool,
                 max_modes: int, max_modes_per_shift: int, band_contains: Callable,
                 tol: float, initial_shifts=None, start_modes=None,
                 factorize: Callable | None = None, krylov: str = "krylov-schur",
                 block_size: int | None = None, excluded: Callable | None = None,
                 count_growth: float | None = None):
        self.A, self.B = A, B
        # d of the count law below (None: 1 for a Hermitian pencil, 3 for a general one)
        self.count_growth = count_growth or (1.0 if hermitian else 3.0)
        self.n = A.shape[0]
        self.start_modes = int(start_modes) if start_modes else self.START_MODES
        self.initial_shifts = list(initial_shifts or [])
        self.region = region
        self.backend = backend
        self.factorize = factorize
        self.krylov = krylov
        self.excluded = excluded      # eigenvalues no Krylov-Schur run wants (outside the band)
        self.hermitian = hermitian
        complex_pencil = np.iscomplexobj(A.data) or np.iscomplexobj(B.data)
        self.real_arithmetic = hermitian and not complex_pencil
        self.max_modes = max_modes
        self.max_modes_per_shift = max_modes_per_shift
        self.band_contains = band_contains
        self.tol = tol
        self.progress = _say      # progress lines: this module's logger at INFO
        self.known = KnownPairs(A, B, hermitian, self.real_arithmetic, region.scale)
        self.shifts: list[Shift] = []
        self.factorisation_seconds = 0.0
        self.iteration_seconds = 0.0
        self.runs = 0
        self.exhaustive = False
        rng = np.random.default_rng(20240611)  # fixed seed: deterministic Krylov start
        start = rng.standard_normal(self.n)
        if self.known.dtype.kind == "c":
            start = start + 1j * rng.standard_normal(self.n)
        self.start_vector = start             # ARPACK's (the first column of the block)
        block_size = krylov_module.BLOCK_SIZE if block_size is None else block_size
        others = max(1, min(int(block_size), self.n // 4)) - 1
        extra = rng.standard_normal((self.n, others)) + 1j * rng.standard_normal((self.n, others))
        self.start_block = np.concatenate([start.astype(complex)[:, None], extra], axis=1)

    # ---------------------------------------------------------------- shifts

    def add_shift(self, sigma: float, radius_hint: float) -> Shift:
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
                if self.factorize is not None:
                    factorization = self.factorize(sigma)
                else:
                    factorization = Factorization((self.A - sigma * self.B).tocsr(), self.backend)
                self._check_factorization(factorization)
            except EigenSolverError as error:
                self.factorisation_seconds += time.perf_counter() - start
                self.progress(f"shift at {self.region.format_hz(sigma)} is singular ({error}); moving it")
                sigma += 1e-4 * scale * 10.0**attempt
                last_error = error
                continue
            self.factorisation_seconds += time.perf_counter() - start
            shift = Shift(sigma, factorization)
            self.shifts.append(shift)
            self.progress(
                f"shift {len(self.shifts)} at {self.region.format_hz(sigma)}: factorised n={self.n} "
                f"with {self.backend} in {factorization.factorisation_seconds:.3g} s"
            )
            return shift
        raise EigenSolverError(
            f"A - sigma B stays singular near sigma = {sigma:.6g} rad^2/s^2 ({self.region.format_hz(sigma)}) "
            f"after 4 nudges: is the pencil singular (a DOF with zero rows in both A and B)? "
            f"last error: {last_error}"
        )

    def _check_factorization(self, factorization: Factorization) -> None:
        """UMFPACK/SuperLU raise on an exactly singular matrix; catch a silent inf/nan too."""
        probe = self.start_vector.real
        solution = factorization.solve(probe)
        if not np.all(np.isfinite(solution)):
            raise EigenSolverError("the solve returned non-finite values")

    # ---------------------------------------------------------------- Krylov runs

    def run(self, shift: Shift, k: int) -> int:
        """Find the ``k`` unknown eigenpairs nearest ``shift.sigma``; return how many were added."""
        if self.n <= self.DENSE_DOFS or self.known.count + k >= self.n // 3:
            # ARPACK needs k < n - 1 and works badly when the deflated operator
            # is mostly null; a problem this small is cheaper dense.
            if self.n > self.DENSE_MAX_DOFS:
                raise EigenSolverError(
                    f"{self.known.count + k} eigenpairs requested of an n={self.n} pencil: "
                    "too many for ARPACK and too large for a dense solve; narrow the band"
                )
            self.solve_dense(shift.sigma)
            return 0
        self.runs += 1
        shift.runs += 1
        sigma = shift.sigma
        start = time.perf_counter()
        solves_before = shift.factorization.solve_count
        values, vectors, exhausted = self.nearest_unknown(shift, k)
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
        self.known.add(values, vectors)
        in_band = int(np.count_nonzero(self.band_contains(self.known.values)))
        self.progress(
            f"shift {self.shifts.index(shift) + 1} at {self.region.format_hz(sigma)}: {values.size} new modes "
            f"(k={k}, {solves} solves, {run_seconds:.3g} s), {self.known.count} known, "
            f"{in_band} in band; radius {self.region.format_radius(sigma, shift.trusted_radius)}; "
            f"{self.certified_percent()}"
        )
        if in_band > self.max_modes:
            raise TooManyModesError(
                f"the band holds more than max_modes={self.max_modes} eigenpairs "
                f"({in_band} found so far); raise max_modes or narrow the band"
            )
        return int(values.size)

    def certify(self, shift: Shift) -> None:
        """Nearest eigenvalue still unknown at ``shift``: sets its certified radius.

        Only the dominant eigenvalue of the deflated operator is needed and
        nothing is stored, so two Ritz values at ``CERTIFY_TOL`` suffice (a Krylov-Schur
        run resumes the shift's last decomposition: :meth:`nearest_unknown`).  The
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
        # The nearest unknown eigenvalue sits in a ring of others just outside
        # the trusted disc; where air/PML modes crowd it (as many as the disc
        # holds), a basis of CERTIFY_BASIS_PER_PAIR vectors per pair inside keeps
        # a fresh run from restarting hundreds of times (0.65 m drum sector, 43
        # pairs inside: 418 solves with ARPACK's default 22 vectors, 101 with 65;
        # resuming the shift's decomposition, 1-2).
        crowd = int(self.CERTIFY_BASIS_PER_PAIR * self.count_within(shift, shift.trusted_radius))
        values, _, exhausted = self.nearest_unknown(shift, self.CERTIFY_MODES,
                                                    tol=self.CERTIFY_TOL, basis=crowd)
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
            f"shift {self.shifts.index(shift) + 1} at {self.region.format_hz(shift.sigma)}: certified radius "
            f"{self.region.format_radius(shift.sigma, shift.confirmed_radius)} "
            f"({shift.factorization.solve_count - solves_before} solves, {run_seconds:.3g} s); "
            f"{self.certified_percent()}"
        )

    def certified_percent(self) -> str:
        """``"band N % certified"``: the share of the region inside certified discs."""
        sigmas = np.array([s.sigma for s in self.shifts], dtype=complex)
        radii = np.array([s.confirmed_radius for s in self.shifts])
        fraction = 1.0 if self.exhaustive else self.region.covered_fraction(sigmas, radii)
        return f"band {100.0 * fraction:.0f} % certified"

    def nearest_unknown(self, shift: Shift, k: int, tol: float | None = None,
                        basis: int | None = None):
        """The Krylov run at ``shift``: ``(values, vectors, exhausted)`` of the ``k`` unknown
        eigenpairs nearest it (:func:`copdea_fem.fe.eigen.krylov.nearest_unknown`).

        A Krylov-Schur run keeps its decomposition on the shift (``shift.session``); the
        next run there (more pairs, or the certification) resumes it: the ``c`` pairs it
        converged plus ``k`` more are asked of the *same* operator (deflated by the pairs
        known when the session began), and the pairs among them that are known by now
        (:meth:`KnownPairs.contains`) are dropped.  Whatever the Krylov space holds
        nearer than the farthest of those ``c + k`` is then either known or returned,
        as after a fresh run; a resumed run that returns nothing new (the pairs of other
        shifts fill it) is redone fresh.
        """
        index = self.shifts.index(shift) + 1

        def heartbeat(solves, seconds):
            self.progress(f"shift {index} at {self.region.format_hz(shift.sigma)}: {solves} solves, "
                          f"{seconds:.0f} s ({self.certified_percent()}) ...")

        solve = counting(shift.factorization.solve, heartbeat)
        tol = self.tol if tol is None else tol
        # resume only while the decomposition's basis (3 vectors a pair) stays below n
        block = self.start_block.shape[1]
        if shift.session is not None and \
                basis_size(shift.session[2] + k, block, self.n) < self.n - 1:
            operator, decomposition, converged = shift.session
            operator.solve = solve
            values, vectors, exhausted, decomposition = nearest_unknown(
                operator, converged + k, tol, self.start_block, self.krylov,
                self.real_arithmetic, basis, resume=decomposition, excluded=self.excluded)
            shift.session = (operator, decomposition, converged + k)
            new = ~self.known.contains(values, vectors)
            if np.any(new) or exhausted:
                return values[new], vectors[:, new], exhausted
        operator = DeflatedOperator(self.B, solve, shift.sigma, self.known.values,
                                    self.known.vectors, self.hermitian,
                                    shift.factorization.dtype)
        values, vectors, exhausted, decomposition = nearest_unknown(
            operator, k, tol, self.start_block, self.krylov, self.real_arithmetic, basis,
            excluded=self.excluded)
        shift.session = None if decomposition is None else (operator, decomposition, k)
        return values, vectors, exhausted

    def end_sessions(self) -> None:
        """Free every shift's kept Krylov decomposition (the band is certified)."""
        for shift in self.shifts:
            shift.session = None

    # ---------------------------------------------------------------- dense fallback

    def solve_dense(self, sigma: float | None = None) -> None:
        """All finite eigenpairs, dense: the problem is small.  A Hermitian pencil: eigh.  A
        general one: QZ up to :attr:`DENSE_DOFS` unknowns; above (the dense fallback of a
        crowded band, ``sigma`` the shift that ran into it) the shift-invert standard
        problem :meth:`shift_inverted_dense`, whose Hessenberg QR costs a quarter of QZ's
        (n = 225: 0.06 s against 0.25 s, one BLAS thread)."""
        start = time.perf_counter()
        a, b = self.A.toarray(), self.B.toarray()
        values = vectors = None
        if self.hermitian:
            try:
                values, vectors = scipy.linalg.eigh(a, b)
                values = values.astype(complex)
            except np.linalg.LinAlgError:  # B only semi-definite
                values = None
        elif sigma is not None and self.n > self.DENSE_DOFS:
            values, vectors = self.shift_inverted_dense(a, b, float(np.real(sigma)))
        if values is None:
            alpha_beta, vectors = scipy.linalg.eig(a, b, homogeneous_eigvals=True)
            alpha, beta = alpha_beta
            finite = np.abs(beta) > 1e-13 * np.abs(alpha)  # |lam| < 1e13 |alpha|/|alpha|: finite
            values = alpha[finite] / beta[finite]
            vectors = vectors[:, finite]
            if self.hermitian:
                values = values.real + 0j
        self.iteration_seconds += time.perf_counter() - start
        self.known.clear()
        if self.real_arithmetic:
            if np.iscomplexobj(vectors):  # real and imaginary parts span the eigenspace
                vectors = np.concatenate([vectors.real, vectors.imag], axis=1)
                values = np.concatenate([values, values])
        self.known.add(values, vectors)
        self.exhaustive = True
        for shift in self.shifts:
            shift.trusted_radius = shift.confirmed_radius = math.inf
        self.progress(f"dense solve (n={self.n}): {self.known.count} finite eigenpairs")

    @staticmethod
    def shift_inverted_dense(a: np.ndarray, b: np.ndarray, sigma: float):
        """``(values, vectors)``: the finite eigenpairs of ``a x = lam b x`` from the
        standard problem ``(a - sigma b)^-1 b x = nu x``, ``lam = sigma + 1 / nu`` (the
        same eigenvectors); an infinite eigenvalue (``b`` singular) is ``nu = 0`` and
        dropped with every ``|nu| <= 1e-13 max |nu|`` (``|lam - sigma|`` above 1e13 times
        the nearest's: beyond any band).  ``(None, None)`` where ``a - sigma b`` is
        numerically singular (``sigma`` on an eigenvalue): the caller's QZ then."""
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("error", scipy.linalg.LinAlgWarning)
            try:
                factors = scipy.linalg.lu_factor(a - sigma * b, check_finite=False)
                operator = scipy.linalg.lu_solve(factors, b, check_finite=False)
            except (scipy.linalg.LinAlgWarning, np.linalg.LinAlgError, ValueError):
                return None, None
        if not np.all(np.isfinite(operator)):
            return None, None
        nu, vectors = scipy.linalg.eig(operator, check_finite=False)
        finite = np.abs(nu) > 1e-13 * np.abs(nu).max(initial=0.0)
        return sigma + 1.0 / nu[finite], vectors[:, finite]

    # ---------------------------------------------------------------- planning

    def covered(self, use_confirmed: bool) -> np.ndarray:
        sigmas = np.array([s.sigma for s in self.shifts], dtype=complex)
        radii = np.array([s.confirmed_radius if use_confirmed else s.trusted_radius
                          for s in self.shifts])
        return self.region.uncovered(sigmas, radii)

    def count_within(self, shift: Shift, radius: float) -> int:
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
            # Count grows like radius**d: d = 1 for a Hermitian pencil (Weyl: a
            # membrane's eigenvalue density in lam is uniform on the real axis),
            # d = 3 for a general one, whose air/PML modes fill the disc with a
            # density growing with |lam| (3-D air: N(omega) ~ omega^3; a 0.65 m
            # drum sector: 11 pairs within 2.72e6 rad^2/s^2 of the shift, 42 within
            # 4.07e6, d = 3.3).  Over-asking costs a few solves per pair;
            # under-asking costs another run, which rebuilds a Krylov space (the
            # pairs found are kept, deflation).
            inside = max(self.count_within(nearest, radius), 1)
            expected = inside * ((distance / radius) ** self.count_growth - 1.0)
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
                f"cannot cover the band near f = {self.region.format_hz(point)}: {len(self.shifts)} shifts, "
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
                raise EigenSolverError(f"band not covered after {self.MAX_RUNS} Krylov runs")
            if np.all(self.covered(use_confirmed=True) <= 0):
                self.end_sessions()
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
