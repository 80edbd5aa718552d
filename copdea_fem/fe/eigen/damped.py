"""The damped band: ``T(omega) x = 0``, quadratic/rational in ``omega``, by linearisation.

With structural damping (Rayleigh ``C``, :func:`copdea_fem.fe.linearise.damping_terms`) and
a generalised Maxwell (Prony) series on the material tangent, the free vibrations
``u(t) = Re(x e^{-i omega t})`` of ``M u'' + C u' + K u + sum_j G_j (u - q_j) = 0``,
``tau_j q_j' + q_j = u`` (module doc of :mod:`copdea_fem.fe.linearise`) solve

    T(omega) x = [K - i omega C - omega^2 M + sum_j G_j r_j(omega)] x = 0,
    r_j(omega) = -i omega tau_j / (1 - i omega tau_j) = omega tau_j / (i + omega tau_j),

``omega`` in rad/s, decaying modes ``Im omega < 0`` (``e^{-i omega t}``).  ``K``, ``M``
may be any pencil of the linear path (the dry membrane, or the scaled coupled
membrane-air pencil ``A, B`` of :mod:`copdea_fem.fe.coupled` with ``C`` and ``G_j`` in its
membrane block).

Linearisation (exact, no frequency freezing).  Unknowns ``y = [x; v; z_1 .. z_P]`` with
``v = omega x / s`` (``s`` [rad/s] a fixed scale that gives ``v`` the size of ``x``) and
``z_j = x / (1 - i omega tau_j)`` (the Maxwell branch's internal displacement ``q_j``,
restricted to the rows where ``G_j`` has entries, index set ``S``)::

    row 1:   omega x                 = s v
    row 2:   omega s M v             = (K + sum G_j) x - i s C v - sum_j G_j E z_j
    row 3j:  omega tau_j z_j         = i (E^T x - z_j)

(``E`` puts a vector on ``S`` into the n rows; row 3j is ``(1 - i omega tau_j) z_j = x``
on ``S`` multiplied by ``i``).  Eliminating ``v`` and ``z_j`` from row 2 gives back
``T(omega) x = 0``, so ``A y = omega B y`` has every eigenvalue of ``T`` with its ``x``;
its other eigenvalues are the relaxation poles ``omega = -i / tau_j`` (``x = 0``), which
:func:`copdea_fem.study` keeps out of the band.  Rows 1 and 3j are multiplied by
``c1 = s ||M||`` and ``c3 = ||K||`` (row scaling leaves the eigenpairs and the operator
``(A - sigma B)^-1 B`` unchanged; it only balances the pencil's residuals).

Shift-invert in omega through ONE n-by-n solve per right-hand side.  For a real shift
``sigma`` [rad/s] and ``r = [r1; r2; r3_j]`` (rows unscaled), ``(A - sigma B) y = r`` is::

    row 1:   s v - sigma x = r1                  ->  v   = (r1 + sigma x) / s
    row 3j:  i x_S - (i + sigma tau_j) z_j = r3j ->  z_j = (i x_S - r3j) / (i + sigma tau_j)
    row 2:   T(sigma) x = r2 + (i C + sigma M) r1 - sum_j G_j E r3j / (i + sigma tau_j)

with ``T(sigma) = K - i sigma C - sigma^2 M + sum_j G_j sigma tau_j / (i + sigma tau_j)``
(insert rows 1, 3j into row 2: ``K + sum G_j (1 - i / (i + sigma tau_j)) = K + sum G_j
r_j(sigma)``).  So :class:`ShiftedLinearisation` factorises only ``T(sigma)`` (complex,
n-by-n, any back-end of :class:`Factorization`), as SLEPc's TOAR/NLEIGS do.

The band in the omega-plane.  The band ``f_min <= Re f <= f_max``, ``|Im f| <= h`` is
a rectangle in ``omega = 2 pi f`` (:class:`OmegaBandRegion`, the image is linear so a
cell's slack is 2 pi times its half-diagonal); the shifts are real omegas, every run is
the deflated block Krylov-Schur of :mod:`copdea_fem.fe.eigen.krylov` on the linearised
pencil, and the cover / certification of :class:`copdea_fem.fe.eigen.planner.BandSolver`
work unchanged with discs in omega (radii in rad/s).  :func:`solve_damped_band` returns a
:class:`BandResult` of the usual shape: ``eigenvalues = omega^2``, ``vectors`` the
``x`` part (n rows), residuals of ``T(omega) x``; ``shifts`` are ``sigma^2``
[rad^2/s^2] (so a sweep's shift plan feeds back), ``coverage_radii`` in rad/s.

:func:`solve_structural_band` is the one branch point: without damping terms it is
:func:`solve_band` itself (the linear path and its speed unchanged).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from copdea_fem.fe.eigen.band import BandResult, _normalise, _validate_band, solve_band
from copdea_fem.fe.eigen.errors import EigenInputError, EigenResidualError, TooManyModesError
from copdea_fem.fe.eigen.factorization import Factorization, check_backend_name, require_backend
from copdea_fem.fe.eigen.frequencies import TWO_PI, matrix_norm_estimate
from copdea_fem.fe.eigen.planner import BandSolver
from copdea_fem.fe.eigen.region import BandRegion
from copdea_fem.progress import tagged

logger = logging.getLogger(__name__)


@dataclass
class DampingTerms:
    """The damping of a pencil: viscous ``C`` and Prony branches ``(G_j, tau_j)``.

    ``damping``: ``C`` [N s/m] (n x n, or None); ``relaxation``: list of ``(G_j
    [N/m], tau_j [s])``, ``G_j = g_j K_mat`` (ratio times the material tangent).
    """

    damping: sp.csr_matrix | None = None
    relaxation: list = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return self.damping is None and not self.relaxation

    def embedded(self, index: np.ndarray, size: int) -> "DampingTerms":
        """The same terms in a larger pencil whose unknowns ``index`` are these (coupled)."""
        def embed(matrix):
            coo = sp.coo_matrix(matrix)
            return sp.csr_matrix((coo.data, (index[coo.row], index[coo.col])),
                                 shape=(size, size))
        return DampingTerms(None if self.damping is None else embed(self.damping),
                            [(embed(g), tau) for g, tau in self.relaxation])


def residual_of_t(stiffness, mass, terms: DampingTerms, omegas, vectors) -> np.ndarray:
    """``||T(omega) x|| / (||T||_est ||x||)`` of each pair, ``||T||_est = ||K|| + |omega|
    ||C|| + |omega|^2 ||M|| + sum |r_j| ||G_j||`` (norms: :func:`matrix_norm_estimate`)."""
    k_norm, m_norm = matrix_norm_estimate(stiffness), matrix_norm_estimate(mass)
    c_norm = matrix_norm_estimate(terms.damping) if terms.damping is not None else 0.0
    g_norms = [matrix_norm_estimate(g) for g, _ in terms.relaxation]
    out = np.zeros(len(omegas))
    for k, omega in enumerate(omegas):
        x = vectors[:, k]
        value = stiffness @ x - omega**2 * (mass @ x)
        scale = k_norm + abs(omega) ** 2 * m_norm
        if terms.damping is not None:
            value = value - 1j * omega * (terms.damping @ x)
            scale += abs(omega) * c_norm
        for (g, tau), g_norm in zip(terms.relaxation, g_norms):
            ratio = omega * tau / (1j + omega * tau)
            value = value + ratio * (g @ x)
            scale += abs(ratio) * g_norm
        out[k] = np.linalg.norm(value) / (scale * max(np.linalg.norm(x), 1e-300))
    return out


class OmegaBandRegion(BandRegion):
    """The band as a region of the omega-plane (rad/s): the rectangle ``2 pi ([f_lo, f_hi]
    x [-h, h])`` in cells, each with the slack ``2 pi`` x its half-diagonal (the map
    ``f -> omega`` is linear), for :class:`BandSolver`'s cover test."""

    def __init__(self, f_min, f_max, imag_max_hz, margin_hz):
        self.hermitian = False
        f_lo, f_hi = max(f_min - margin_hz, 0.0), f_max + margin_hz
        h = imag_max_hz + margin_hz
        re_edges = np.linspace(f_lo, f_hi, self.GRID_CELLS_RE + 1)
        im_edges = np.linspace(-h, h, self.GRID_CELLS_IM + 1)
        re_c = 0.5 * (re_edges[1:] + re_edges[:-1])
        im_c = 0.5 * (im_edges[1:] + im_edges[:-1])
        self.centres = TWO_PI * (re_c[:, None] + 1j * im_c[None, :]).ravel()
        half_diagonal = 0.5 * math.hypot(re_edges[1] - re_edges[0], im_edges[1] - im_edges[0])
        self.slack = np.full(self.centres.shape, TWO_PI * half_diagonal)
        self.real_extent = (float(self.centres.real.min() - self.slack.max()),
                            float(self.centres.real.max() + self.slack.max()))
        self.scale = max(abs(self.real_extent[0]), abs(self.real_extent[1]),
                         float(np.max(np.abs(self.centres))))

    @staticmethod
    def format_hz(point) -> str:
        f = complex(point) / TWO_PI
        if abs(f.imag) <= 1e-9 * abs(f):
            return f"{f.real:.6g} Hz"
        return f"{f.real:.6g}{f.imag:+.4g}i Hz"

    @staticmethod
    def format_radius(sigma, radius) -> str:
        if not np.isfinite(radius):
            return "inf"
        return (f"{radius:.4g} rad/s (real axis {(sigma - radius) / TWO_PI:.4g}.."
                f"{(sigma + radius) / TWO_PI:.4g} Hz)")


