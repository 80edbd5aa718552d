r"""Imperfect devices on the axisymmetric engine: first-order perturbation theory.

An anisotropic pre-stretch (``membrane.prestretch_anisotropy`` e along ``alpha``) and a
thickness variation (``membrane.thickness_variation``: ``h0 (1 + sum a cos k (theta -
beta))``) break the rotational symmetry weakly.  The modes of the round device (the
engine's orders m, both members of each pair) are the basis; the imperfection's matrix
elements between them come from the same energy the engine differentiates
(:func:`copdea_fem.fe.membrane.energy_density`, through the meridian's gradients of
:mod:`.membrane`), and the perturbed frequencies from the small matrix of each
(near-)degenerate block.

**The energy at an angle.**  In the polar bases of :mod:`.membrane` the round state's
gradient ``G0(R)`` does not depend on theta.  A mode ``i`` of order m has
``G_i(theta) = G_c^i C_i(theta) + G_s^i S_i(theta)`` (:func:`.membrane.harmonic_gradients`)
with ``(C, S) = (cos m theta, sin m theta)`` for a cos member, ``(sin m theta, -cos m
theta)`` for a sin member (the cos member turned by pi/(2m)) and ``(1, 1)`` at m = 0; its
displacement is ``(a C, b S, c C)``.  The stiffness between modes i and j is

    K_ij = int_0^2pi int W''(G(theta); theta)[G_i(theta), G_j(theta)] R dR dtheta

(W the energy per reference area; the round device: the engine's ``K_s``).

**The imperfection, to first order in its size s (e or a).**  Each term is one Fourier
order k at an angle beta:

* the anisotropy: ``B_p = F_p F_p^T = lambda_p^2 ((1 + e^2) I + 2 e R(phi) Z R(phi)^T)``
  with ``Z = diag(1, -1)`` and, in the polar basis at theta, ``phi = alpha - theta``; so to
  first order in e, ``dB_p = 2 e lambda_p^2 (cos 2(theta - alpha) Z - sin 2(theta -
  alpha) X)`` (X the off-diagonal unit): k = 2, beta = alpha, the cos part the material
  with its axis along e_R (``phi = 0``), the sin part the material with ``phi = -pi/4``.
  ``det B_p`` and the film's volume change at second order only (``(1 - e^2)``);
* a thickness term ``a cos k (theta - beta)``: the cos part a film uniformly ``1 + a``
  thicker (strain energy and mass times t, co-energy over t: the energy of
  :func:`copdea_fem.fe.membrane.energy_density` with ``h0 t``), no sin part; the mass
  changes by ``rho_s a cos k (theta - beta)``.

The round state is no longer in equilibrium: its first-order correction ``s du0`` is an
order-k field, the cos member at beta (the sin member's load vanishes by the mirror
symmetry about beta), ``K_k du0 = -f``, ``f`` the derivative in s of the order-k energy's
gradient at ``G0`` (``K_k``: the engine's own order-k stiffness).  The first-order change
of the stiffness is then the derivative of ``W''`` along the material's change AND the
state's, in one:

    dK_ij = d/ds int int W_s''(G0 + s G_du0(theta); theta)[G_i, G_j] R dR dtheta
          = int int [cos k(theta - beta) P_c + sin k(theta - beta) P_s][G_i(theta), G_j(theta)]

with ``P_c = d/ds W''_{c,s}(G0 + s G_c^du0)``, ``P_s = d/ds W''_{s,s}(G0 + s G_s^du0)``
(``W_{c,s}``, ``W_{s,s}``: the cos- and sin-part materials of size s; for the thickness
``W_{s,s} = W``): 6 x 6 matrices at each quadrature point of the membrane line (G has
six entries, its third column is zero), ``W''`` taken exactly (NGSolve's ``Diff`` in six
gradient Parameters), d/ds by a central difference in the size (a Parameter the material
and the state take) with the step :data:`SIZE_STEP`: one compiled CoefficientFunction of
``W''`` evaluated twice (compiling the exact third derivative instead costs more than
the rest of the path), to ~1e-9.
The theta integral of the three trigonometric factors is done by the trapezoid rule on
``2 (2 m_max + k) + 4`` points (exact for those products).  The mass elements: ``dM_ij =
rho_s int int cos k (theta - beta) (a_i a_j C_i C_j + b_i b_j S_i S_j + c_i c_j C_i C_j)
R dR dtheta``.  The disc and the spring are round: unchanged.

**Point masses** (``imperfections.point_masses``).  A mass dm riding with the film at
``x0 = (r0, theta0)`` on the flat pre-stretched reference adds its kinetic energy
``dm |u(x0)|^2 / 2`` to the device's: the mass matrix gains, exactly (no term left out),

    dM_ij = dm phi_i(x0) . phi_j(x0)
          = dm (a_i a_j C_i C_j + b_i b_j S_i S_j + c_i c_j C_i C_j)   at (r0, theta0)

(the polar components of both modes at one point: their dot product is the Cartesian one),
between every pair of modes of every order the band holds, cos and sin members; a mass on
the rigid disc (``r0 <= r_i``, :func:`copdea_fem.fe.prestress.disc_point_mass`) rides with
its axial motion only: ``dM_ij = dm w_i w_j`` (w the disc's displacement, non-zero for
m = 0; none with ``disc.motion: held``).  No stiffness changes and the state does not move.
The same blocks and partitioning below then give, for an isolated mode, the closed form
``df/f = -dm |phi(x0)|^2 / (2 phi^T M phi)`` (``-dM_ii / 2`` mass-normalised); a pair is
split at first order, its member with the antinode at theta0 lowered, the one with its
nodal line through the mass not moved (``C = cos m (theta - theta0)``, ``S = 0`` there;
the in-plane parts add ``b^2`` to the other).  Range: the total mass below
:data:`~copdea_fem.study.imperfections.PERTURBATION_MAX_MASS_RATIO` of the film's (its
derivation there), and the neglected higher-order shift checked after the solve.

**The small matrix.**  With the modes mass-normalised (``phi^T M phi = 1``,
eigenvalues ``lambda = omega^2``), ``(Lambda + dK) y = omega^2 (I + dM) y`` is to first
order the symmetric ``H = Lambda + dK - (Lambda dM + dM Lambda)/2``.  A degenerate pair
(m,n)a/b joined by H (``2m = k``: the anisotropy splits the m = 1 pairs, an order-k
thickness term the m = k/2 pairs) is diagonalised within its block: the split is first
order.  Every other first-order shift is the diagonal element (zero for these traceless
terms; the pair of order m and m' = m +- k couple only at second order).  Modes whose
coupling ``|H_ij|`` exceeds :data:`QUASI_DEGENERATE` times their eigenvalue gap share a
block (the small matrix widens).

**Range of validity.**  The terms left out are the second-order ones,
``sum_j H_ij^2 / (lambda_i - lambda_j)`` over the modes outside i's block, a relative
frequency shift of half that over lambda_i.  Where it exceeds :data:`TOLERANCE` for any
mode in the band the path refuses (:class:`PerturbationRangeError`, naming the keys, their
values and the limit); the study's own check (:mod:`copdea_fem.study.imperfections`)
sends a study whose imperfection exceeds the a-priori bound to the 3-D engine (auto) or
refuses it (axisymmetric).  The coupling to modes above the band is not counted.

**Shapes.**  A perturbed mode keeps its label from the perfect member it is closest to
(``a``: nearer cos m theta) and its vector (the order's cos member, or its sin twin); its
orientation (modes.csv ``orientation_deg``) is that of its block eigenvector: ``x cos m
theta + y sin m theta = cos m(theta - psi/m)`` with ``(x, y) ~ (cos psi, sin psi)``, its
antinode at ``psi / m``; its shape everywhere (sampled, revolved, at scan points) is the
member turned there (:func:`.modes.order_harmonics`), and its parity about x = 0 and y =
0 (modes.csv ``symmetry``) is kept only where the orientation is its family's own (0 or
90/m deg), else empty as on the 3-D engine's whole mesh.

**The coupled (air) modes.**  Each order's pencil (:mod:`.operators`) is the unsymmetric
u-p form ``A x = lambda B x``, ``A = [[K, C^T], [0, H]]``, ``B = [[M, 0], [-C, Q]]``
(``K``, ``M`` the membrane's, ``H``, ``Q`` the air's stiffness and mass with the PML, all
complex symmetric; ``C`` the coupling).  Its right eigenvector is ``x = (u, p)`` (``K u +
C^T p = lambda M u``, ``H p = lambda (Q p - C u)``); its left one ``y`` (``y^T A = lambda
y^T B``) is ``y = (lambda u, p)``: the first block column of ``y^T (A - lambda B)`` is
``lambda (K u + C^T p - lambda M u)^T = 0``, the second ``(H p - lambda (Q p - C u))^T =
0``.  The air is round, so the imperfection changes ``K`` and ``M`` only (the first-order
change of the air's shape, which the state's correction ``du0`` would bring, is left
out), and to first order

    d lambda = y^T (dA - lambda dB) x / y^T B x
             = lambda u^T (dK - lambda dM) u / (lambda u^T M u - p^T C u + p^T Q p)

with the unconjugated products (:func:`coupled_norm`: the denominator, ``N``); in the dry
limit (p = 0) it is the dry path's ``(dK_ii - lambda dM_ii) / m_i``.  ``dK``, ``dM``
between the complex membrane vectors are the same bilinear forms as above, taken between
their real and imaginary parts and combined.  With ``x_i``, ``y_i`` scaled by
``N_i^(-1/2)`` (``y_i^T B x_j = delta_ij``) the small matrix is the unsymmetric

    H_ij = lambda_i delta_ij + lambda_i (dK_ij - (lambda_i + lambda_j) dM_ij / 2) / sqrt(N_i N_j)

(a similarity transform of the dry path's ``H`` in the dry limit); the members of a pair
(the cos and sin partners of one coupled eigenvector: the same ``lambda`` and ``N``) form
a non-Hermitian 2 x 2 block, diagonalised by :func:`numpy.linalg.eig`, the couplings
outside a block folded in at second order as above (:func:`_second_order_coupled`); a
member's complex frequency is ``sqrt(lambda) / (2 pi)`` of its block eigenvalue, its
orientation that of its eigenvector turned to its most nearly real phase.  The air modes
are kept as they are (not in the basis).  The dry partners (the dry modes of the same
device) are perturbed by the dry path, each coupled member paired with the dry member in
its partner's place.  The forced response of an imperfect device is refused on the
axisymmetric engine (:func:`.engine.refuse_imperfect`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

from copdea_fem.fe.axisymmetric.membrane import d_dr, harmonic_gradients, prestress_gradient
from copdea_fem.fe.axisymmetric.operators import amplitude_proxies
from copdea_fem.fe.eigen.frequencies import eigenvalue_from_frequency, frequency_from_eigenvalue
from copdea_fem.fe.materials import Membrane
from copdea_fem.fe.membrane import cf_entries, energy_density
from copdea_fem.fe.modes import AIR
from copdea_fem.fe.prestress import disc_point_mass, membrane_point_masses
from copdea_fem.study.keys import StudyError

logger = logging.getLogger(__name__)

#: Largest neglected (third-order) relative frequency shift of a mode in the band [-].
TOLERANCE = 1e-3
#: Step in the imperfection's size s of the central difference that gives d/ds W'' [-]:
#: its truncation error, (h^2 / 6) d^3/ds^3 W'', is ~1e-9 relative for W'' smooth in s on the
#: scale 1, its round-off ~1e-16 / h ~ 1e-12 relative; both far below :data:`TOLERANCE`.
SIZE_STEP = 1e-4
#: |H_ij| above this share of |lambda_i - lambda_j| joins i and j in one block [-].
QUASI_DEGENERATE = 0.1
#: The six entries of the 3x3 meridian gradient that can be non-zero (its column 2 is 0).
ENTRIES = ((0, 0), (0, 1), (1, 0), (1, 1), (2, 0), (2, 1))


class PerturbationRangeError(StudyError):
    """An imperfection beyond the axisymmetric perturbation path's range of validity."""


