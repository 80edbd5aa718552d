"""Incompressible-air added mass of axisymmetric membrane modes (effect ``air_loading``).

Without the coupled FE step, the air's inertia on a mode is estimated from
the low-frequency limit of eq. (8): below 1 kHz the air near the membrane
(wavelength >= 0.34 m against r_o = 35.5 mm, k_a r_o <= 0.65) moves almost as
an incompressible fluid, ``div grad p = 0``.  The membrane is taken as a
source distribution in the plane of the frame, with rigid baffle around it
(the infinite-baffle limit of the paper's 80 mm square frame), air on both
faces.

Half space z > 0, velocity potential phi, ``d phi/dz = w(r)`` on z = 0 for
r in the source, 0 elsewhere.  With the Hankel transform
``W(k) = int_0^inf w(r) J0(k r) r dr`` the solution is
``phi = -int_0^inf W(k) J0(k r) exp(-k z) dk`` and the kinetic energy of one
face, ``rho_a / 2 int (-phi) w dS``, gives the added mass of one face

    m_face = 2 pi rho_a int_0^inf W(k)^2 dk                       (A1)

(check: a rigid piston of radius a, ``W = a J1(k a) / k``, gives the textbook
``8/3 rho_a a^3``, Kinsler et al. [30]).  Both faces: ``m_ad = 2 m_face``.

A conical (z > 0) membrane is replaced by the flat source that carries the
same volume flux: a surface ``z = h(r)`` moving by ``(u_r, u_z)`` sweeps
``(u_z - h'(r) u_r)`` per projected area, so ``w = u_z - h' u_r`` over the
projected radius r (exact for z = 0; at z > 0 it keeps the volume velocity
but not the cone's extra radiating area, so it errs low).  Within a ring of
the ring model (Sect. 3.2.1) u and r are linear in R, so ``w`` is linear in r
on each ring, with jumps at the nodes where ``h'`` changes.

For ``w = alpha + beta r`` on ``[a, b]`` the transform is closed form:

    int (alpha + beta r) J0(k r) r dr = alpha [r J1(k r) / k] + beta [F2(k r) / k^3],
    F2(x) = x^2 J1(x) + x J0(x) - int_0^x J0(t) dt,

and (A1) is integrated by 8-point Gauss-Legendre panels of width pi / r_max
in k (W^2 oscillates with period pi / r_max) up to
``k_max = 25 / min(segment length)``.  The tail beyond ``k_max`` is
``~ rho_a r / k_max^2`` per unit jump of w at radius r (piston asymptotics,
``W^2 ~ a / (pi k^3)``): 6e-4 of a piston's added mass (a test checks it),
about 1e-6 for ring-model modes, which vanish at both rims.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.special

_GAUSS_POINTS = 8


def _f2(x):
    """F2(x) = int_0^x t^2 J0(t) dt (closed form; series below x = 0.05)."""
    x = np.asarray(x, float)
    small = x < 0.05
    safe = np.where(small, 0.1, x)
    integral_j0 = scipy.special.itj0y0(safe)[0]
    value = safe ** 2 * scipy.special.j1(safe) + safe * scipy.special.j0(safe) - integral_j0
    series = x ** 3 / 3 - x ** 5 / 20 + x ** 7 / 448
    return np.where(small, series, value)


def _segment_transform(k, start, end, value_start, value_end):
    """int_start^end w(r) J0(k r) r dr for w linear from value_start to value_end [m^3 * w]."""
    slope = (value_end - value_start) / (end - start)
    offset = value_start - slope * start
    k = k[:, None]
    first = lambda r: r * scipy.special.j1(k * r) / k          # noqa: E731  int r J0
    second = lambda r: _f2(k * r) / k ** 3                     # noqa: E731  int r^2 J0
    return (offset * (first(end) - first(start)) + slope * (second(end) - second(start))).sum(1)


def hankel_transform(k, segments) -> np.ndarray:
    """W(k) of a piecewise-linear source [m^2 per unit w].

    Parameters
    ----------
    k : ndarray
        Wavenumbers [1/m], > 0.
    segments : sequence of (start, end, value_start, value_end)
        Radii [m] with start < end and the source's values there (w is
        linear in r in between, zero outside all segments).
    """
    k = np.asarray(k, float)
    total = np.zeros(k.size)
    for start, end, value_start, value_end in segments:
        if end <= start:
            raise ValueError(f"segment ({start!r}, {end!r}) m is not allowed; allowed: start < end")
        total += _segment_transform(k, start, end, np.full(1, value_start),
                                    np.full(1, value_end))
    return total


def face_added_mass(segments, air_density: float) -> float:
    """Added mass of one face, eq. (A1): 2 pi rho_a int_0^inf W(k)^2 dk [kg per unit w^2].

    Parameters
    ----------
    segments : sequence of (start, end, value_start, value_end)
        The source (see :func:`hankel_transform`), radii in m.
    air_density : float
        rho_a [kg/m^3].
    """
    segments = [tuple(map(float, s)) for s in segments]
    r_max = max(s[1] for s in segments)
    shortest = min(s[1] - s[0] for s in segments)
    k_max = 25.0 / shortest
    panel = math.pi / r_max
    edges = np.arange(0.0, k_max + panel, panel)
    nodes, weights = np.polynomial.legendre.leggauss(_GAUSS_POINTS)
    half = 0.5 * panel
    k = (edges[:-1, None] + half * (nodes[None, :] + 1)).ravel()
    w = np.tile(half * weights, edges.size - 1)
    transform = hankel_transform(k, segments)
    return float(2 * math.pi * air_density * np.sum(w * transform ** 2))


def ring_sources(radii, heights, radial, axial, disc_axial: float = 0.0):
    """Flat equivalent source of a ring-model displacement: w = u_z - h' u_r per ring.

    Parameters
    ----------
    radii, heights : ndarray, shape (n + 1,)
        Equilibrium node positions r_k, z_k [m], k = 0 (outer clamp) .. n (disc rim)
        (Sect. 3.2.1).
    radial, axial : ndarray, shape (n + 1,)
        Node displacements u_r, u_z of the mode [m or -].
    disc_axial : float
        Axial displacement of the rigid disc (r < r_n), 0 when it is held.

    Returns
    -------
    list of (start, end, value_start, value_end)
        One segment per ring (and one for a moving disc) over the projected radius.
    """
    r, h = np.asarray(radii, float), np.asarray(heights, float)
    u_r, u_z = np.asarray(radial, float), np.asarray(axial, float)
    segments = []
    for j in range(len(r) - 1):                 # ring j + 1 spans node j (outer) .. j + 1 (inner)
        outer, inner = j, j + 1
        slope = (h[outer] - h[inner]) / (r[outer] - r[inner])
        w_outer = u_z[outer] - slope * u_r[outer]
        w_inner = u_z[inner] - slope * u_r[inner]
        segments.append((r[inner], r[outer], w_inner, w_outer))
    if disc_axial != 0.0:
        segments.append((0.0, r[-1], disc_axial, disc_axial))
    return segments


def ring_mode_added_mass(equilibrium, radial, axial, air_density: float,
                         faces: int = 2) -> float:
    """Incompressible-air added mass of a ring-model mode with the disc held [kg per unit^2].

    ``faces`` = 2: air on both faces of the membrane (Sect. 3.1.2).  For a
    mass-normalised shape (q^T M_s q = 1) the result is m_ad / m directly.
    """
    segments = ring_sources(equilibrium.radii, equilibrium.heights, radial, axial)
    return faces * face_added_mass(segments, air_density)