class LinearisedPencil:
    """``A y = omega B y`` of ``T(omega)`` (module doc), and the shifted solves through T."""

    def __init__(self, stiffness, mass, terms: DampingTerms, scale: float):
        self.K, self.M = sp.csr_matrix(stiffness), sp.csr_matrix(mass)
        self.C = None if terms.damping is None else sp.csr_matrix(terms.damping)
        self.n = n = self.K.shape[0]
        self.s = float(scale)
        self.c1 = self.s * max(matrix_norm_estimate(self.M), 1e-300)
        self.c3 = max(matrix_norm_estimate(self.K), 1e-300)
        self.branches = []            # (G restricted to its support S, S, tau)
        for g, tau in terms.relaxation:
            g = sp.csr_matrix(g)
            support = np.flatnonzero(g.getnnz(axis=1) + g.getnnz(axis=0) > 0)
            self.branches.append((g[support][:, support].tocsr(), support, float(tau)))
        self.offsets = np.cumsum([0, n, n] + [s.size for _, s, _ in self.branches])
        self.size = int(self.offsets[-1])
        identity = sp.identity(n, format="csr")
        k_tilde = self.K.astype(complex)
        for g_s, support, _ in self.branches:
            k_tilde = k_tilde + self._place(g_s, support, support)
        c_block = None if self.C is None else -1j * self.s * self.C
        rows_a = [[None, self.c1 * self.s * identity] + [None] * len(self.branches),
                  [k_tilde, c_block] + [-self._columns(g_s, support)
                                        for g_s, support, _ in self.branches]]
        rows_b = [[self.c1 * identity, None] + [None] * len(self.branches),
                  [None, self.s * self.M] + [None] * len(self.branches)]
        for j, (g_s, support, tau) in enumerate(self.branches):
            pick = sp.csr_matrix((np.ones(support.size), (np.arange(support.size), support)),
                                 shape=(support.size, n))
            eye = sp.identity(support.size, format="csr")
            row_a, row_b = [1j * self.c3 * pick, None], [None, None]
            for k in range(len(self.branches)):
                row_a.append(-1j * self.c3 * eye if k == j else None)
                row_b.append(tau * self.c3 * eye if k == j else None)
            rows_a.append(row_a)
            rows_b.append(row_b)
        if c_block is None:      # bmat needs every block row/column to hold something
            rows_a[1][1] = sp.csr_matrix((n, n), dtype=complex)
        self.A = sp.bmat(rows_a, format="csr").astype(complex)
        self.B = sp.bmat(rows_b, format="csr").astype(complex)

    def _place(self, block, rows, columns):
        coo = sp.coo_matrix(block)
        return sp.csr_matrix((coo.data, (rows[coo.row], columns[coo.col])),
                             shape=(self.n, self.n))

    def _columns(self, block, support):
        """``G_j E``: the n x |S| matrix of a branch's block (rows put back at ``S``)."""
        coo = sp.coo_matrix(block)
        return sp.csr_matrix((coo.data, (support[coo.row], coo.col)),
                             shape=(self.n, support.size))

    def t_matrix(self, sigma: float) -> sp.csr_matrix:
        """``T(sigma) = K - i sigma C - sigma^2 M + sum_j G_j sigma tau_j/(i + sigma tau_j)``."""
        matrix = self.K.astype(complex) - sigma**2 * self.M
        if self.C is not None:
            matrix = matrix - 1j * sigma * self.C
        for g_s, support, tau in self.branches:
            matrix = matrix + (sigma * tau / (1j + sigma * tau)) * self._place(g_s, support,
                                                                              support)
        return matrix.tocsr()


