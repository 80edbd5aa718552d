r"""The air inside an enclosure: cavity-mode labels and the rigid cylinder's closed form.

Shared by both engines (pure NumPy/SciPy; the engines sample the pressure).

A coupled mode whose air carries most of its kinetic energy (the membrane's share below
:data:`CAVITY_MEMBRANE_ENERGY`; :func:`copdea_fem.fe.modes.membrane_energy_fractions`)
and most of whose air's potential energy ``int |p|^2 / (rho_a c_a^2) dV`` lies inside the
enclosure (share above :data:`CAVITY_SHARE`) is a *cavity mode* and is labelled
``cavity(m,n,p)`` by its pressure pattern, as the structural labels are made (DESIGN.md:
what the mode is, never its rank in a band).  This holds the air modes
(:data:`copdea_fem.fe.modes.AIR`, membrane share below ``air.min_membrane_energy``) and a
vented enclosure's Helmholtz mode, ``cavity(0,0,0)``: the cavity's uniform pressure
breathing through the vent drags the membrane along (share 0.12-0.17 for G1 over a
3-6 mm vent), but the vent's air carries most of the kinetic energy.  Such a mode keeps
its kind (its membrane part is still damped and driven as the structural modes' are,
:mod:`copdea_fem.forced_response`); it takes no structural label, so the membrane's own
(0,1), stiffened above it, keeps ``(0,1)``:

* ``m`` nodal diameters: the circumferential order (the axisymmetric engine's order;
  the 3-D engine reads it off the pressure around the axis, :func:`circumferential_order`);
* ``n`` nodal circles: sign changes of the pressure along the radius, in the cavity's
  meridian (r, z) section through the mode's largest pressure;
* ``p`` nodal surfaces across the depth: sign changes along z.

In a rigid cylinder of radius a and depth L the pressure is
``J_m(j'_mn r / a) cos(p pi z / L) cos(m theta)`` (zero normal gradient on every wall),
so the counts are exactly (m, n, p) of its closed-form frequency
(:func:`rigid_cylinder_frequency`): ``J_m(j'_mn r/a)`` changes sign n times in
0 < r < a (j'_mn is the n-th positive zero of J_m' counting j'_00 = 0 for m = 0, so
(0,0,0) is the uniform pressure) and ``cos(p pi z / L)`` p times.  Under a flexible
membrane the pattern stays the rigid one's as long as the membrane moves little, which
is what makes the mode a cavity mode.
"""

from __future__ import annotations

import math

import numpy as np

#: An air mode with more than this share of its air's potential energy inside the
#: enclosure is a cavity mode (module doc): the sealed cavity holds ~all of it, the
#: outside air's radiating modes ~none, so any split near one half is a mode the
#: vent or the walls share between both and it is labelled ``air``.
CAVITY_SHARE = 0.5

#: A coupled mode whose membrane (+ disc) carries less than this share of the kinetic
#: energy moves mostly air: a cavity mode when its pressure lies inside (module doc).  One
#: half, as :data:`copdea_fem.fe.modes.OUT_OF_PLANE_FRACTION` splits the membrane's kinds:
#: the Helmholtz modes of G1's vented boxes lie at 0.12-0.17, every membrane mode there
#: (the air-stiffened (0,1) included) at 0.62 or more.
CAVITY_MEMBRANE_ENERGY = 0.5


#: A sample below this share of the line's largest |p| is not a sign (as
#: :data:`copdea_fem.fe.modes.NODE_THRESHOLD` for the membrane's nodal circles).
NODE_THRESHOLD = 0.02


def cavity_label(m: int, n: int, p: int) -> str:
    """``cavity(m,n,p)``: m nodal diameters, n nodal circles, p nodal surfaces across the
    depth (module doc)."""
    return f"cavity({m},{n},{p})"


#: Below this share of ``f_max`` a mode of a sealed enclosure's pencil is its static
#: solution (module doc of :func:`without_static_solution`).
STATIC_SHARE = 1e-4


def without_static_solution(result, f_max: float):
    """``result`` (a :class:`copdea_fem.fe.eigen.BandResult`) without the pairs at f = 0.

    The (u, p) pencil (eq. A3 of :mod:`copdea_fem.fe.acoustics`) of a sealed enclosure
    has the eigenvalue omega^2 = 0: a uniform cavity pressure P with the membrane at its
    static deflection under P (``K_a 1 = 0``, and the compressibility term ``omega^2 M_a``
    that would tie P to the volume change vanishes with omega).  It is no vibration;
    pairs with ``|f| <`` :data:`STATIC_SHARE` ``f_max`` are dropped (the genuine modes of
    a membrane over a cavity lie far above: the cavity only stiffens it).
    """
    import dataclasses

    keep = np.abs(result.freq_hz + 1j * result.freq_im_hz) >= STATIC_SHARE * f_max
    if keep.all():
        return result
    return dataclasses.replace(
        result, eigenvalues=result.eigenvalues[keep], freq_hz=result.freq_hz[keep],
        freq_im_hz=result.freq_im_hz[keep], vectors=result.vectors[:, keep],
        residuals=result.residuals[keep])


