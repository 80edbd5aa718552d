"""Biasing spring with mass: pumping modes P_k (Annex I, eqs 21-23).

The spring (mass M_s spread uniformly over its length L_s, stiffness k_d) is
fixed at X = 0 and carries the disc (mass M_d) at X = L_s, where the
membrane acts as a spring k_DE (the slope of the force-displacement curve at
the operating point).  Longitudinal waves travel along it at
``c_s = sqrt(k_d L_s^2 / M_s)``.  Eq. (21) with the boundary condition of
DESIGN.md, ``M_d x_tt + k_d L_s x_X + k_DE x = 0`` at X = L_s (the printed
``M_d c_s^2 x_tt`` has a stray ``c_s^2``), and ``x = sin(beta X) e^{i w t}``,
``beta = w / c_s``, give eq. (22) as printed:

    -M_d w^2 sin(beta L_s) + k_d L_s beta cos(beta L_s) + k_DE sin(beta L_s) = 0.

With ``theta = beta L_s`` (so ``w^2 = theta^2 k_d / M_s``), ``mu = M_d/M_s``
and ``kappa = k_DE/k_d`` this reads

    f(theta) = sin(theta) (kappa - mu theta^2) + theta cos(theta) = 0.

Where ``sin(theta) != 0``, f = 0 is ``theta cot(theta) + kappa - mu theta^2 =
0``; the left side falls strictly on every interval (j pi, (j+1) pi) (the
derivative of theta cot theta is (sin cos - theta)/sin^2 < 0), from 1 + kappa
(j = 0) or +inf (j >= 1) to -inf: so, for 1 + kappa > 0, there is exactly one
root per interval, root j in (j pi, (j+1) pi).  Pumping mode P_{j+1} is that
root; its shape along the spring is eq. (23), ``sin(theta X / L_s)``.

As M_s -> 0, f/theta = (1 + kappa) - theta^2 (mu + 1/3) + O(theta^4) gives
``w^2 = (k_d + k_DE) / (M_d + M_s/3)``: the spring-mass rule, and in the
limit the rigid-disc value sqrt((k_DE + k_d)/M_d).
"""

from __future__ import annotations

import math

import numpy as np

from copdea_fem.reduced.rings import ReducedModelError


def _check(axial_stiffness, spring_stiffness, disc_mass, spring_mass, spring_length):
    if disc_mass <= 0 or spring_mass < 0 or spring_length <= 0 or spring_stiffness < 0:
        raise ReducedModelError(
            f"disc mass {disc_mass!r} kg, spring mass {spring_mass!r} kg, spring length "
            f"{spring_length!r} m, spring stiffness {spring_stiffness!r} N/m are not allowed; "
            "allowed: disc mass > 0, spring mass >= 0, length > 0, stiffness >= 0")
    if axial_stiffness + spring_stiffness <= 0:
        raise ReducedModelError(
            f"k_DE + k_d = {axial_stiffness + spring_stiffness:.4g} N/m is not allowed; "
            "allowed: > 0 (the disc is statically unstable otherwise)")


def pumping_roots(mass_ratio: float, stiffness_ratio: float, count: int) -> np.ndarray:
    """First ``count`` positive roots theta_k of f(theta) (eq. 22 in theta form) [-].

    Parameters
    ----------
    mass_ratio : float
        mu = M_d / M_s [-].
    stiffness_ratio : float
        kappa = k_DE / k_d [-] (> -1).
    count : int
        How many roots, in increasing order; root j is bracketed in
        (j pi, (j+1) pi) (module notes).
    """
    mu, kappa = float(mass_ratio), float(stiffness_ratio)
    if not (mu > 0 and kappa > -1 and count >= 1):
        raise ReducedModelError(f"mass ratio {mu!r}, stiffness ratio {kappa!r}, count {count!r} "
                                "are not allowed; allowed: mu > 0, kappa > -1, count >= 1")

    def f(theta):
        return math.sin(theta) * (kappa - mu * theta ** 2) + theta * math.cos(theta)

    roots = []
    for j in range(count):
        if j == 0:
            # f/theta = (1 + kappa) - theta^2 (mu + kappa/6 + 1/2) + O(theta^4) > 0 below this
            low = min(0.5 * math.sqrt((1 + kappa) / (mu + abs(kappa) / 6 + 0.5)), math.pi / 2)
            while f(low) <= 0:
                low *= 0.5
        else:
            low = j * math.pi          # f(j pi) = j pi (-1)^j
        high = (j + 1) * math.pi       # f((j+1) pi) = (j+1) pi (-1)^(j+1)
        import scipy.optimize  # at use: 0.15 s of import the modal commands skip
        roots.append(scipy.optimize.brentq(f, low, high, xtol=1e-15, rtol=1e-15))
    return np.array(roots)