@dataclass(frozen=True)
class HarmonicTerm:
    """One Fourier order of an imperfection: ``size`` s times cos/sin k (theta - angle).

    ``key``: the study key (messages); ``cos_material(s)`` / ``sin_material(s)``: the
    membrane material of the cos / sin part at size s, a number or an NGSolve Parameter
    (None: the sin part is round);
    ``mass``: the thickness term's ``rho_s`` factor (1), 0 for the anisotropy."""

    key: str
    order: int
    angle: float               # [rad]
    size: float
    cos_material: object
    sin_material: object
    mass: float


def round_material(material):
    """The perfect film of ``material``: no anisotropy, even thickness (the base state)."""
    return replace(material, anisotropy=0.0, anisotropy_axis=0.0, thickness_variation=())


def harmonic_terms(material, round_film) -> list[HarmonicTerm]:
    """The imperfection of ``material`` as Fourier terms about ``round_film`` (module doc)."""
    terms = []
    if material.anisotropy:
        terms.append(HarmonicTerm(
            "membrane.prestretch_anisotropy", 2, material.anisotropy_axis, material.anisotropy,
            lambda s: replace(round_film, anisotropy=s, anisotropy_axis=0.0),
            lambda s: replace(round_film, anisotropy=s, anisotropy_axis=-math.pi / 4), 0.0))
    for order, amplitude, angle in material.thickness_variation:
        terms.append(HarmonicTerm(
            "membrane.thickness_variation", int(order), angle, amplitude,
            lambda s: replace(round_film, thickness=round_film.thickness * (1 + s)),
            None, 1.0))
    return terms


