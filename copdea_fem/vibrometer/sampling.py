r"""FE fields sampled where a vibrometer measured: the scan points and their directions.

A scan point lies on the *prestressed* device (:mod:`copdea_fem.measured.scan`: the
membrane's outer rim in the plane z = 0, the disc at z = +load.z).  The FE fields live on
the *reference* (flat) membrane, so each point is first mapped back to the material point
that the prestress carried there: in the plane, the deformed position is
``x = X + u_0(X)`` (``u_0`` the prestress displacement, its in-plane part), solved for ``X``
by the fixed-point iteration ``X <- x - u_0,xy(X)`` (a contraction: the prestress's radial
displacement changes by far less than the radius over the membrane, ``|du_0,r/dR| < 1``).
A point whose deformed radius is inside the disc's rim lies on the (rigid) disc.

A mode's velocity at the point, in the convention of :class:`copdea_fem.fe.modes.Mode`
(fields go as ``e^{-i omega t}``), is ``v = -i omega u`` with ``omega = 2 pi (f + i f_im)``
and ``u`` the mode's displacement there; on the disc ``u = (0, 0, w_d)`` (the disc's rigid
axial motion, ``Mode.disc_displacement``).  A channel measures ``v . d`` along its unit
direction ``d``.

The two engines store a mode differently:

- the 3-D quadrant (:mod:`copdea_fem.fe.quadrant`): the membrane's Cartesian displacement
  on the meshed part; a point of another quadrant is folded into the meshed one
  (:meth:`copdea_fem.fe.symmetry.Symmetry.fold`) and the field unfolded with its sector's
  parities, ``u(q x) = s(q) R_q u(x)`` (:mod:`copdea_fem.fe.symmetry`);
- the axisymmetric engine (:mod:`copdea_fem.fe.axisymmetric`): order-m amplitudes
  ``(a, b, c)(r)`` on the meridian; the cos family is
  ``u_r = a cos m theta, u_theta = b sin m theta, u_z = c cos m theta``, the sin family its
  copy turned by a quarter wave (``a sin, -b cos, c sin``:
  :func:`copdea_fem.fe.axisymmetric.modes.order_harmonics`, also at m = 0).
"""

from __future__ import annotations

import logging

import numpy as np

logger = logging.getLogger(__name__)

#: Fixed-point iterations of the reference point (the prestress's in-plane stretch moves a
#: point by ~1 % of the radius; each iteration gains about two digits).
REFERENCE_ITERATIONS = 30

#: Relative distance from the rims kept by a sample point: a point search exactly on a rim
#: may return no membrane element (fields change by ~1e-6 there).
RIM_NUDGE = 1e-6