class ShiftedLinearisation:
    """``(A - sigma B)^-1`` of a :class:`LinearisedPencil` by one solve with ``T(sigma)``
    per right-hand side (module doc); the factorisation interface of :class:`BandSolver`
    (``solve`` of 1-D/2-D right-hand sides, ``dtype``, counts, seconds)."""

    def __init__(self, pencil: LinearisedPencil, sigma: float, factorize_t):
        self.pencil, self.sigma = pencil, float(sigma)
        start = time.perf_counter()
        self.factorization = factorize_t(self.sigma)
        self.factorisation_seconds = time.perf_counter() - start
        self.dtype = np.dtype(complex)
        self.is_complex = True
        self.block_solve_count = 0

    @property
    def solve_count(self) -> int:
        return self.factorization.solve_count

    def solve(self, rhs) -> np.ndarray:
        rhs = np.asarray(rhs)
        one = rhs.ndim == 1
        rhs = rhs[:, None] if one else rhs
        p, sigma = self.pencil, self.sigma
        n, offsets = p.n, p.offsets
        self.block_solve_count += 1
        r1 = rhs[:n] / p.c1
        r2 = rhs[n:2 * n].astype(complex)
        right = r2 + sigma * (p.M @ r1)
        if p.C is not None:
            right = right + 1j * (p.C @ r1)
        r3 = []
        for j, (g_s, support, tau) in enumerate(p.branches):
            part = rhs[offsets[2 + j]:offsets[3 + j]] / p.c3
            r3.append(part)
            right[support] -= g_s @ (part / (1j + sigma * tau))
        x = self.factorization.solve(right)
        x = x[:, None] if x.ndim == 1 else x
        out = np.empty((p.size, rhs.shape[1]), dtype=complex)
        out[:n] = x
        out[n:2 * n] = (r1 + sigma * x) / p.s
        for j, (g_s, support, tau) in enumerate(p.branches):
            out[offsets[2 + j]:offsets[3 + j]] = (1j * x[support] - r3[j]) / (1j + sigma * tau)
        return out[:, 0] if one else out