class LineQuadrature:
    """Gauss points of the membrane line of a meridian mesh: ``points`` (NGSolve mapped
    points), ``weights`` [m] (ds) and ``radii`` R [m]."""

    def __init__(self, mesh, order: int):
        count = order + 3       # exact for polynomials of degree 2 order + 5 per segment
        nodes, weights = np.polynomial.legendre.leggauss(count)
        nodes, weights = (nodes + 1) / 2, weights / 2
        rule = ngs.IntegrationRule([(float(t),) for t in nodes], [float(w) for w in weights])
        points = mesh.MapToAllElements(rule, ngs.BND)
        names = mesh.GetBoundaries()
        elements = [el for el in mesh.Elements(ngs.BND) if names[el.index] == "membrane"]
        rows = np.array([el.nr for el in elements])[:, None] * count + np.arange(count)
        self.points = points[rows.ravel()]
        vertices = [[mesh[v].point[0] for v in el.vertices] for el in elements]
        lengths = np.array([abs(b - a) for a, b in vertices])
        self.weights = (lengths[:, None] * weights[None, :]).ravel()
        self.radii = np.asarray(ngs.x(self.points)).ravel()

    @staticmethod
    def points_at(mesh, radii):
        """NGSolve mapped points of the membrane line at the radii R [m] (each in the first
        membrane segment that holds it)."""
        names = mesh.GetBoundaries()
        elements = [el for el in mesh.Elements(ngs.BND) if names[el.index] == "membrane"]
        found = []
        for radius in radii:
            for el in elements:
                start, end = (mesh[v].point[0] for v in el.vertices)
                if min(start, end) - 1e-12 <= radius <= max(start, end) + 1e-12:
                    break
            else:
                raise ValueError(f"R = {radius!r} m is not on the membrane line")
            # the segment's local coordinate runs from one vertex to the other: map both
            # ends and take the one whose map is R
            local = (radius - end) / (start - end)
            for t in (local, 1 - local):
                rule = ngs.IntegrationRule([(float(t),)], [1.0])
                point = mesh.MapToAllElements(rule, ngs.BND)[el.nr:el.nr + 1]
                if abs(float(np.asarray(ngs.x(point)).ravel()[0]) - radius) <= 1e-9:
                    break
            found.append(point)
        return np.concatenate(found) if found else None

    def values(self, coefficient) -> np.ndarray:
        """(points, d) values of a CoefficientFunction."""
        values = np.asarray(coefficient(self.points))
        return values.reshape(len(self.radii), -1)