class ScanSampler:
    """FE fields of one prestressed state at a scan's points, along its channels.

    Parameters
    ----------
    state : copdea_fem.fe.prestress.PrestressedState
        The prestressed state the modes belong to (either engine).
    positions : (P, 3) array
        Scan points [m] on the prestressed device, in the model's frame.

    Attributes
    ----------
    reference : (P, 2) array
        The material point (x, y) [m] of each scan point on the flat reference membrane.
    on_disc : (P,) bool array
        Points on the rigid disc.
    """

    def __init__(self, state, positions):
        self.state = state
        self.positions = np.asarray(positions, dtype=float).reshape(-1, 3)
        self.axisymmetric = isinstance_axisymmetric(state)
        r_o, r_i = float(state.outer_radius), float(state.inner_radius)
        radius = np.hypot(self.positions[:, 0], self.positions[:, 1])
        self.on_disc = radius < r_i if r_i > 0 else np.zeros(len(radius), dtype=bool)
        self.angle = np.arctan2(self.positions[:, 1], self.positions[:, 0])
        self._reference_radius = self._reference_radii(radius.clip(max=r_o), r_i, r_o)
        self.reference = np.column_stack([self._reference_radius * np.cos(self.angle),
                                          self._reference_radius * np.sin(self.angle)])
        if not self.axisymmetric:
            self._prepare_quadrant()

    # ---------------------------------------------------------------- reference points
    def _radial_prestress(self, radii) -> np.ndarray:
        """The prestress's radial displacement u_0,r [m] at reference radii (on the x axis:
        the prestress is axisymmetric)."""
        if self.axisymmetric:
            return self.state.profile(radii)[:, 0]
        return _quadrant_prestress(self.state, radii)[:, 0]

    def _reference_radii(self, radius, r_i, r_o) -> np.ndarray:
        """Reference radii of the membrane points (module notes); the disc's keep theirs."""
        low, high = r_i + RIM_NUDGE * r_o, r_o * (1 - RIM_NUDGE)
        membrane = ~self.on_disc
        reference = radius.copy()
        if np.any(membrane):
            deformed = radius[membrane]
            guess = deformed.clip(low, high)
            for _ in range(REFERENCE_ITERATIONS):
                update = (deformed - self._radial_prestress(guess)).clip(low, high)
                change = float(np.max(np.abs(update - guess), initial=0.0))
                guess = update
                if change <= 1e-12 * r_o:
                    break
            reference[membrane] = guess
        return reference

    # ---------------------------------------------------------------- 3-D quadrant
    def _prepare_quadrant(self) -> None:
        import ngsolve as ngs

        state = self.state
        membrane = ~self.on_disc
        x, y = self.reference[membrane, 0], self.reference[membrane, 1]
        xs, ys, self._qx, self._qy = state.symmetry.fold(x, y)
        self._points = state.mesh(xs, ys, np.zeros_like(xs), ngs.BND)
        self._gf = ngs.GridFunction(state.space)

    def _quadrant_displacement(self, vector, sector, disc) -> np.ndarray:
        """Cartesian displacement (P, 3) of a 3-D engine's field at the scan points."""
        out = np.zeros((len(self.positions), 3), dtype=complex)
        membrane = ~self.on_disc
        if np.any(membrane):
            parts = []
            for part in (np.real(vector), np.imag(vector)):
                self._gf.vec.FV().NumPy()[:] = part
                parts.append(np.asarray(self._gf(self._points)).reshape(-1, 3))
            values = parts[0] + 1j * parts[1]
            if sector is not None:
                sign = sector.sign(self._qx, self._qy)
                values = values * (sign[:, None] * np.column_stack(
                    [self._qx, self._qy, np.ones_like(self._qx)]))
            out[membrane] = values
        out[self.on_disc, 2] = complex(disc)
        return out

    # ---------------------------------------------------------------- axisymmetric
    def _order_displacement(self, vector, operators, m, family, disc) -> np.ndarray:
        """Cartesian displacement (P, 3) of an axisymmetric engine's order-m field."""
        import ngsolve as ngs

        from copdea_fem.fe.axisymmetric.modes import order_harmonics

        out = np.zeros((len(self.positions), 3), dtype=complex)
        membrane = ~self.on_disc
        if np.any(membrane):
            gf = ngs.GridFunction(operators.space)
            amplitudes = []
            for part in (np.real(vector), np.imag(vector)):
                gf.vec.FV().NumPy()[:] = part
                amplitudes.append(self.state.line().at(ngs.CF(tuple(operators.amplitudes(gf))),
                                                       self._reference_radius[membrane]))
            a, b, c = (amplitudes[0] + 1j * amplitudes[1]).T
            theta = self.angle[membrane]
            main, cross = order_harmonics(int(m), family, theta)
            u_r, u_t, u_z = a * main, b * cross, c * main
            out[membrane] = np.column_stack([u_r * np.cos(theta) - u_t * np.sin(theta),
                                             u_r * np.sin(theta) + u_t * np.cos(theta), u_z])
        out[self.on_disc, 2] = complex(disc)
        return out

    # ---------------------------------------------------------------- public
    def displacement(self, mode) -> np.ndarray:
        """Cartesian displacement (P, 3) of ``mode`` at the scan points [units of the mode
        vector: peak |u| = 1 for a normalised mode]."""
        if self.axisymmetric:
            return self._order_displacement(mode.vector, mode.operators, mode.m, mode.family,
                                            mode.disc_displacement)
        return self._quadrant_displacement(mode.vector, mode.sector, mode.disc_displacement)

    def field_displacement(self, vector, disc=0.0, *, sector=None, operators=None, m=0,
                           family="cos") -> np.ndarray:
        """Cartesian displacement (P, 3) of any membrane field at the scan points [units of
        ``vector``]: ``vector`` on the membrane space's DOFs (``operators.to_full``), ``disc``
        the disc's axial displacement; 3-D: ``sector`` the field's symmetry sector (None on a
        whole mesh); axisymmetric: ``operators`` (the order's), ``m`` and ``family``
        (``"cos"`` or ``"sin"``, :func:`copdea_fem.fe.axisymmetric.modes.order_harmonics`)."""
        if self.axisymmetric:
            return self._order_displacement(vector, operators, m, family, disc)
        return self._quadrant_displacement(vector, sector, disc)

    def velocities(self, modes) -> np.ndarray:
        """Cartesian velocity ``-i omega u`` (P, 3, K) of each mode at the scan points
        [1/s per unit of the mode vector]."""
        out = np.zeros((len(self.positions), 3, len(modes)), dtype=complex)
        for k, mode in enumerate(modes):
            omega = 2 * np.pi * complex(mode.freq_hz, mode.freq_im_hz)
            out[:, :, k] = -1j * omega * self.displacement(mode)
        logger.debug("sampled %d modes at %d scan points", len(modes), len(self.positions))
        return out