def label_cavity_modes(modes) -> None:
    """Label the air modes with :attr:`copdea_fem.fe.modes.Mode.cavity_orders`:
    ``cavity(m,n,p)``, plus ``a``/``b`` for the cos/sin member of an m >= 1 pair (as the
    structural pairs, :func:`copdea_fem.fe.modes.pair_letter`); n, the membrane's nodal
    count, is 0 (as an air mode's)."""
    for mode in modes:
        if mode.cavity_orders:
            mode.n = 0
            letter = "" if mode.cavity_orders[0] == 0 or mode.family not in ("cos", "sin") \
                else "ab"[mode.family == "sin"]
            mode.label = cavity_label(*mode.cavity_orders) + letter


def sign_changes(line: np.ndarray) -> int:
    """Sign changes along ``line`` (real samples), samples below :data:`NODE_THRESHOLD`
    of its largest magnitude skipped (NaN: outside the cavity, skipped too)."""
    line = np.asarray(line, dtype=float)
    line = line[np.isfinite(line)]
    if line.size == 0:
        return 0
    peak = np.max(np.abs(line))
    if peak == 0:
        return 0
    signs = np.sign(line[np.abs(line) > NODE_THRESHOLD * peak])
    return int(np.count_nonzero(signs[1:] != signs[:-1]))


def real_pattern(values: np.ndarray) -> np.ndarray:
    """The real pressure pattern of a complex mode: phase turned so that its largest sample
    is real (a standing cavity mode is real up to that phase)."""
    values = np.asarray(values)
    finite = np.where(np.isfinite(values), values, 0)
    peak = finite.ravel()[np.argmax(np.abs(finite))]
    turned = values * (np.conj(peak) / abs(peak) if abs(peak) > 0 else 1.0)
    return np.real(turned)


def nodal_counts(section: np.ndarray) -> tuple[int, int]:
    """(n, p) of a cavity mode from its pressure on a grid of the meridian section.

    Parameters
    ----------
    section : numpy.ndarray, shape (radii, depths)
        Pressure [Pa] (complex allowed) at radii 0 < r < a (rows, increasing) and heights
        from the top z = 0 down to the bottom (columns); NaN outside the cavity.

    Returns
    -------
    (int, int)
        Nodal circles n: sign changes along the row of largest energy; nodal surfaces
        across the depth p: along the column of largest energy (module doc).
    """
    pattern = real_pattern(section)
    energy = np.where(np.isfinite(pattern), pattern, 0) ** 2
    column = int(np.argmax(energy.sum(axis=0)))      # the depth where the rows are strongest
    row = int(np.argmax(energy.sum(axis=1)))
    return sign_changes(pattern[:, column]), sign_changes(pattern[row, :])


def circumferential_order(ring: np.ndarray) -> int:
    """m of a pressure sampled at equispaced angles 0 .. 2 pi on a circle about the axis:
    the dominant Fourier order (for the 3-D engine's cavity modes)."""
    spectrum = np.abs(np.fft.rfft(real_pattern(ring))) ** 2
    return int(np.argmax(spectrum))


def rigid_cylinder_frequency(m: int, n: int, p: int, radius: float, depth: float,
                             sound_speed: float) -> float:
    r"""Natural frequency [Hz] of the (m, n, p) mode of air in a rigid closed cylinder.

    ``f = c / (2 pi) sqrt((j'_mn / a)^2 + (p pi / L)^2)`` (separation of the Helmholtz
    equation with zero normal gradient on the walls; e.g. Kinsler et al., Fundamentals of
    Acoustics, 4th ed., eq. 9.9.3), ``j'_mn`` the n-th zero of ``J_m'`` counted from
    ``j'_00 = 0``.

    Parameters
    ----------
    m, n, p : int
        Nodal diameters, nodal circles, nodal surfaces across the depth (module doc).
    radius, depth : float
        a, L [m].
    sound_speed : float
        c [m/s].
    """
    from scipy.special import jnp_zeros

    if m == 0:
        root = 0.0 if n == 0 else float(jnp_zeros(0, n)[-1])
    else:
        root = float(jnp_zeros(m, n + 1)[-1])
    return sound_speed / (2 * math.pi) * math.hypot(root / radius, p * math.pi / depth)


def lowest_order_frequency(m: int, radius: float, sound_speed: float) -> float:
    """Lowest frequency [Hz] of an order m >= 1 in a rigid cylinder of radius a:
    ``c j'_m1 / (2 pi a)`` (p = 0); 0 for m = 0 (the uniform pressure).  The axisymmetric
    engine takes it as where an enclosure's order m starts (a bowl inside the cylinder of
    its rim lies higher; a flexible top lowers it little, and the order loop looks
    1.5 f_max up: :mod:`copdea_fem.fe.bands`)."""
    return 0.0 if m == 0 else rigid_cylinder_frequency(m, 0, 0, radius, 1.0, sound_speed)