def _entries(matrix) -> list:
    return [matrix[i, j] for i, j in ENTRIES]


#: Positions in :data:`ENTRIES` of a cos-type gradient's entries (``G_c``: a', (a + m b)/R,
#: c') and of a sin-type one's (``G_s``).
COS_ENTRIES, SIN_ENTRIES = (0, 3, 4), (1, 2, 5)
#: The entries (p, q) of the 6 x 6 second derivative that a perturbation's cos part can
#: make non-zero: within the cos-type and within the sin-type entries (it keeps the mirror
#: symmetry about its angle, like the round state); its sin part: across them.
COS_PAIRS = tuple((p, q) for group in (COS_ENTRIES, SIN_ENTRIES) for p in group
                  for q in group if p <= q)
SIN_PAIRS = tuple((p, q) for p in COS_ENTRIES for q in SIN_ENTRIES)


def _hessian_cf(material, voltage, base, pairs):
    """The entries ``pairs`` of ``W''(base)`` [J/m^2] (6 x 6 in the gradient's
    :data:`ENTRIES`) as one vector CoefficientFunction:
    :func:`copdea_fem.fe.membrane.energy_density` at ``base + sum_k s_k E_k``,
    differentiated twice in the parameters s_k at 0."""
    parameters = [ngs.Parameter(0.0) for _ in ENTRIES]
    increment = [[0] * 3 for _ in range(3)]
    for (i, j), parameter in zip(ENTRIES, parameters):
        increment[i][j] = parameter
    gradient = base + cf_entries(tuple(value for row in increment for value in row),
                                 dims=(3, 3))
    energy = energy_density(None, material, voltage, gradient=gradient)
    first = {p: energy.Diff(parameters[p]) for p in {p for p, _ in pairs}}
    return ngs.CF(tuple(first[p].Diff(parameters[q]) for p, q in pairs))


def _symmetric(values: np.ndarray, pairs) -> np.ndarray:
    """(points, len(pairs)) entries -> (points, 6, 6) symmetric matrices (others 0)."""
    full = np.zeros((values.shape[0], 6, 6))
    rows, cols = np.array(pairs).T
    full[:, rows, cols] = values
    full[:, cols, rows] = values
    return full


def field_gradients(operators, vector, order=None):
    """(G_c, G_s, (a, b, c), GridFunction) of a coefficient ``vector`` of ``operators``'
    order space (the disc lift included in it); ``order``: an NGSolve Parameter standing
    for m >= 1 (one CoefficientFunction for the orders sharing a space), else the
    operators' m."""
    function = ngs.GridFunction(operators.space)
    function.vec.FV().NumPy()[:] = np.real(vector)
    a, second, c = function.components
    da, dsecond, dc = d_dr(a), d_dr(second), d_dr(c)
    b, db = (second - a, dsecond - da) if operators.axis_m1 else (second, dsecond)
    g_c, g_s = harmonic_gradients(operators.m if order is None else order,
                                  a, b, c, da, db, dc)
    return g_c, g_s, (a, b, c), function


def _state_correction(state, term: HarmonicTerm, forms, size, operators=None):
    """``du0``: the round state's first-order correction per unit size, an order-k cos
    member at the term's angle (module doc): ``(G_c, G_s)`` CoefficientFunctions and the
    GridFunction they read.  ``size``: the Parameter s (at 0) the materials depend on;
    ``operators``: the order-k operators where the engine made them, else made here."""
    k = term.order
    operators = operators or forms.operators(k)
    space = operators.space
    (a, da), (b, db), (c, dc) = amplitude_proxies(space.TrialFunction(), operators.axis_m1)
    g_c, g_s = harmonic_gradients(k, a, b, c, da, db, dc)
    base = prestress_gradient(state.displacement)
    voltage = state.voltage
    sin_film = state.material if term.sin_material is None else term.sin_material(size)
    energy = math.pi * ngs.x * (
        energy_density(None, term.cos_material(size), voltage, gradient=base + g_c)
        + energy_density(None, sin_film, voltage, gradient=base + g_s))
    form = ngs.BilinearForm(space, symmetric=False)
    form += ngs.Variation(energy.Diff(size).Compile() * state.measure)
    zero, load = ngs.GridFunction(space).vec, ngs.GridFunction(space).vec
    form.Apply(zero, load)
    free = operators.free_dofs
    correction = np.zeros(space.ndof)
    correction[free] = spla.spsolve(operators.stiffness.tocsc(), -load.FV().NumPy()[free])
    g_c, g_s, _, function = field_gradients(operators, correction)
    return g_c, g_s, function