def prestressed_positions(state, reference_xy, disc_z: float) -> np.ndarray:
    """Where material points of the flat reference device lie on the prestressed one: (P, 3)
    [m] in the model's frame (the inverse of :class:`ScanSampler`'s mapping).

    Parameters
    ----------
    state : copdea_fem.fe.prestress.PrestressedState
    reference_xy : (P, 2) array
        Reference points [m]; those inside the disc's rim (``state.inner_radius``) are on
        the rigid disc.
    disc_z : float
        The disc's height ``load.z`` [m] (it moves rigidly along z).
    """
    reference_xy = np.asarray(reference_xy, dtype=float).reshape(-1, 2)
    r_o, r_i = float(state.outer_radius), float(state.inner_radius)
    radius = np.hypot(reference_xy[:, 0], reference_xy[:, 1])
    angle = np.arctan2(reference_xy[:, 1], reference_xy[:, 0])
    on_disc = radius < r_i if r_i > 0 else np.zeros(len(radius), dtype=bool)
    out = np.column_stack([reference_xy, np.full(len(radius), float(disc_z))])
    membrane = ~on_disc
    if np.any(membrane):
        inside = radius[membrane].clip(r_i + RIM_NUDGE * r_o, r_o * (1 - RIM_NUDGE))
        if isinstance_axisymmetric(state):
            u_r, u_z = state.profile(inside).T
        else:
            values = _quadrant_prestress(state, inside)
            u_r, u_z = values[:, 0], values[:, 2]
        deformed = radius[membrane] + u_r
        out[membrane] = np.column_stack([deformed * np.cos(angle[membrane]),
                                         deformed * np.sin(angle[membrane]), u_z])
    return out


def _quadrant_prestress(state, radii) -> np.ndarray:
    """The 3-D engine's prestress displacement (P, 3) [m] at reference radii on the x axis
    (axisymmetric: any angle will do; the mirror line's points nudged into the mesh)."""
    import ngsolve as ngs

    xs, ys, _, _ = state.symmetry.fold(radii, np.zeros_like(radii))
    points = state.mesh(xs, ys, np.zeros_like(xs), ngs.BND)
    return np.asarray(state.displacement(points)).reshape(-1, 3)


def isinstance_axisymmetric(state) -> bool:
    """Whether ``state`` is the axisymmetric engine's (its fields live on the meridian)."""
    from copdea_fem.fe.axisymmetric.prestress import AxisymmetricState

    return isinstance(state, AxisymmetricState)


def project_channels(point_values, channel_point, channel_direction) -> np.ndarray:
    """Per-channel values ``v(point) . direction``: (C, ...) from point vectors (P, 3, ...).

    Parameters
    ----------
    point_values : (P, 3, ...) array
        A vector field (Cartesian) at the scan points, e.g. :meth:`ScanSampler.velocities`.
    channel_point : (C,) int array
        The point of each channel.
    channel_direction : (C, 3) array
        Each channel's unit direction.
    """
    values = np.asarray(point_values)[np.asarray(channel_point, dtype=int)]
    direction = np.asarray(channel_direction, dtype=float)
    return np.einsum("cd...,cd->c...", values, direction)


def mode_shapes_at_scan(state, modes, scan) -> np.ndarray:
    """The FE modes' velocity shapes along a scan's channels: (C, K) complex.

    Parameters
    ----------
    state : copdea_fem.fe.prestress.PrestressedState
    modes : sequence of copdea_fem.fe.modes.Mode
        Structural modes of ``state`` (either engine).
    scan : copdea_fem.measured.ScanData
    """
    sampler = ScanSampler(state, scan.positions)
    return project_channels(sampler.velocities(modes), scan.channel_point,
                            scan.channel_direction)


__all__ = ["ScanSampler", "isinstance_axisymmetric", "mode_shapes_at_scan",
           "prestressed_positions", "project_channels"]
