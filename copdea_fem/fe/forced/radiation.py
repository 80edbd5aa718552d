r"""Observables of a forced response: membrane velocity at points, power, far-field sound.

Every observable but the powers is linear in the solution, so it is applied to a few
basis vectors (:class:`.harmonic.ModalBasis`) and combined per line.

Velocity (Sect. 5.3): ``v = -i omega u`` (``e^{-i omega t}``); the vibrometer looks along
the axis, so a point sits at the *projected* radius ``r = r_i + f (r_o - r_i)`` on the
prestressed profile (as :func:`copdea_fem.reduced.chirp_response.observation_matrix`); its
reference radius R solves ``R + u_r0(R) = r``.  Axial = u_z, radial = u_r (order 0).

Far field beyond the air sphere (the FE field ends at the PML), on a sphere ``Sigma`` of
radius ``rho_s = KIRCHHOFF_FRACTION R`` inside the physical air, outward normal n:

- ``frame: baffle`` -- Rayleigh's half-space problem: with the half-space Green's function
  ``G_h(x, y) = G(x, y) + G(x, y')`` (``y'`` mirrored in z = 0, ``dG_h/dn = 0`` on the
  rigid plane) the Kirchhoff-Helmholtz integral over the hemisphere on the microphone's side
  is exact; it equals the Rayleigh integral ``p = -i omega rho_a/(2 pi) int v_n e^{ikd}/d dS``
  of the baffle-plane velocity (checked in the tests against the baffled piston).
- otherwise -- Kirchhoff-Helmholtz over the whole sphere with the free-space
  ``G = e^{ikd}/(4 pi d)``, ``k = omega/c_a``::

      p(x) = int_Sigma [p dG/dn_y - G dp/dn_y] dS_y

Axisymmetric fields (m = 0): Gauss-Legendre in the polar angle, trapezoidal (spectral for
a periodic integrand) in the azimuth.  Microphones inside the air sphere read the FE field.

Powers (time averages, per |V~|^2): input ``P_in = omega/2 Im(f^H u)``, radiated
``P_rad = 1/2 Re int_Sigma p conj(v_rho) dS`` with ``v_rho = (dp/drho)/(i omega rho_a)``
(Euler), hysteretic ``P_d = omega/2 eta u^H K_el u``.  SPL ``= 20 log10(|p|/sqrt(2) / 20 uPa)``
(|p| an amplitude; with chirp lines |FFT|/N the line amplitude as in the velocity spectra).
"""

from __future__ import annotations

import math

import ngsolve as ngs
import numpy as np

#: Radius of the Kirchhoff-Helmholtz sphere as a share of the air radius R: inside the air,
#: one air element (~0.25 r_o = 0.07 R) clear of the PML.
KIRCHHOFF_FRACTION = 0.85
#: Gauss points in the polar angle per hemisphere, azimuth points (far field).
POLAR_POINTS, AZIMUTH_POINTS = 48, 64
REFERENCE_PRESSURE = 20e-6          # Pa


def spl_db(pressure_amplitude) -> np.ndarray:
    """SPL [dB re 20 uPa] of a pressure amplitude [Pa] (RMS = amplitude / sqrt 2)."""
    rms = np.abs(pressure_amplitude) / math.sqrt(2)
    return 20 * np.log10(np.maximum(rms, 1e-30) / REFERENCE_PRESSURE)


class MembraneObserver:
    """u_z, u_r of order-0 vectors at points placed by projected radius (module doc)."""

    def __init__(self, state, dry, fractions):
        self.dry = dry
        self.line = state.line()
        r_i, r_o = state.inner_radius, state.outer_radius
        grid = np.linspace(r_i, r_o, 801)
        deformed = grid + state.profile(grid)[:, 0]
        if np.any(np.diff(deformed) <= 0):
            raise ValueError("the prestressed profile folds back; allowed: a profile the axis "
                             "sees once")
        self.projected = r_i + np.asarray(fractions, float) * (r_o - r_i)
        self.reference = np.interp(self.projected, deformed, grid)
        self.gf = ngs.GridFunction(dry.space)

    def observe(self, membrane_vectors) -> tuple[np.ndarray, np.ndarray]:
        """(axial, radial) displacements (points, columns) of membrane unknowns (n_u, columns)."""
        full = self.dry.to_full(np.asarray(membrane_vectors))
        axial = np.zeros((self.reference.size, full.shape[1]), complex)
        radial = np.zeros_like(axial)
        a, _, c = self.dry.amplitudes(self.gf)
        for k in range(full.shape[1]):
            for part, factor in ((full[:, k].real, 1.0), (full[:, k].imag, 1j)):
                self.gf.vec.FV().NumPy()[:] = part
                radial[:, k] += factor * self.line.at(a, self.reference)
                axial[:, k] += factor * self.line.at(c, self.reference)
        return axial, radial