def _perturbation_tensors(state, terms, forms, quadrature, operators_of: dict):
    """[(P_c, P_s) per term]: (points, 6, 6) each [J/m^2 per unit size] (module doc),
    all evaluated from one compiled CoefficientFunction of the exact ``W''`` at ``s = +-``
    :data:`SIZE_STEP`."""
    base = prestress_gradient(state.displacement)
    voltage, size = state.voltage, ngs.Parameter(0.0)
    parts, keep = [], []
    for term in terms:
        correction_c, correction_s, function = _state_correction(
            state, term, forms, size, operators_of.get(term.order))
        keep.append(function)
        for material_of, correction, pairs in ((term.cos_material, correction_c, COS_PAIRS),
                                               (term.sin_material, correction_s, SIN_PAIRS)):
            film = state.material if material_of is None else material_of(size)
            parts.append(_hessian_cf(film, voltage, base + size * correction, pairs))
    # d/ds by a central difference of the exact W'' (module doc): one compiled
    # CoefficientFunction evaluated at s = +h and -h
    compiled = ngs.CF(tuple(parts)).Compile()
    size.Set(SIZE_STEP)
    plus = quadrature.values(compiled)
    size.Set(-SIZE_STEP)
    minus = quadrature.values(compiled)
    size.Set(0.0)
    values = (plus - minus) / (2 * SIZE_STEP)
    tensors, start = [], 0
    for j in range(len(parts)):
        pairs = COS_PAIRS if j % 2 == 0 else SIN_PAIRS
        tensors.append(_symmetric(values[:, start:start + len(pairs)], pairs))
        start += len(pairs)
    return [(tensors[2 * j], tensors[2 * j + 1]) for j in range(len(terms))]


def _mode_factors(modes, angles):
    """(modes, 2, angles): the (C, S) factors of each mode (module doc)."""
    factors = np.empty((len(modes), 2, len(angles)))
    for i, mode in enumerate(modes):
        m = mode.m
        if m == 0:
            factors[i] = 1.0
        elif mode.family == "sin":
            factors[i] = np.sin(m * angles), -np.cos(m * angles)
        else:
            factors[i] = np.cos(m * angles), np.sin(m * angles)
    return factors


def _sampled_modes(modes, quadrature, points=None):
    """(modes, 2, points, 6) gradients, (modes, 3, points) amplitudes (a, b, c) and the
    modal masses (modes,) [kg] of the modes' vectors; with ``points`` (mapped points of
    the membrane line, :meth:`LineQuadrature.points_at`) also their (modes, 3, len(points))
    amplitudes there (else None)."""
    gradients = np.empty((len(modes), 2, len(quadrature.radii), 6))
    amplitudes = np.empty((len(modes), 3, len(quadrature.radii)))
    at_points = None if points is None else np.empty((len(modes), 3, len(points)))
    masses = np.empty(len(modes))
    sampled, order = {}, ngs.Parameter(1.0)     # small CFs: compiling costs more than it saves
    for i, mode in enumerate(modes):
        operators = mode.operators
        # one CoefficientFunction per space (the orders m >= 1 of a space share it)
        key = (id(operators.space), operators.axis_m1, mode.m == 0)
        if key not in sampled:
            g_c, g_s, (a, b, c), function = field_gradients(
                operators, mode.vector, None if mode.m == 0 else order)
            sampled[key] = (function, ngs.CF(tuple(_entries(g_c) + _entries(g_s) + [a, b, c])),
                            ngs.CF((a, b, c)))
        function, values_cf, amplitudes_cf = sampled[key]
        order.Set(float(max(mode.m, 1)))
        function.vec.FV().NumPy()[:] = np.real(mode.vector)
        values = quadrature.values(values_cf)
        gradients[i, 0], gradients[i, 1] = values[:, :6], values[:, 6:12]
        amplitudes[i] = values[:, 12:].T
        if points is not None:
            at_points[i] = np.asarray(amplitudes_cf(points)).reshape(len(points), 3).T
        vector = np.real(mode.vector)
        masses[i] = float(vector @ (operators.mass_full @ vector)) + \
            operators.disc_mass * abs(mode.disc_displacement) ** 2
    return gradients, amplitudes, masses, at_points


def point_mass_matrix(modes, amplitudes, point_masses, disc_mass) -> np.ndarray:
    """``dM`` [kg] of point masses between ``modes`` (module doc): ``point_masses`` ((mass
    [kg], x [m], y [m]), ...) on the membrane with the modes' amplitudes (a, b, c) there
    (modes, 3, masses); ``disc_mass`` [kg] on the rigid disc."""
    mass = np.zeros((len(modes), len(modes)))
    for index, (dm, x, y) in enumerate(point_masses):
        factors = _mode_factors(modes, np.array([math.atan2(y, x)]))[:, :, 0]   # (modes, 2)
        a, b, c = amplitudes[:, :, index].T
        radial, hoop, axial = a * factors[:, 0], b * factors[:, 1], c * factors[:, 0]
        mass += dm * (np.outer(radial, radial) + np.outer(hoop, hoop)
                      + np.outer(axial, axial))
    if disc_mass:
        disc = np.array([np.real(mode.disc_displacement) for mode in modes])
        mass += disc_mass * np.outer(disc, disc)
    return mass


