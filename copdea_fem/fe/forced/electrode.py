r"""An imperfect electrode: a drive that is not the same all round the membrane.

A real COP-DEA's drive is never perfectly axisymmetric: the electrode's coverage and
conductivity, the film's thickness (the co-energy density of eq. 7 goes as ``1/h^2``) vary
round the device.  Model it as a weight on the electrostatic co-energy density,

    w(theta) = 1 + sum_m delta_m cos(m (theta - theta_m)),      m >= 1,            (1)

so that the electrostatic energy is ``-int w (eps/2) (V/h0)^2 det_c dA0`` instead of the
uniform electrode's (``w = 1``; a thickness variation ``h = h0 (1 + t(theta))`` is
``w ~ 1 - 2 t`` to first order).  The prestress is kept axisymmetric (the weight moves it
at first order in delta only by an order-m static deflection that does not change the
linear dynamics at first order), and the voltage forcing ``f = -dR/dV`` of
:mod:`.harmonic` becomes that of the weighted energy: linear in ``w``, it is the uniform
electrode's forcing of the order m = 0 plus, for every m, ``delta_m`` times the forcing of
the weight ``cos(m (theta - theta_m))``.  That forcing drives only the order m (the weight
is a single harmonic and the prestressed device is axisymmetric):

- axisymmetric engine (:func:`copdea_fem.fe.axisymmetric.forcing.order_forcing`): the
  order-m cos family is driven by ``delta_m cos(m theta_m)`` and the sin family by
  ``delta_m sin(m theta_m)`` times the forcing of the weight ``cos(m theta)`` on the
  cos family (``cos(m(theta - theta_m)) = cos m theta cos m theta_m + sin m theta sin m
  theta_m``);
- 3-D quadrant (:func:`copdea_fem.fe.quadrant.forced.quadrant_forcing`): the load of the
  whole device on a field of sector s (``u(q x) = s(q) R_q u(x)``, :mod:`copdea_fem.fe.symmetry`)
  is the quadrant's with the weight folded by the sector's parities,

      W_s(x, y) = 1/4 sum_q s(q) w(q_x x, q_y y)                                   (2)

  (the weighted load density is ``w`` times the uniform one, which the reflections map
  onto itself: ``sum_q s(q) int_quadrant w(q x) L(x) . R_q u(x) ...``); the quadrant's
  forms are a quarter of the device's, hence the 1/4 (``W_s = 1`` for the even-even
  sector of the uniform electrode).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ElectrodeImperfection:
    """The weight (1) of the module notes: ``delta_m`` [-] and ``theta_m`` [rad] per order.

    Attributes
    ----------
    orders : tuple of int
        The orders m >= 1 of the imperfection.
    amplitudes : tuple of float
        ``delta_m`` [-], one per order.
    angles : tuple of float
        ``theta_m`` [rad], one per order.
    """

    orders: tuple = ()
    amplitudes: tuple = ()
    angles: tuple = ()

    def __post_init__(self):
        if not len(self.orders) == len(self.amplitudes) == len(self.angles):
            raise ValueError("ElectrodeImperfection: orders, amplitudes and angles must have "
                             "the same length")
        for m in self.orders:
            if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
                raise ValueError(f"imperfection order m = {m!r} is not allowed; allowed: an "
                                 "integer >= 1 (m = 0 is the uniform electrode)")

    @classmethod
    def random(cls, orders, scale: float, rng) -> ElectrodeImperfection:
        """A random imperfection: ``delta_m = scale LogNormal(0, 1/2)``, ``theta_m``
        uniform in [0, 2 pi / m) (a rotation by 2 pi / m leaves the order m unchanged)."""
        orders = tuple(int(m) for m in orders)
        amplitudes = tuple(float(scale * math.exp(rng.normal(0.0, 0.5))) for _ in orders)
        angles = tuple(float(rng.uniform(0.0, 2 * math.pi / m)) for m in orders)
        return cls(orders, amplitudes, angles)

    def family_weights(self, m: int) -> tuple[float, float]:
        """(cos, sin) factors of the order-m forcing of the weight ``cos(m theta)`` (module
        notes): ``delta_m (cos m theta_m, sin m theta_m)``; (1, 0) for m = 0 (the uniform
        electrode); (0, 0) for an order the imperfection does not hold."""
        if m == 0:
            return 1.0, 0.0
        for order, amplitude, angle in zip(self.orders, self.amplitudes, self.angles):
            if order == m:
                return amplitude * math.cos(m * angle), amplitude * math.sin(m * angle)
        return 0.0, 0.0

    def weight(self, x, y):
        """w(theta) of (1) at points (x, y) [m] (NumPy arrays or NGSolve coefficient
        functions; at the centre the angle is 0)."""
        theta = _angle(x, y)
        total = 1.0
        for m, amplitude, angle in zip(self.orders, self.amplitudes, self.angles):
            total = total + amplitude * _cos(m * (theta - angle))
        return total

    def sector_weight(self, sector, x, y):
        """W_s of (2) for a :class:`copdea_fem.fe.symmetry.Sector` (``None``: the whole
        device, ``w`` itself)."""
        if sector is None:
            return self.weight(x, y)
        from copdea_fem.fe.symmetry import QUADRANTS
        total = 0
        for qx, qy in QUADRANTS:
            total = total + float(sector.sign(qx, qy)) * self.weight(qx * x, qy * y)
        return 0.25 * total


def _angle(x, y):
    if isinstance(x, np.ndarray) or np.isscalar(x):
        return np.arctan2(y, x)
    import ngsolve as ngs
    return ngs.atan2(y, x)


def _cos(value):
    if isinstance(value, np.ndarray) or np.isscalar(value):
        return np.cos(value)
    import ngsolve as ngs
    return ngs.cos(value)


__all__ = ["ElectrodeImperfection"]