def solve_damped_band(stiffness, mass, f_min: float, f_max: float, terms: DampingTerms, *,
                      backend: str = "umfpack", max_modes: int = 200,
                      residual_tol: float = 1e-6, check: bool = True,
                      max_imag_hz: float | None = None, normalization_matrix=None,
                      max_modes_per_shift: int = 80, initial_shifts=None,
                      start_modes: int | None = None, factorize_t=None,
                      hermitian=None, factorize=None, krylov: str = "krylov-schur"
                      ) -> BandResult:
    """All eigenpairs of ``T(omega) x = 0`` (module doc) with ``f = omega / (2 pi)`` in the
    band ``f_min <= Re f <= f_max``, ``|Im f| <= max_imag_hz`` (default ``0.25 f_max``).

    Parameters as :func:`solve_band` (``stiffness, mass`` = its ``A, B``), plus ``terms``
    (:class:`DampingTerms`, not empty) and ``factorize_t(sigma)`` -> a
    :class:`Factorization`-like object of ``T(sigma)`` (default: ``Factorization`` of
    :meth:`LinearisedPencil.t_matrix` with ``backend``).  ``initial_shifts`` are the
    linear path's ``(sigma [rad^2/s^2], k)``, taken at ``sqrt(sigma)``.  ``hermitian``
    chooses the normalisation only (``x^H M x = 1`` if True); ``factorize`` (the linear
    pencil's hook) is not used: T(sigma) is another matrix.

    Returns
    -------
    BandResult
        ``eigenvalues = omega^2`` [rad^2/s^2], ``freq_hz + i freq_im_hz = omega/(2 pi)``,
        ``vectors`` the ``x`` part, ``residuals`` of ``T(omega) x`` (:func:`residual_of_t`),
        ``shifts = sigma^2``, ``coverage_radii`` [rad/s] in the omega-plane.
    """
    total_start = time.perf_counter()
    f_min, f_max = _validate_band(f_min, f_max)
    check_backend_name(backend)
    require_backend(backend)
    if terms is None or terms.empty:
        raise EigenInputError("solve_damped_band needs damping terms (C or Prony branches)")
    if max_imag_hz is None:
        max_imag_hz = 0.25 * f_max
    if not (np.isfinite(max_imag_hz) and max_imag_hz >= 0):
        raise EigenInputError(f"max_imag_hz={max_imag_hz!r} Hz must be a finite number >= 0")
    for _, tau in terms.relaxation:
        pole = 1.0 / (TWO_PI * tau)           # omega = -i/tau: Re f = 0, Im f = -pole
        if f_min <= 1e-9 * f_max and pole <= max_imag_hz * (1 + 1e-9):
            raise EigenInputError(
                f"the relaxation pole Im f = -{pole:.4g} Hz (tau = {tau:.4g} s) lies in the "
                f"band (f_min = {f_min:g} Hz, |Im f| <= {max_imag_hz:.4g} Hz): raise f_min")
    stiffness, mass = sp.csr_matrix(stiffness), sp.csr_matrix(mass)
    omega_scale = TWO_PI * 0.5 * (f_min + f_max)
    pencil = LinearisedPencil(stiffness, mass, terms, omega_scale)
    if factorize_t is None:
        def factorize_t(sigma):
            return Factorization(pencil.t_matrix(sigma).tocsc(), backend)

    edge = 1e-9 * f_max

    def band_contains(omegas):
        f = np.asarray(omegas, dtype=complex) / TWO_PI
        return ((f.real >= f_min - edge) & (f.real <= f_max + edge)
                & (np.abs(f.imag) <= max_imag_hz + edge))

    excluded = None
    if terms.relaxation:
        # The relaxation spectrum (internal variables, Re omega ~ 0): one eigenvalue per
        # unknown of each branch, crowded near -i/(tau_max (1 + sum g)) .. -i/tau_min.  It is
        # outside the band (study check), so the Krylov runs never want it (a cone of
        # +-5 % about that stretch of the imaginary axis): a disc then certifies every
        # eigenvalue but those, which keeps the band's cells certified.
        taus = [tau for _, tau in terms.relaxation]
        ratio = sum(matrix_norm_estimate(g) for g, _ in terms.relaxation) / max(
            matrix_norm_estimate(stiffness), 1e-300)
        lowest = 1.0 / (max(taus) * (1.0 + max(ratio, 0.0) + 1.0))
        highest = 1.0 / min(taus)

        def excluded(omegas):
            omegas = np.asarray(omegas, dtype=complex)
            depth = -omegas.imag
            return ((depth >= 0.5 * lowest) & (depth <= 2.0 * highest)
                    & (np.abs(omegas.real) <= 0.05 * depth) & ~band_contains(omegas))

    region = OmegaBandRegion(f_min, f_max, max_imag_hz, 1e-3 * (f_max - f_min))
    plan = None
    if initial_shifts is not None:
        plan = [(math.sqrt(max(float(sigma), 0.0)), int(k)) for sigma, k in initial_shifts]
        plan = [(sigma if sigma > 0 else region.first_shift(), k) for sigma, k in plan]
    krylov_tol = max(min(1e-10, 0.01 * residual_tol), 1e-14)
    solver = BandSolver(pencil.A, pencil.B, region, backend=backend, hermitian=False,
                        max_modes=max_modes, max_modes_per_shift=int(max_modes_per_shift),
                        band_contains=band_contains, tol=krylov_tol,
                        initial_shifts=plan, start_modes=start_modes,
                        factorize=lambda sigma: ShiftedLinearisation(pencil, sigma, factorize_t),
                        krylov=krylov, excluded=excluded,
                        # dry (hermitian=True): the modes lie along the real omega axis,
                        # N(omega) ~ omega^2 counts 4 sigma r within r of sigma: d = 1
                        count_growth=1.0 if hermitian else None)
    solver.solve()
    omegas, vectors = solver.known.values, solver.known.vectors
    selected = band_contains(omegas)
    omegas, vectors = omegas[selected], vectors[:pencil.n, selected]
    if omegas.size > max_modes:
        raise TooManyModesError(
            f"the band holds {omegas.size} eigenpairs, more than max_modes={max_modes}; "
            "raise max_modes or narrow the band")
    weight = normalization_matrix if normalization_matrix is not None else (
        mass if hermitian else None)
    vectors = _normalise(vectors, None if weight is None else sp.csr_matrix(weight))
    order = np.lexsort((omegas.imag, omegas.real))
    omegas, vectors = omegas[order], vectors[:, order]
    residuals = residual_of_t(stiffness, mass, terms, omegas, vectors)
    sigmas = np.array([s.sigma for s in solver.shifts], dtype=float)
    result = BandResult(
        eigenvalues=(omegas**2).astype(complex), freq_hz=omegas.real / TWO_PI,
        freq_im_hz=omegas.imag / TWO_PI, vectors=vectors, residuals=residuals,
        shifts=sigmas**2, shift_freq_hz=sigmas / TWO_PI,
        coverage_radii=np.array([s.confirmed_radius for s in solver.shifts], dtype=float),
        factorisation_seconds=solver.factorisation_seconds,
        iteration_seconds=solver.iteration_seconds,
        total_seconds=time.perf_counter() - total_start,
        n_factorisations=len(solver.shifts),
        n_solves=sum(s.factorization.solve_count for s in solver.shifts),
        n_block_solves=sum(s.factorization.block_solve_count for s in solver.shifts),
        hermitian=False, backend=backend, residual_tol=float(residual_tol))
    logger.info(tagged(f"damped band {f_min:g}..{f_max:g} Hz: {len(result)} modes, "
                       f"{result.n_factorisations} factorisations of T(sigma) "
                       f"({result.factorisation_seconds:.3g} s), {result.n_solves} solves"))
    if check and np.any(~result.residual_ok):
        worst = int(np.argmax(result.residuals))
        raise EigenResidualError(
            f"{np.count_nonzero(~result.residual_ok)} eigenpair(s) above "
            f"residual_tol={residual_tol:g}; worst: f = {result.freq_hz[worst]:.6g}"
            f"{result.freq_im_hz[worst]:+.3g}i Hz with relative residual "
            f"{result.residuals[worst]:.3g}")
    return result


def solve_structural_band(stiffness, mass, f_min, f_max, terms: DampingTerms | None = None,
                          damped_imag_hz: float | None = None, **options) -> BandResult:
    """THE branch between the linear and the damped eigen step: :func:`solve_band` on
    ``A x = omega^2 B x`` when ``terms`` is None or empty (unchanged linear path), else
    :func:`solve_damped_band` (``factorize`` then ignored: the damped solve factorises
    ``T(sigma)``).  A Hermitian dry call (``hermitian=True``) keeps ``x^H M x = 1``;
    ``damped_imag_hz`` is the damped band's half-height in ``Im f`` [Hz] when ``options``
    has no ``max_imag_hz`` (a dry linear call has none: its band is the real axis)."""
    if terms is None or terms.empty:
        return solve_band(stiffness, mass, f_min, f_max, **options)
    if options.get("max_imag_hz") is None and damped_imag_hz is not None:
        options["max_imag_hz"] = damped_imag_hz
    return solve_damped_band(stiffness, mass, f_min, f_max, terms, **options)