def perturbation_matrices(state, modes, terms, forms, point_masses=(), disc_mass=0.0):
    """(dK, dM, modal masses): the imperfection's first-order matrices between ``modes``
    (their vectors as they are, not normalised) [N/m], [kg], and the modes' masses
    ``phi^T M phi`` [kg] (module doc); ``point_masses``, ``disc_mass``: as
    :func:`point_mass_matrix` takes them."""
    quadrature = LineQuadrature(state.mesh, forms.study.mesh.order)
    points = LineQuadrature.points_at(state.mesh, [math.hypot(x, y)
                                                   for _, x, y in point_masses])
    gradients, amplitudes, masses, at_points = _sampled_modes(modes, quadrature, points)
    weights = quadrature.weights * quadrature.radii
    top = max([mode.m for mode in modes] + [0])
    size = len(modes)
    stiffness = np.zeros((size, size))
    mass = point_mass_matrix(modes, at_points, point_masses, disc_mass)
    operators_of = {mode.m: mode.operators for mode in modes}
    tensors_of = _perturbation_tensors(state, terms, forms, quadrature, operators_of) \
        if terms else []
    for term, tensors in zip(terms, tensors_of):
        count = 2 * (2 * top + term.order) + 4
        angles = 2 * np.pi * np.arange(count) / count
        factors = _mode_factors(modes, angles)
        phase = term.order * (angles - term.angle)
        perturbation = np.stack([np.cos(phase), np.sin(phase)])
        # trig[p, i, x, j, y] = (2 pi / count) sum_t pert_p(t) F_ix(t) F_jy(t)
        flat = factors.reshape(2 * size, count)
        trig = ((perturbation[:, None, :] * flat[None]).reshape(4 * size, count) @ flat.T
                ).reshape(2, size, 2, size, 2) * (2 * np.pi / count)
        # radial[p, i, x, j, y] = sum_q w_q G_ix(q) . P_p(q) G_jy(q)
        tensors = np.stack(tensors)                                    # (p, q, a, b)
        applied = np.einsum("pqab,jyqb->pjyqa", tensors, gradients)    # (p, j, y, q, a)
        weighted = (gradients * weights[None, None, :, None]).reshape(2 * size, -1)
        radial = np.stack([weighted @ applied[p].reshape(2 * size, -1).T for p in range(2)]
                          ).reshape(2, size, 2, size, 2)
        stiffness += term.size * np.sum(trig * radial, axis=(0, 2, 4))
        if term.mass:
            rho = state.material.areal_density
            # a and c go with C, b with S (module doc)
            same = (amplitudes[:, 0] * weights) @ amplitudes[:, 0].T + \
                (amplitudes[:, 2] * weights) @ amplitudes[:, 2].T
            hoop = (amplitudes[:, 1] * weights) @ amplitudes[:, 1].T
            mass += term.size * term.mass * rho * (trig[0, :, 0, :, 0] * same
                                                   + trig[0, :, 1, :, 1] * hoop)
    return stiffness, mass, masses


def _blocks(matrix: np.ndarray, eigenvalues: np.ndarray) -> list[list[int]]:
    """Groups of modes joined by degeneracy or by |H_ij| > QUASI_DEGENERATE |gap| (either of
    H_ij, H_ji: the coupled path's H is not symmetric): the connected components of the
    graph of those links, each in ascending order."""
    gaps = np.abs(eigenvalues[:, None] - eigenvalues[None, :])
    links = (np.abs(matrix) > QUASI_DEGENERATE * gaps) | \
        (gaps <= 1e-9 * np.abs(eigenvalues)[:, None])
    count, labels = connected_components(sp.csr_matrix(links), directed=False)
    return [np.flatnonzero(labels == label).tolist() for label in range(count)]


def _imperfection(study, state):
    """(terms, point masses, disc mass, keys): the study's imperfection as the path takes it
    (:func:`harmonic_terms`, :func:`copdea_fem.fe.prestress.membrane_point_masses`)."""
    terms = harmonic_terms(Membrane.with_effects(study), state.material)
    point_masses, disc_mass = membrane_point_masses(study), disc_point_mass(study)
    keys = sorted({t.key for t in terms}) + (
        ["imperfections.point_masses"] if point_masses or disc_mass else [])
    return terms, point_masses, disc_mass, keys


def _given(terms, point_masses, disc_mass) -> str:
    """The imperfection's keys and values, for the range message."""
    given = [f"{t.key} = {t.size:g}" + (f" (order {t.order})" if t.mass else "")
             for t in terms]
    if point_masses or disc_mass:
        given.append("imperfections.point_masses = "
                     f"{sum(m for m, _, _ in point_masses) + disc_mass:g} kg in all")
    return "; ".join(given)


def perturbed_modes(state, modes, study, forms):
    """The ``modes`` of the round device (cos and sin members, as the engine lists them)
    with their frequencies and orientations perturbed by the study's imperfection (module
    doc); refuses (:class:`PerturbationRangeError`) beyond the range of validity."""
    terms, point_masses, disc_mass, keys = _imperfection(study, state)
    if not (terms or point_masses or disc_mass) or not modes:
        return modes
    logger.info("imperfections on the axisymmetric engine: first-order perturbation of "
                f"{len(modes)} modes ({', '.join(keys)})")
    stiffness, mass, masses = perturbation_matrices(state, modes, terms, forms,
                                                    point_masses, disc_mass)
    scale = 1 / np.sqrt(masses)
    stiffness = stiffness * np.outer(scale, scale)
    mass = mass * np.outer(scale, scale)
    eigenvalues = (2 * np.pi * np.array([mode.freq_hz for mode in modes])) ** 2
    matrix = np.diag(eigenvalues) + stiffness - 0.5 * (
        eigenvalues[:, None] * mass + mass * eigenvalues[None, :])
    matrix = 0.5 * (matrix + matrix.T)
    blocks = _blocks(matrix, eigenvalues)
    out = list(modes)
    worst = (0.0, None)
    for block in blocks:
        values, vectors, third = _second_order(matrix, eigenvalues, block)
        worst = max(worst, (float(np.max(third)), modes[block[int(np.argmax(third))]]),
                    key=lambda item: item[0])
        _assign(block, np.sqrt(np.maximum(values, 0.0)) / (2 * np.pi), vectors, modes, out)
    _check_range(*worst, _given(terms, point_masses, disc_mass))
    return out