def pumping_frequencies(axial_stiffness: float, spring_stiffness: float, disc_mass: float,
                        spring_mass: float, spring_length: float, count: int = 3) -> np.ndarray:
    """Natural frequencies of P1..P_count from eq. (22) [Hz].

    Parameters
    ----------
    axial_stiffness : float
        k_DE, the membrane's axial stiffness at the operating point [N/m].
    spring_stiffness, spring_mass, spring_length : float
        k_d [N/m], M_s [kg], L_s [m] (Table 1).
    disc_mass : float
        M_d [kg] (Table 1).

    With M_s = 0 (or k_d = 0, a spring that transmits nothing) only P1 is
    finite, sqrt((k_DE + k_d) / M_d) / 2 pi; the others are returned as inf.
    """
    _check(axial_stiffness, spring_stiffness, disc_mass, spring_mass, spring_length)
    if spring_mass == 0 or spring_stiffness == 0:
        first = math.sqrt((axial_stiffness + spring_stiffness) / disc_mass) / (2 * math.pi)
        return np.array([first] + [math.inf] * (count - 1))
    theta = pumping_roots(disc_mass / spring_mass, axial_stiffness / spring_stiffness, count)
    return theta * math.sqrt(spring_stiffness / spring_mass) / (2 * math.pi)


def pumping_mode_shape(frequency_hz: float, positions, spring_stiffness: float,
                       spring_mass: float, spring_length: float) -> np.ndarray:
    """Axial displacement along the spring of pumping mode P_k, eq. (23) [-].

    ``sin(w X / c_s)`` at material positions X [m] (0 = fixed end, L_s = disc),
    with c_s = L_s sqrt(k_d / M_s) [m/s].
    """
    wave_speed = spring_length * math.sqrt(spring_stiffness / spring_mass)
    return np.sin(2 * math.pi * frequency_hz * np.asarray(positions, float) / wave_speed)


def spring_dynamic_stiffness(angular_frequency, spring_stiffness: float, spring_mass: float,
                             spring_length: float):
    """Force per displacement the massive spring exerts on the disc, k_d theta cot theta [N/m].

    From eq. (21): x(X) = x_L sin(beta X) / sin(beta L_s), force on the disc
    -k_d L_s x_X(L_s) = -k_d theta cot(theta) x_L with theta = w L_s / c_s =
    w sqrt(M_s / k_d).  Tends to k_d - w^2 M_s / 3 as w -> 0.
    """
    theta = np.asarray(angular_frequency, float) * math.sqrt(spring_mass / spring_stiffness)
    with np.errstate(invalid="ignore", divide="ignore"):
        value = np.where(theta == 0, 1.0, theta / np.tan(np.where(theta == 0, 1.0, theta)))
    return spring_stiffness * value


def pumping_added_mass(modal_stiffness: float, modal_mass: float, disc_amplitude: float,
                       spring_stiffness: float, spring_mass: float,
                       spring_length: float) -> tuple[float, float]:
    """Constant added mass that puts the ring model's P1 where the massive spring puts it.

    The ring model's K_s holds the massless spring k_d.  Replacing it by the
    dynamic stiffness D(w) of :func:`spring_dynamic_stiffness` and projecting
    on the P1 shape (disc displacement ``disc_amplitude`` per unit modal
    coordinate) gives the scalar equation
    ``k - w^2 m + a^2 (D(w) - k_d) = 0``; its root below the spring's first
    fixed-fixed resonance (theta = pi, where D -> -inf) is the P1 frequency,
    and ``m_ad = k / w^2 - m`` (eq. 19).  As M_s -> 0, m_ad -> a^2 M_s / 3.

    Returns
    -------
    added_mass : float
        m_ad [kg] in the units of ``modal_mass``.
    frequency_hz : float
        The P1 frequency with the spring's mass [Hz].
    """
    if spring_mass == 0 or spring_stiffness == 0:
        return 0.0, math.sqrt(modal_stiffness / modal_mass) / (2 * math.pi)
    a2 = disc_amplitude ** 2

    def residual(omega):
        return (modal_stiffness - omega ** 2 * modal_mass
                + a2 * (spring_dynamic_stiffness(omega, spring_stiffness, spring_mass,
                                                 spring_length) - spring_stiffness))

    omega_dry = math.sqrt(modal_stiffness / modal_mass)
    omega_pi = math.pi * math.sqrt(spring_stiffness / spring_mass)
    high = min(omega_dry, omega_pi * (1 - 1e-12))
    if residual(high) >= 0:    # only when disc_amplitude = 0: the spring is not excited
        omega = high
    else:
        import scipy.optimize  # at use: 0.15 s of import the modal commands skip
        omega = scipy.optimize.brentq(residual, 0.0, high, xtol=1e-12 * omega_dry)
    return float(modal_stiffness / omega ** 2 - modal_mass), float(omega / (2 * math.pi))
