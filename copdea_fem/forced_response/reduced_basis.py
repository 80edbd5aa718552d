r"""The forced response by a reduced basis: rational Krylov / multi-point moment matching of
``T(omega)`` over the chirp band (``response.method: reduced``).

The problem
-----------
Every line of the direct path (:meth:`copdea_fem.fe.forced.harmonic.ForcedOrder.direct`)
solves, on the scaled coupled pencil (membrane + air + PML),

    T(omega) x = F,     T(omega) = A - i eta K_el - omega^2 B - i omega C
                                     + sum_j r_j(omega) G_j,
    r_j(omega) = -i omega tau_j / (1 - i omega tau_j)                              (1)

(``A, B`` the coupled pencil with its ALE air and PML, ``eta`` ``membrane.loss_factor``,
``C`` the Rayleigh damping, ``G_j`` the Prony branches: :mod:`.harmonic`).  One sparse
factorisation per line is what makes the direct path slow on the 3-D engine (24572 complex
unknowns in the baffle, 800 lines).

Projection
----------
With ``V`` (n x k, orthonormal columns) the reduced solution is the Galerkin one::

    x_r(omega) = V y(omega),    V^H T(omega) V y = V^H F.                            (2)

Every term of (1) is a fixed matrix times a scalar function of omega, so
``V^H T(omega) V = sum_p c_p(omega) V^H P_p V`` is assembled once (``P_p`` in ``A, B, K_el,
C, G_j``; ``c_p`` = 1, -omega^2, -i eta, -i omega, r_j(omega)) and each line is a dense
k x k solve.  Nothing of the damping model is approximated: (2) uses the same ``T(omega)``
as the direct path, whatever ``C``, ``G_j`` and ``tau_j``; the only error is the basis.

Exactness at the shifts and moment matching.  If ``x(sigma) = T(sigma)^-1 F`` lies in
``span V`` (``x(sigma) = V z``) then ``z`` solves (2) at ``sigma`` (insert it:
``V^H T V z = V^H T x = V^H F``), so ``x_r(sigma) = x(sigma)`` whenever ``V^H T(sigma) V``
is non-singular.  Differentiating (2) and ``T x = F`` k times,
``sum_i binom(k, i) T^(i) x^(k-i) = 0`` and the same for ``V y``: by induction, if
``x^(0..k)(sigma)`` all lie in ``span V`` then ``x_r^(i)(sigma) = x^(i)(sigma)``, i <= k
(the reduced model matches k + 1 moments of the Taylor series of ``x`` at ``sigma``).

The moments come from the exact linearisation of (1) of :mod:`copdea_fem.fe.eigen.damped`:
with ``L y = omega N y`` its pencil (``y = [x; omega x / s; z_j]``), ``T(omega) x = F`` is
``(L - omega N) y = b``, ``b = [0; F; 0]`` (row 2 of the linearisation is ``T(omega) x``
once ``v`` and the branch variables ``z_j = x / (1 - i omega tau_j)`` are eliminated), and

    y(sigma + h) = (L - sigma N - h N)^-1 b = sum_k h^k S^k y_0,
    S = (L - sigma N)^-1 N,   y_0 = (L - sigma N)^-1 b.

So the Krylov space ``K_m(S, y_0)`` holds the first m Taylor coefficients of ``y`` and its
``x`` rows those of ``x(omega)``.  It is built by Arnoldi (orthonormal, not the explicit,
ill-conditioned powers ``S^k y_0``), and a shifted solve with ``L - sigma N`` costs one solve
with the n x n ``T(sigma)`` (:class:`copdea_fem.fe.eigen.damped.ShiftedLinearisation`): one
sparse factorisation per shift, m cheap solves.  Shift-invert Krylov spaces also capture
the poles (modes) nearest to ``sigma`` first, so a handful of shifts spread over the band
resolves every resonance between them.

Adaptivity.  Shifts start at ``initial`` points spread over the lines; after each round the
relative residual ``rho(omega) = ||T(omega) x_r - F|| / ||F||`` is computed at every line
(exactly and cheaply: ``T(omega) V y - F = W z(omega)`` with ``W = [P_1 V, P_2 V, ..., F]``,
``z = [c_1 y; c_2 y; ...; -1]``, and ``||W z|| = ||R z||`` for ``W = Q R``) and a new shift
goes to the line of the largest residual, until ``max rho <= tol`` (``response.reduced_tol``)
or ``max_shifts``.  ``rho`` bounds the error through ``||T^-1||``: near a lightly damped
resonance the same residual means a larger error, which the benchmark and tests measure
against the direct path.

The paper's modal damping on the reduced basis (``response.method: reduced_modal``)
-------------------------------------------------------------------------------------
The paper damps modal coordinates (Sect. 5.3, eq. 19: ``b_j = (b/m)_j m_j``), which no
matrix of (1) holds; the modal path (:mod:`copdea_fem.fe.forced.harmonic`, "Modal
superposition") puts ``-i omega lambda_j (b/m)_j m_j`` in each mode's denominator.  The
reduced model is damped the same way, in *its* modes: without a loss of its own (1) is
``A - omega^2 B`` and its projection ``A_r - omega^2 B_r`` (``A_r = V^H A V``, k x k) has
right and left eigenvectors ``A_r z_i = lambda_i B_r z_i``, ``w_i^H A_r = lambda_i w_i^H B_r``
(``w_i^H B_r z_j = 0`` for ``lambda_i != lambda_j``), so the reduced solution of (2) is,
exactly, the sum over all k of them::

    x_r(omega) = sum_i V z_i  phi_i / (lambda_i - omega^2),   phi_i = w_i^H V^H F / (w_i^H B_r z_i).

Each structural mode gets the modal path's damping term divided by its ``n_i``::

    x_r(omega) = sum_i V z_i  phi_i / (lambda_i - omega^2 - i omega (b/m)_i s_i),
    s_i = lambda_i m_i / n_i                                                        (3)

with ``m_i = u_i^T M_s u_i``, ``n_i = y_i^T B x_i`` of the Ritz vector ``x_i = V z_i`` and its
left vector ``y_i = (lambda_i u_i, beta p_i^/alpha)`` (as :class:`~copdea_fem.fe.forced.harmonic.ModalBasis`):
``s_i`` is the mode's membrane share of the kinetic energy, so the term is eq. (19)'s
``(b/m) m/(m + m_ad)``.  Where ``x_i`` is an eigenvector of the full pencil (Ritz residual
~0), (3)'s term of mode i is the modal path's; the modes the basis does not resolve are in
(2) through the moment matching, where the modal path has its residual correction.  Modes
are damped only where converged (relative residual <= ``eigen.residual_tol``, as the
eigen solver accepts a pair); a structural Ritz mode inside the lines that is not
converged gets a shift of its own (:func:`ritz_modes`' caller,
:func:`copdea_fem.forced_response.run.reduced_modal_solution`).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from copdea_fem.fe.eigen.damped import DampingTerms, LinearisedPencil, ShiftedLinearisation

logger = logging.getLogger(__name__)

#: Arnoldi steps (basis vectors) per shift, shifts at the start, most shifts.
STEPS_PER_SHIFT, INITIAL_SHIFTS, MAX_SHIFTS = 40, 1, 16
#: A new basis vector is kept when its part orthogonal to the basis exceeds this (relative).
DEFLATION_TOL = 1e-10


def _pieces(forced, loss_factor: float):
    """``(matrix, c(omega), name)`` of every term of T(omega) (module doc, eq. 1)."""
    coupled = forced.coupled
    pieces = [(coupled.stiffness, lambda w: 1.0, "A"), (coupled.mass, lambda w: -w ** 2, "B")]
    if loss_factor:
        pieces.append((forced.elastic, lambda w: -1j * loss_factor, "K_el"))
    terms = forced.damping
    if terms is not None:
        if terms.damping is not None:
            pieces.append((terms.damping, lambda w: -1j * w, "C"))
        for j, (tangent, tau) in enumerate(terms.relaxation):
            pieces.append((tangent, lambda w, tau=tau: -1j * w * tau / (1 - 1j * w * tau),
                           f"G_{j + 1}"))
    return pieces


@dataclass
class ReducedBasis:
    """The reduced model (module doc): orthonormal ``vectors`` V (n, k), the projected terms
    ``V^H P_p V`` with their coefficient functions, ``V^H F``; the shifts [Hz], the final
    residual per line, and counts for the report."""

    vectors: np.ndarray
    projected: list                  # [(k x k, c(omega))]
    forcing: np.ndarray
    shifts_hz: list
    residuals: np.ndarray            # rho per line of the build (module doc)
    frequency_hz: np.ndarray         # the lines it was built on
    tolerance: float
    seconds: dict = field(default_factory=dict)
    solves: int = 0
    line_coefficients: np.ndarray | None = None     # y per volt on ``frequency_hz``

    @property
    def size(self) -> int:
        return self.vectors.shape[1]

    def coefficients(self, frequency_hz) -> np.ndarray:
        """y(omega) per volt (lines, k): the small dense solves of eq. (2), batched."""
        frequency_hz = np.atleast_1d(np.asarray(frequency_hz, float))
        out = np.empty((frequency_hz.size, self.size), dtype=complex)
        for chunk in range(0, frequency_hz.size, 64):
            omega = 2 * math.pi * frequency_hz[chunk:chunk + 64]
            matrices = sum(np.array([c(w) for w in omega], complex)[:, None, None]
                           * block[None] for block, c in self.projected)
            rhs = np.broadcast_to(self.forcing[:, None], (omega.size, self.size, 1))
            try:
                out[chunk:chunk + 64] = np.linalg.solve(matrices, rhs)[..., 0]
            except np.linalg.LinAlgError:      # a reduced pole on a line: least squares
                out[chunk:chunk + 64] = [np.linalg.lstsq(m, self.forcing, rcond=None)[0]
                                         for m in matrices]
        return out

    def summary(self) -> dict:
        """For ``response.json``: size, shifts [Hz], largest line residual, tolerance."""
        return {"vectors": int(self.size), "shifts_hz": [float(f) for f in self.shifts_hz],
                "max_residual": float(self.residuals.max()), "tolerance": self.tolerance,
                "solves": int(self.solves)}

    def response(self, frequency_hz) -> np.ndarray:
        """Scaled solutions per volt (n, lines), as
        :meth:`copdea_fem.fe.forced.harmonic.ForcedOrder.direct`."""
        return self.vectors @ self.coefficients(frequency_hz).T


class _Builder:
    """The growing basis, its projections and the residual factor R (module doc)."""

    def __init__(self, forced, loss_factor):
        self.forced = forced
        self.pieces = _pieces(forced, loss_factor)
        self.force = np.asarray(forced.forcing, complex)
        self.force_norm = max(float(np.linalg.norm(self.force)), 1e-300)
        n = forced.size
        self.vectors = np.zeros((n, 0), dtype=complex)
        self.images = [np.zeros((n, 0), dtype=complex) for _ in self.pieces]   # P_p V
        self.stiffness = (forced.coupled.stiffness - 1j * loss_factor * forced.elastic
                          if loss_factor else forced.coupled.stiffness)
        terms = forced.damping if forced.damping is not None else DampingTerms()
        self.pencil = None
        self.terms = terms
        self.factorisation_seconds = 0.0

    def add(self, candidates: np.ndarray) -> int:
        """Orthonormalise the columns of ``candidates`` against the basis (twice, classical
        Gram-Schmidt) and keep those that are not (numerically) in it; returns how many."""
        start = self.vectors.shape[1]
        block = np.asfortranarray(candidates, dtype=complex)
        norms0 = np.linalg.norm(block, axis=0)
        kept = []
        basis = np.asfortranarray(self.vectors)
        for j in range(block.shape[1]):
            if norms0[j] == 0:
                continue
            v = block[:, j].copy()
            for _ in range(2):
                v -= basis @ (basis.conj().T @ v)
                if kept:
                    new = block[:, kept]
                    v -= new @ (new.conj().T @ v)
            norm = np.linalg.norm(v)
            if norm <= DEFLATION_TOL * norms0[j]:
                continue
            block[:, j] = v / norm
            kept.append(j)
        new = block[:, kept]
        self.vectors = np.asfortranarray(np.hstack([self.vectors, new]))
        for p, (matrix, _, _) in enumerate(self.pieces):
            self.images[p] = np.asfortranarray(np.hstack([self.images[p], matrix @ new]))
        return self.vectors.shape[1] - start

    def krylov(self, sigma: float, steps: int, scale: float) -> tuple[np.ndarray, int]:
        """The x rows of an orthonormal basis of K_steps(S, y_0) at the real shift ``sigma``
        [rad/s] (module doc); one factorisation of T(sigma), ``steps`` solves."""
        from copdea_fem.fe.eigen import Factorization
        if self.pencil is None:
            self.pencil = LinearisedPencil(self.stiffness, self.forced.coupled.mass, self.terms,
                                           scale)
        pencil = self.pencil
        shifted = ShiftedLinearisation(
            pencil, sigma, lambda s: Factorization(pencil.t_matrix(s).tocsc(),
                                                   self.forced.backend))
        self.factorisation_seconds += shifted.factorisation_seconds
        n = pencil.n
        rhs = np.zeros(pencil.size, dtype=complex)
        rhs[n:2 * n] = self.force                   # b = [0; F; 0] (row 2 unscaled)
        w = shifted.solve(rhs)
        basis = np.zeros((pencil.size, steps), dtype=complex, order="F")
        solves = 1
        for k in range(steps):
            for _ in range(2):
                w -= basis[:, :k] @ (basis[:, :k].conj().T @ w)
            norm = np.linalg.norm(w)
            if norm == 0 or not np.isfinite(norm):
                basis = basis[:, :k]
                break
            basis[:, k] = w / norm
            if k + 1 < steps:
                w = shifted.solve(pencil.B @ basis[:, k])
                solves += 1
        return basis[:n], solves

    def reduced(self):
        v_h = self.vectors.conj().T
        projected = [(v_h @ image, c) for image, (_, c, _) in zip(self.images, self.pieces)]
        return projected, v_h @ self.force

    def residuals(self, frequency_hz, coefficients) -> np.ndarray:
        """rho(omega) per line (module doc): ``||R z|| / ||F||``."""
        w = np.column_stack(self.images + [self.force[:, None]])
        r = scipy.linalg.qr(w, mode="r", check_finite=False)[0]
        r = r[:min(r.shape)]
        k = self.vectors.shape[1]
        out = np.empty(len(frequency_hz))
        for line, f in enumerate(frequency_hz):
            omega = 2 * math.pi * float(f)
            z = np.concatenate([c(omega) * coefficients[line] for _, c, _ in self.pieces]
                               + [np.array([-1.0])])
            assert z.size == len(self.pieces) * k + 1
            out[line] = np.linalg.norm(r @ z) / self.force_norm
        return out


def build_reduced_basis(forced, frequency_hz, loss_factor: float = 0.0, tol: float = 1e-7,
                        steps: int = STEPS_PER_SHIFT, initial: int = INITIAL_SHIFTS,
                        max_shifts: int = MAX_SHIFTS, shifts_hz=None,
                        extra_shifts_hz=()) -> ReducedBasis:
    """The adaptive reduced model of ``forced`` (a
    :class:`copdea_fem.fe.forced.harmonic.ForcedOrder`) on the lines
    ``frequency_hz`` [Hz] (module doc).

    ``shifts_hz``: fixed shifts [Hz] instead of the adaptive choice (tests);
    ``extra_shifts_hz``: shifts [Hz] added to the adaptive start (the modes that
    :func:`ritz_modes` found unconverged); ``tol``: the largest accepted relative residual;
    ``steps``: Arnoldi steps per shift.
    """
    from copdea_fem.progress import single_threaded_blas
    frequency_hz = np.atleast_1d(np.asarray(frequency_hz, float))
    if frequency_hz.size == 0:
        raise ValueError("no lines for the reduced basis; allowed: at least one frequency")
    with single_threaded_blas():
        return _build(forced, frequency_hz, loss_factor, tol, steps, initial, max_shifts,
                      shifts_hz, [float(f) for f in extra_shifts_hz])


def _build(forced, frequency_hz, loss_factor, tol, steps, initial, max_shifts, shifts_hz,
           extra_shifts_hz):
    timings = {"factorise_and_krylov": 0.0, "project": 0.0, "residual": 0.0}
    builder = _Builder(forced, loss_factor)
    f_lo, f_hi = float(frequency_hz.min()), float(frequency_hz.max())
    scale = 2 * math.pi * max(0.5 * (f_lo + f_hi), 1.0)
    if shifts_hz is not None:
        plan, adaptive = [float(f) for f in shifts_hz], False
    else:
        # equal shares of f^2: a membrane's modes crowd towards the top of the band (their
        # count grows like f^2), and so do the vectors a shift needs
        share = (np.arange(initial) + 0.5) / initial
        plan, adaptive = list(np.sqrt(f_lo ** 2 + share * (f_hi ** 2 - f_lo ** 2))), True
        plan += extra_shifts_hz
    shifts, solves = [], 0
    for _ in range(max_shifts):          # each round: the plan, then one shift at a time
        added = 0
        for f in plan:
            start = time.perf_counter()
            krylov, count = builder.krylov(2 * math.pi * f, steps, scale)
            kept = builder.add(krylov)
            added += kept
            solves += count
            shifts.append(f)
            timings["factorise_and_krylov"] += time.perf_counter() - start
            logger.info(f"reduced basis: shift {len(shifts)} at {f:.2f} Hz, {kept} new vectors "
                        f"({builder.vectors.shape[1]} in all)")
        if builder.vectors.shape[1] == 0:
            raise ValueError("the voltage forcing vanishes on every line (no basis vector); "
                             "allowed: load.voltage > 0 with a driven membrane")
        start = time.perf_counter()
        projected, forcing = builder.reduced()
        model = ReducedBasis(builder.vectors, projected, forcing, list(shifts), np.empty(0),
                             frequency_hz, tol)
        coefficients = model.coefficients(frequency_hz)
        timings["project"] += time.perf_counter() - start
        start = time.perf_counter()
        rho = builder.residuals(frequency_hz, coefficients)
        timings["residual"] += time.perf_counter() - start
        worst = int(np.argmax(rho))
        logger.info(f"reduced basis: {builder.vectors.shape[1]} vectors, {len(shifts)} shifts, "
                    f"largest residual {rho[worst]:.2e} at {frequency_hz[worst]:.2f} Hz "
                    f"(tolerance {tol:.1e})")
        if not adaptive or rho[worst] <= tol or len(shifts) >= max_shifts or added == 0:
            break
        plan = [float(frequency_hz[worst])]
    if adaptive and rho[worst] > tol:
        logger.warning(f"reduced basis: largest residual {rho[worst]:.2e} above the tolerance "
                       f"{tol:.1e} after {len(shifts)} shifts (at {frequency_hz[worst]:.2f} Hz)")
    timings["factorisation"] = builder.factorisation_seconds
    model.residuals, model.seconds, model.solves = rho, timings, solves
    model.line_coefficients = coefficients
    return model


@dataclass
class RitzModes:
    """The reduced model without a loss of its own, diagonalised in its k modes and damped
    per mode (module doc, eq. 3): ``x_r(omega) = vectors @ coefficients(omega)``.

    ``eigenvalues`` lambda_i [rad^2/s^2] and ``right`` z_i (k, k) of ``A_r z = lambda B_r z``;
    ``participation`` phi_i [N/V per kg: the solution's units times rad^2/s^2];
    ``residuals`` ``||A x_i - lambda_i B x_i|| / (||A|| ||x_i||)`` of ``x_i = V z_i``
    (``||A|| = sqrt(||A||_1 ||A||_inf)``, as :class:`copdea_fem.fe.eigen.band.BandResult`);
    ``damping`` ``(b/m)_i s_i`` [1/s] per Ritz mode (0: undamped); ``mode_index`` the Ritz
    modes reported as the response's modes, ``damping_per_mass`` their (b/m) [1/s].
    """

    reduced: ReducedBasis
    eigenvalues: np.ndarray
    right: np.ndarray
    participation: np.ndarray
    residuals: np.ndarray
    damping: np.ndarray
    mode_index: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    damping_per_mass: np.ndarray = field(default_factory=lambda: np.zeros(0))
    vectors: np.ndarray | None = None

    @property
    def size(self) -> int:
        return self.eigenvalues.size

    @property
    def frequency(self) -> np.ndarray:
        """f_i = sqrt(lambda_i) / (2 pi) [Hz], Re f >= 0 (complex)."""
        f = np.sqrt(self.eigenvalues.astype(complex)) / (2 * math.pi)
        return np.where(f.real < 0, -f, f)

    def coefficients(self, frequency_hz) -> np.ndarray:
        """Weights (lines, k) of the Ritz vectors per volt (module doc, eq. 3)."""
        omega = 2 * math.pi * np.atleast_1d(np.asarray(frequency_hz, float))[:, None]
        return self.participation / (self.eigenvalues - omega ** 2
                                     - 1j * omega * self.damping)

    def response(self, frequency_hz) -> np.ndarray:
        """Scaled solutions per volt (n, lines), as
        :meth:`copdea_fem.fe.forced.harmonic.ForcedOrder.direct`."""
        return self.vectors @ self.coefficients(frequency_hz).T

    def kinetic_shares(self, forced, index) -> np.ndarray:
        """s_i = lambda_i m_i / n_i (module doc, eq. 3) of the Ritz modes ``index`` [-]."""
        coupled = forced.coupled
        x = self.vectors[:, index]
        lam = self.eigenvalues[index]
        left = x.copy()
        left[coupled.membrane_index] *= lam[None, :]
        left[coupled.pressure_index] *= coupled.pressure_scale / forced.alpha
        norms = np.einsum("ij,ij->j", left, coupled.mass @ x)
        membrane = x[coupled.membrane_index]
        mass = np.einsum("ij,ij->j", membrane, coupled.membrane.mass @ membrane)
        return lam * mass / norms

    def summary(self) -> dict:
        """For ``response.json``: the basis (:meth:`ReducedBasis.summary`) and its modes."""
        return {**self.reduced.summary(), "ritz_modes": int(self.size),
                "damped_modes": int(np.count_nonzero(self.damping))}


def ritz_modes(forced, reduced: ReducedBasis) -> RitzModes:
    """The modes of the projected pencil ``(V^H A V, V^H B V)`` of ``reduced`` (built without
    a loss of its own: module doc, eq. 3), undamped, with their Ritz residuals."""
    import scipy.sparse.linalg as spla
    projected = {name: block for (block, _), (_, _, name) in
                 zip(reduced.projected, _pieces(forced, 0.0))}
    if set(projected) != {"A", "B"}:
        raise ValueError("modal damping on the reduced basis needs a model without a loss of "
                         f"its own; got the terms {sorted(projected)}; allowed: A, B")
    a_r, b_r = projected["A"], projected["B"]
    eigenvalues, left, right = scipy.linalg.eig(a_r, b_r, left=True, right=True)
    if not np.all(np.isfinite(eigenvalues)):
        raise ValueError("the reduced pencil V^H B V is singular (an infinite Ritz value); "
                         "allowed: a basis whose mass is non-singular")
    participation = (left.conj().T @ reduced.forcing) / np.einsum(
        "ij,ij->j", left.conj(), b_r @ right)
    vectors = reduced.vectors @ right
    a, b = forced.coupled.stiffness, forced.coupled.mass
    a_norm = math.sqrt(spla.norm(a, 1) * spla.norm(a, np.inf))
    residuals = np.linalg.norm(a @ vectors - (b @ vectors) * eigenvalues, axis=0) / (
        a_norm * np.maximum(np.linalg.norm(vectors, axis=0), 1e-300))
    return RitzModes(reduced, eigenvalues, right, participation, residuals,
                     np.zeros(eigenvalues.size, complex), vectors=vectors)