def coupled_norm(mode, pressure, pencil) -> complex:
    """``y^T B x`` [J] of a coupled eigenpair (module doc, "The coupled (air) modes"):
    ``lambda u^T M_s u - p^T C u + p^T M_a p``, unconjugated, ``u`` the membrane's unknowns
    of ``mode`` (its vector's free DOFs, then the disc's displacement), ``pressure`` [Pa] on
    ``pencil.pressure_free`` (:func:`.modes.coupled_order_modes`), ``pencil`` the order's
    :class:`.operators.CoupledOrderOperators`."""
    dry = pencil.membrane
    u = np.asarray(mode.vector)[dry.free_dofs].astype(complex)
    if dry.disc_dof:
        u = np.append(u, complex(mode.disc_displacement))
    eigenvalue = complex(eigenvalue_from_frequency(mode.freq_hz + 1j * mode.freq_im_hz))
    pressure = np.asarray(pressure, dtype=complex)
    return complex(eigenvalue * (u @ (dry.mass @ u)) - pressure @ (pencil.coupling @ u)
                   + pressure @ (pencil.air_mass @ pressure))


def perturbed_coupled_modes(state, modes, pressures, pencils: dict, study, forms):
    """The coupled (air) ``modes`` of the round device (cos and sin members, ``pressures``
    their pressure vectors, ``pencils`` {m: the order's
    :class:`.operators.CoupledOrderOperators`}) with their complex frequencies and
    orientations perturbed by the study's imperfection (module doc, "The coupled (air)
    modes"); the air modes are kept as they are.  Refuses
    (:class:`PerturbationRangeError`) beyond the range of validity."""
    terms, point_masses, disc_mass, keys = _imperfection(study, state)
    chosen = [k for k, mode in enumerate(modes) if mode.kind != AIR]
    if not (terms or point_masses or disc_mass) or not chosen:
        return modes
    basis = [modes[k] for k in chosen]
    logger.info("imperfections on the axisymmetric engine: first-order perturbation of "
                f"{len(basis)} coupled modes ({', '.join(keys)})")
    # the unconjugated forms of complex vectors from the real ones of their parts
    parts = [replace(mode, vector=np.ascontiguousarray(part(mode.vector)),
                     disc_displacement=float(part(mode.disc_displacement)))
             for mode in basis for part in (np.real, np.imag)]
    stiffness, mass, _ = perturbation_matrices(state, parts, terms, forms, point_masses,
                                               disc_mass)
    size = len(basis)
    combine = np.zeros((2 * size, size), dtype=complex)
    combine[2 * np.arange(size), np.arange(size)] = 1.0
    combine[2 * np.arange(size) + 1, np.arange(size)] = 1j
    norms = np.array([coupled_norm(modes[k], pressures[k], pencils[modes[k].m])
                      for k in chosen])
    scale = 1 / np.sqrt(norms)
    stiffness = (combine.T @ stiffness @ combine) * np.outer(scale, scale)
    mass = (combine.T @ mass @ combine) * np.outer(scale, scale)
    eigenvalues = eigenvalue_from_frequency(np.array([mode.freq_hz + 1j * mode.freq_im_hz
                                                      for mode in basis]))
    matrix = np.diag(eigenvalues) + eigenvalues[:, None] * (
        stiffness - 0.5 * (eigenvalues[:, None] + eigenvalues[None, :]) * mass)
    out = list(basis)
    worst = (0.0, None)
    for block in _blocks(matrix, eigenvalues):
        values, vectors, third = _second_order_coupled(matrix, eigenvalues, block)
        worst = max(worst, (float(np.max(third)), basis[block[int(np.argmax(third))]]),
                    key=lambda item: item[0])
        _assign(block, frequency_from_eigenvalue(values), _real_phase(vectors), basis, out)
    _check_range(*worst, _given(terms, point_masses, disc_mass))
    result = list(modes)
    for k, mode in zip(chosen, out):
        result[k] = mode
    return result


def _real_phase(vectors: np.ndarray) -> np.ndarray:
    """Complex block eigenvectors (columns) turned by the phase that makes them most nearly
    real (``v^T v`` real positive), their real parts, unit length: the split members'
    orientations (a member of a real pair of cos/sin partners is real up to its phase)."""
    vectors = np.atleast_2d(vectors)
    phases = np.exp(-0.5j * np.angle(np.sum(vectors**2, axis=0)))
    real = np.real(vectors * phases[None, :])
    return real / np.maximum(np.linalg.norm(real, axis=0), 1e-300)[None, :]


def _second_order_coupled(matrix, eigenvalues, block):
    """:func:`_second_order` for the coupled path's non-symmetric complex ``H`` (module doc):
    ``H_eff = H_BB + H_Bo D H_oB`` with the same symmetrised ``D``, its eigenpairs by
    ``numpy.linalg.eig`` and each eigenpair's neglected third-order estimate, relative to
    its frequency: half its second-order shift over |lambda| times its largest
    ``sqrt(|w^T H_Bj| |H_jB v|) / |lambda_v - lambda_j|`` (w, v: its left and right
    vectors)."""
    inside = matrix[np.ix_(block, block)]
    outside = np.setdiff1d(np.arange(len(eigenvalues)), block)
    if not len(outside):
        values, vectors = np.linalg.eig(inside)
        return values, vectors, np.zeros(len(values))
    out_of = matrix[np.ix_(block, outside)]                        # (block, outside)
    into = matrix[np.ix_(outside, block)]                          # (outside, block)
    inverse_gaps = 1 / (eigenvalues[block][:, None] - eigenvalues[None, outside])
    folded = 0.5 * ((out_of * inverse_gaps) @ into + out_of @ (inverse_gaps.T * into))
    values, vectors = np.linalg.eig(inside + folded)
    left = np.linalg.inv(vectors)                                  # rows: w^T, w^T v = 1
    shifts = np.einsum("vb,bc,cv->v", left, folded, vectors)
    coupling = np.sqrt(np.abs(left @ out_of) * np.abs(into @ vectors).T)
    gaps = np.abs(values[:, None] - eigenvalues[None, outside])
    ratios = np.max(coupling / gaps, axis=1)
    return values, vectors, np.abs(shifts) / np.abs(values) / 2 * ratios