def polar_quadrature(hemispheres=("upper", "lower")) -> tuple[np.ndarray, np.ndarray]:
    """Polar angles theta [rad] and weights [rad] of :data:`POLAR_POINTS` Gauss-Legendre
    points per hemisphere (upper: theta in (0, pi/2), lower: (pi/2, pi)), for both
    engines' Kirchhoff spheres."""
    nodes, weights = np.polynomial.legendre.leggauss(POLAR_POINTS)
    starts = [0.0 if half == "upper" else 0.5 * np.pi for half in hemispheres]
    return (np.concatenate([start + 0.25 * np.pi * (nodes + 1) for start in starts]),
            np.tile(0.25 * np.pi * weights, len(starts)))


class SphereSampler:
    """p and dp/drho of order-0 pressure vectors on the Kirchhoff sphere (module doc)."""

    def __init__(self, coupled, radius: float, hemispheres=("upper", "lower")):
        mesh = coupled.pressure_space.mesh
        self.coupled, self.radius = coupled, radius
        self.polar, self.weight = polar_quadrature(hemispheres)
        self.r, self.z = radius * np.sin(self.polar), radius * np.cos(self.polar)
        self.points = mesh(self.r, self.z)
        self.gf = ngs.GridFunction(coupled.pressure_space)
        p, q = self.gf.components
        e = ngs.CF((ngs.x, ngs.y)) / ngs.sqrt(ngs.x ** 2 + ngs.y ** 2)
        self._upper = ngs.CF((p, ngs.grad(p) * e))
        self._lower = ngs.CF((p + q, (ngs.grad(p) + ngs.grad(q)) * e))
        self.is_upper = self.z > 0

    def kernels(self, microphone, wavenumber: float, baffle: bool):
        """:func:`kirchhoff_kernels` on this sphere."""
        return kirchhoff_kernels(self, microphone, wavenumber, baffle)

    def sample(self, pressure_vectors) -> tuple[np.ndarray, np.ndarray]:
        """(p, dp/drho) (points, columns) of free-pressure vectors [Pa] (n_p, columns)."""
        pressure_vectors = np.atleast_2d(np.asarray(pressure_vectors).T).T
        values = np.zeros((self.polar.size, 2, pressure_vectors.shape[1]), complex)
        for k, factor in pressure_parts(self.gf, self.coupled.pressure_free, pressure_vectors):
            upper = np.asarray(self._upper(self.points))
            lower = np.asarray(self._lower(self.points))
            values[:, :, k] += factor * np.where(self.is_upper[:, None], upper, lower)
        return values[:, 0], values[:, 1]


def pressure_parts(gf, free, pressure_vectors):
    """Set ``gf`` (a real GridFunction of the pressure space) to the real, then the imaginary
    part of each column of ``pressure_vectors`` (free DOFs ``free``, the rest 0) and yield
    ``(column, factor)`` with ``factor`` 1 or 1j: what is sampled of ``gf`` then, times
    ``factor``, summed over both parts, is the column's complex field."""
    for k in range(pressure_vectors.shape[1]):
        for part, factor in ((pressure_vectors[:, k].real, 1.0),
                             (pressure_vectors[:, k].imag, 1j)):
            vector = gf.vec.FV().NumPy()
            vector[:] = 0.0
            vector[free] = part
            yield k, factor


