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

**Segments.**  A segmented electrode (``electrodes.segments``) is the same mechanism: the
segment k driven alone by ``V~_k`` is the weight

    w_k(r, theta) = 1_[r1, r2](r) 1_[a, b](theta)                                  (3)

on the co-energy (the film outside the segment sees only the bias; the forcing is linear in
``w``), and a drive of every segment at once is the sum of the segments' forcings, each
times its complex AC voltage.  :class:`SegmentWeight` is that indicator; on the
axisymmetric engine its Fourier orders (eq. 4 there) split it into the orders' families,
its radial factor staying inside the forcing integral; on the 3-D quadrant it is folded as
(2).

**The weight protocol** (what :meth:`copdea_fem.fe.engines.Engine.electrode_forcing` asks of
a weight; :class:`ElectrodeImperfection` and :class:`SegmentWeight` follow it): a weight
``w(r, theta) = rho(r) sum_m (c_m cos m theta + s_m sin m theta)`` has

- ``family_weights(m) -> (c_m, s_m)`` [-]: the factors of the order-m forcing of the weight
  ``cos(m theta)`` on the cos and sin families (``c_0``: of the uniform weight on m = 0);
- ``radial_weight(r)``: ``rho(r)`` at reference radii [m] (NumPy or NGSolve), an indicator
  (0 or 1: the axisymmetric engine weights the co-energy by the voltage ``V rho``), or None
  where it is 1 (then nothing enters the forcing integral: the uniform electrode's numbers);
- ``weight(x, y)`` and ``sector_weight(sector, x, y)``: ``w`` and the folded W_s of (2).

:func:`segment_weights` gives a study's segments as weights with their complex drives.
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

    def radial_weight(self, r):
        """None: the weight (1) does not vary with the radius."""
        return None

    def mirror_of(self, other):
        """None: not compared (:meth:`SegmentWeight.mirror_of`)."""
        return None

    def sector_weight(self, sector, x, y):
        """W_s of (2) for a :class:`copdea_fem.fe.symmetry.Sector` (``None``: the whole
        device, ``w`` itself)."""
        return folded_weight(self, sector, x, y)


@dataclass(frozen=True)
class SegmentWeight:
    r"""The indicator of an electrode segment as a co-energy weight (module notes, eq. 3):
    ``w(r, theta) = 1_[r1, r2](r) 1_arc(theta)``, the arc from ``start`` counter-clockwise
    over ``span`` [rad].

    Its Fourier orders (the integrals of ``w cos m theta``, ``w sin m theta`` over the turn
    divided by ``2 pi`` for m = 0, ``pi`` for m >= 1), with ``a = start``, ``b = start + span``:

        c_0 = 1_r (b - a) / (2 pi),  c_m = 1_r (sin mb - sin ma) / (m pi),
        s_m = 1_r (cos ma - cos mb) / (m pi)                                         (4)

    (exactly 1 and 0 for a whole turn).  The radial factor ``1_r`` stays in the forcing
    integral (:meth:`radial_weight`); the angular factors are :meth:`family_weights`.

    Attributes
    ----------
    start : float
        Where the arc starts [rad], counter-clockwise from the x axis.
    span : float
        The arc's angle [rad], in (0, 2 pi].
    radii : tuple of float or None
        ``(r1, r2)`` [m] on the flat pre-stretched reference; None = the whole membrane.
    """

    start: float = 0.0
    span: float = 2 * math.pi
    radii: tuple | None = None

    def __post_init__(self):
        if not 0.0 < self.span <= 2 * math.pi:
            raise ValueError(f"segment span = {self.span!r} rad is not allowed; allowed: "
                             "(0, 2 pi]")
        if self.radii is not None and not 0.0 <= self.radii[0] < self.radii[1]:
            raise ValueError(f"segment radii = {self.radii!r} m are not allowed; allowed: "
                             "(r1, r2) with 0 <= r1 < r2")

    @classmethod
    def from_degrees(cls, theta, radii=None) -> SegmentWeight:
        """The weight of a segment ``theta = (from, to)`` [deg] (wrapping through 0 where
        ``to < from``, the whole turn where ``to - from >= 360``), ``radii`` [m] or None."""
        start, end = float(theta[0]), float(theta[1])
        span = 360.0 if end - start >= 360.0 else (end - start) % 360.0
        return cls(math.radians(start % 360.0), math.radians(span),
                   None if radii is None else (float(radii[0]), float(radii[1])))

    @property
    def whole_turn(self) -> bool:
        """Whether the arc is the whole circle."""
        return self.span >= 2 * math.pi

    def family_weights(self, m: int) -> tuple[float, float]:
        """(c_m, s_m) of (4) without the radial factor [-]: the factors of the order-m
        forcing of the weight ``cos(m theta)`` on the cos and sin families."""
        if m == 0:
            return self.span / (2 * math.pi), 0.0
        if self.whole_turn:
            return 0.0, 0.0
        a, b = self.start, self.start + self.span
        return ((math.sin(m * b) - math.sin(m * a)) / (m * math.pi),
                (math.cos(m * a) - math.cos(m * b)) / (m * math.pi))

    def mirror_of(self, other):
        """``(qx, qy)`` with ``other.weight(x, y) = self.weight(qx x, qy y)``: ``other`` is
        this segment mirrored in the y axis (qx = -1), the x axis (qy = -1) or both (a half
        turn); ``None`` otherwise (or ``other`` not a segment).  The arc from a to b maps
        to ``(-b, -a)`` in the x axis, ``(pi - b, pi - a)`` in the y axis, ``(a + pi, b +
        pi)`` in both; a sector's folded weights (2) of the two then differ by the sector's
        sign ``s(qx, qy)`` alone."""
        if not isinstance(other, SegmentWeight) or other.span != self.span \
                or other.radii != self.radii:
            return None
        end = self.start + self.span
        for (qx, qy), start in (((1, -1), -end), ((-1, 1), math.pi - end),
                                ((-1, -1), self.start + math.pi)):
            if abs(float(_wrap(other.start - start + math.pi)) - math.pi) <= 1e-12:
                return qx, qy
        return None

    def radial_weight(self, r):
        """``1_[r1, r2](r)`` at reference radii ``r`` [m] (NumPy arrays or NGSolve
        coefficient functions); None where the segment spans the whole membrane (no radial
        factor)."""
        if self.radii is None:
            return None
        r1, r2 = self.radii
        return _step(r - r1) * _step(r2 - r)

    def weight(self, x, y):
        """w(r, theta) of (3) at points (x, y) [m] (NumPy arrays or NGSolve coefficient
        functions)."""
        if self.whole_turn:
            angular = 1.0
        else:
            offset = _wrap(_angle(x, y) - self.start)           # in [0, 2 pi)
            angular = _step(self.span - offset)
        radial = self.radial_weight(_radius(x, y))
        return angular if radial is None else angular * radial

    def sector_weight(self, sector, x, y):
        """W_s of (2) for a :class:`copdea_fem.fe.symmetry.Sector` (``None``: the whole
        device, ``w`` itself)."""
        return folded_weight(self, sector, x, y)


def folded_weight(weight, sector, x, y):
    """W_s of (2) of any weight with a ``weight(x, y)`` method, on a
    :class:`copdea_fem.fe.symmetry.Sector` (``None``: the whole device, ``w`` itself)."""
    if sector is None:
        return weight.weight(x, y)
    from copdea_fem.fe.symmetry import QUADRANTS
    total = 0
    for qx, qy in QUADRANTS:
        total = total + float(sector.sign(qx, qy)) * weight.weight(qx * x, qy * y)
    return 0.25 * total


#: The name of the one segment of a study without ``electrodes.segments``.
WHOLE_ELECTRODE = "electrode"


def segment_weights(study) -> list[tuple[str, SegmentWeight, complex]]:
    """The segments of a study as weights: ``[(name, weight, drive), ...]``, ``drive`` the
    complex AC volts of the segment per volt of input ``amplitude e^{i phase}`` [V/V]
    (``electrodes.segments``, :mod:`copdea_fem.study.segments`); a study without segments
    has one, :data:`WHOLE_ELECTRODE`, over the whole membrane, driven by 1."""
    segments = study.electrodes.segments
    if not segments:
        return [(WHOLE_ELECTRODE, SegmentWeight(), 1.0 + 0.0j)]
    return [(segment.name, SegmentWeight.from_degrees(segment.theta, segment.r),
             complex(segment.drive.amplitude * np.exp(1j * math.radians(segment.drive.phase))))
            for segment in segments]


def _radius(x, y):
    if isinstance(x, np.ndarray) or np.isscalar(x):
        return np.hypot(x, y)
    import ngsolve as ngs
    return ngs.sqrt(x * x + y * y)


def _step(value):
    """1 where ``value > 0``, else 0 (NumPy or NGSolve)."""
    if isinstance(value, np.ndarray) or np.isscalar(value):
        return np.where(np.asarray(value) > 0, 1.0, 0.0)
    import ngsolve as ngs
    return ngs.IfPos(value, 1.0, 0.0)


def _wrap(angle):
    """An angle [rad] in (-3 pi, pi] moved into [0, 2 pi)."""
    if isinstance(angle, np.ndarray) or np.isscalar(angle):
        return np.mod(angle, 2 * np.pi)
    import ngsolve as ngs
    once = angle + ngs.IfPos(-angle, 2 * math.pi, 0.0)
    return once + ngs.IfPos(-once, 2 * math.pi, 0.0)


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


__all__ = ["WHOLE_ELECTRODE", "ElectrodeImperfection", "SegmentWeight", "folded_weight",
           "segment_weights"]