def _second_order(matrix, eigenvalues, block):
    """The block's eigenpairs with the couplings to the modes outside it folded in at
    second order (Loewdin partitioning): ``H_eff = H_BB + H_Bo D H_oB`` with ``D_bb'j =
    (1/(lambda_b - lambda_j) + 1/(lambda_b' - lambda_j)) / 2``, so that a pair split only at
    second order (through modes of other orders) is split and oriented too; and each
    eigenpair's estimate of the third-order term left out, relative to its frequency: half
    its second-order shift over lambda times its largest ``|v^T H_Bj| / |lambda_v -
    lambda_j|`` (below :data:`QUASI_DEGENERATE` by the blocks' rule)."""
    inside = matrix[np.ix_(block, block)]
    outside = np.setdiff1d(np.arange(len(eigenvalues)), block)
    if not len(outside):
        values, vectors = np.linalg.eigh(inside)
        return values, vectors, np.zeros_like(values)
    coupling = matrix[np.ix_(block, outside)]                       # (block, outside)
    inverse_gaps = 1 / (eigenvalues[block][:, None] - eigenvalues[None, outside])
    folded = 0.5 * ((coupling * inverse_gaps) @ coupling.T
                    + coupling @ (coupling * inverse_gaps).T)
    values, vectors = np.linalg.eigh(inside + folded)
    projected = vectors.T @ coupling
    shifts = np.einsum("vb,bc,cv->v", vectors.T, folded, vectors)
    gaps = np.abs(values[:, None] - eigenvalues[None, outside])
    ratios = np.max(np.abs(projected) / gaps, axis=1)
    return values, vectors, np.abs(shifts) / values / 2 * ratios


def _check_range(neglected, mode, keys: str) -> None:
    """Refuse where a mode's neglected higher-order shift exceeds :data:`TOLERANCE`
    (``keys``: the imperfection's keys and values, for the message)."""
    logger.info(f"perturbation: largest neglected higher-order shift {neglected:.2e} "
                f"(limit {TOLERANCE:g})")
    if neglected > TOLERANCE:
        raise PerturbationRangeError(
            f"{keys} is not allowed on the axisymmetric engine: its perturbation path "
            f"neglects a relative frequency shift of {neglected:.2e} at {mode.freq_hz:.1f} Hz "
            f"(m = {mode.m}), more than the limit {TOLERANCE:g}; allowed: a smaller "
            "imperfection, or mesh.engine: 3d")


def _assign(block, frequencies, vectors, modes, out) -> None:
    """New frequency [Hz] (``frequencies``: the block's, complex on the coupled path: its
    imaginary part the mode's ``freq_im_hz``), member and orientation (real ``vectors``) of
    each mode of a block (module doc)."""
    order = np.argsort(np.real(frequencies))
    used = set()
    for column in order:
        vector = vectors[:, column]
        weights = vector**2
        # the dominant order and radial family (m, n, kind): its cos/sin members
        leader = block[int(np.argmax(weights))]
        lead = modes[leader]
        twins = [k for k, i in enumerate(block) if modes[i].m == lead.m
                 and modes[i].n == lead.n and modes[i].kind == lead.kind
                 and modes[i].in_plane_component == lead.in_plane_component]
        x = sum(vector[k] for k in twins if modes[block[k]].family == "cos")
        y = sum(vector[k] for k in twins if modes[block[k]].family == "sin")
        family = "cos" if abs(x) >= abs(y) else "sin"
        if lead.m > 0 and any(modes[block[k]].family == family and block[k] in used
                              for k in twins):
            family = "sin" if family == "cos" else "cos"     # the partner took that member
        source = next((block[k] for k in twins if modes[block[k]].family == family), leader)
        used.add(source)
        orientation = math.nan
        if lead.m > 0:
            psi = math.atan2(y, x)
            period = 180.0 / lead.m
            orientation = (math.degrees(psi) / lead.m) % period
            if period - orientation < 1e-9 * period:
                orientation = 0.0
        sector = modes[source].sector
        if lead.m > 0:
            # the parity about x = 0 and y = 0 (modes.csv "symmetry") holds only for a member
            # at its family's own orientation (cos: 0, sin: 90/m deg)
            own = 0.0 if family == "cos" else 90.0 / lead.m
            offset = abs(orientation - own) % (180.0 / lead.m)
            if min(offset, 180.0 / lead.m - offset) > 1e-6:
                sector = None
        frequency = complex(frequencies[column])
        imaginary = frequency.imag if np.iscomplexobj(frequencies) else modes[source].freq_im_hz
        out[source] = replace(modes[source], freq_hz=frequency.real, freq_im_hz=imaginary,
                              family=family, orientation=orientation, sector=sector)