def sampling_matrix(gf, free, element_numbers, evaluate):
    """The sparse matrix S [(points x values), free DOFs] with ``S @ v`` = ``evaluate()`` of
    ``gf`` holding ``v`` on the free DOFs ``free`` (0 elsewhere), for a sampling linear in
    ``gf``'s vector: one matrix applied to every vector instead of one evaluation per vector.

    A point's values depend only on the DOFs of the (volume) element it was found in,
    ``element_numbers[point]``.  The DOFs of those elements are coloured so that no element
    holds two of one colour; ``gf`` set to the indicator of one colour then gives, at each
    point, the shape values of the one DOF of that colour in its element: one evaluation
    per colour (a few tens) gives every entry of S exactly.

    Parameters
    ----------
    gf : ngsolve.GridFunction
        Real, of the space that ``free`` indexes; left at 0.
    free : array of int
        The free DOFs (the columns of S, in this order).
    element_numbers : array of int
        The volume element of each point (P,).
    evaluate : callable
        ``evaluate() -> (P, V)`` real array: the values at the points of what ``gf`` holds.
    """
    import ngsolve as ngs
    import scipy.sparse as sp

    space = gf.space
    free = np.asarray(free)
    if free.dtype == bool:
        free = np.flatnonzero(free)
    column = np.full(space.ndof, -1)
    column[np.asarray(free)] = np.arange(len(free))
    elements, point_element = np.unique(np.asarray(element_numbers), return_inverse=True)
    element_dofs = [[dof for dof in space.GetDofNrs(ngs.ElementId(ngs.VOL, int(number)))
                     if dof >= 0 and column[dof] >= 0] for number in elements]
    neighbours = {}                  # DOF -> the DOFs it shares a sampled element with
    for dofs in element_dofs:
        for dof in dofs:
            neighbours.setdefault(dof, set()).update(dofs)
    colour = {}
    for dof, others in neighbours.items():      # greedy: unlike every neighbour's
        taken = {colour[other] for other in others if other in colour}
        colour[dof] = next(c for c in range(len(taken) + 1) if c not in taken)
    width = max((len(dofs) for dofs in element_dofs), default=0)
    table = np.full((len(elements), width), -1)
    for e, dofs in enumerate(element_dofs):
        table[e, :len(dofs)] = dofs
    table_colour = np.where(table >= 0, np.vectorize(lambda d: colour.get(d, -1))(
        np.maximum(table, 0)), -1) if width else table
    vector = gf.vec.FV().NumPy()
    vector[:] = 0.0
    count = np.asarray(evaluate(), float).shape[1]
    rows, columns, values = [], [], []
    for c in range(max(colour.values(), default=-1) + 1):
        vector[:] = 0.0
        vector[[dof for dof, k in colour.items() if k == c]] = 1.0
        sampled = np.asarray(evaluate(), float)            # (P, V)
        hit = table_colour[point_element] == c             # (P, width): at most one per row
        point, slot = np.nonzero(hit)
        dof_column = column[table[point_element[point], slot]]
        rows.append((point[:, None] * count + np.arange(count)).ravel())
        columns.append(np.repeat(dof_column, count))
        values.append(sampled[point].ravel())
    vector[:] = 0.0
    return sp.csr_matrix((np.concatenate(values + [np.zeros(0)]),
                          (np.concatenate(rows + [np.zeros(0, int)]),
                           np.concatenate(columns + [np.zeros(0, int)]))),
                         shape=(len(point_element) * count, len(free)))


def green_kernels(points, normals, microphone, wavenumber: float, baffle: bool):
    """The Kirchhoff-Helmholtz integrand's kernels at sphere points (module doc), for both
    engines' spheres (:class:`SphereSampler`, :class:`copdea_fem.fe.quadrant.forced.QuadrantSphere`).

    Parameters
    ----------
    points, normals : numpy.ndarray
        Sphere points y [m] and their outward unit normals n_y, shape (..., 3).
    microphone : array_like
        The field point x [m], (3,).
    wavenumber : float
        k = omega / c_a [1/m].
    baffle : bool
        The half-space Green's function ``G(x, y) + G(x', y)`` (x' mirrored in z = 0: zero
        normal derivative on the rigid plane z = 0) instead of the free-space one.

    Returns
    -------
    d_green, green : numpy.ndarray
        ``dG/dn_y`` [1/m^2] and ``G = e^{ikd}/(4 pi d)`` [1/m] (outgoing for the
        ``e^{-i omega t}`` convention), shape (...), so that
        ``p(x) = int [p dG/dn_y - G dp/dn_y] dS_y``.
    """
    x = np.asarray(microphone, float)
    d_green = np.zeros(np.shape(points)[:-1], complex)
    green = np.zeros_like(d_green)
    for source in ([x, x * np.array([1, 1, -1])] if baffle else [x]):
        d_vec = points - source
        d = np.linalg.norm(d_vec, axis=-1)
        g = np.exp(1j * wavenumber * d) / (4 * np.pi * d)
        d_green += (1j * wavenumber - 1 / d) * g * np.einsum("...k,...k->...", d_vec,
                                                              normals) / d
        green += g
    return d_green, green


def kirchhoff_kernels(sampler: SphereSampler, microphone, wavenumber: float, baffle: bool):
    """(K_p, K_g) per sphere point: p(x) = sum_i K_p,i p_i - K_g,i (dp/drho)_i (module doc):
    :func:`green_kernels` averaged over the azimuth, times the polar weights and areas."""
    phi = 2 * np.pi * np.arange(AZIMUTH_POINTS) / AZIMUTH_POINTS
    rs, zs = sampler.r[:, None], sampler.z[:, None]
    y = np.stack([rs * np.cos(phi), rs * np.sin(phi), zs * np.ones_like(phi)], axis=-1)
    d_green, green = green_kernels(y, y / sampler.radius, microphone, wavenumber, baffle)
    area = sampler.weight * sampler.radius ** 2 * np.sin(sampler.polar)
    return d_green.mean(axis=1) * 2 * np.pi * area, green.mean(axis=1) * 2 * np.pi * area


def radiated_power(p_values, dp_values, sampler: SphereSampler, omega: float,
                   density: float) -> np.ndarray:
    """1/2 Re int_Sigma p conj(v_rho) dS [W] of sphere samples (points, columns)."""
    velocity = dp_values / (1j * omega * density)
    area = 2 * np.pi * sampler.weight * sampler.radius ** 2 * np.sin(sampler.polar)
    return 0.5 * np.real(np.einsum("i,i...->...", area, p_values * np.conj(velocity)))
