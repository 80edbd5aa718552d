r"""FE fields at points of the prestressed device: what both engines' point samplers share.

A point (a vibrometer's scan point, say) lies on the *prestressed* device: the membrane's
outer rim in the plane z = 0, the disc at z = +load.z.  The FE fields live on the
*reference* (flat) membrane, so each point is first mapped back to the material point that
the prestress carried there: in the plane, the deformed position is ``x = X + u_0(X)``
(``u_0`` the prestress displacement, its in-plane part), solved for ``X`` by the
fixed-point iteration ``X <- x - u_0,xy(X)`` (a contraction: the prestress's radial
displacement changes by far less than the radius over the membrane, ``|du_0,r/dR| < 1``).
A point whose deformed radius is inside the disc's rim lies on the (rigid) disc.

A mode's velocity at the point, in the convention of :class:`copdea_fem.fe.modes.Mode`
(fields go as ``e^{-i omega t}``), is ``v = -i omega u`` with ``omega = 2 pi (f + i f_im)``
and ``u`` the mode's displacement there; on the disc ``u = (0, 0, w_d)`` (the disc's rigid
axial motion, ``Mode.disc_displacement``).

:class:`PointSampler` holds that mapping; each engine's subclass evaluates its own fields
(the engine's :meth:`copdea_fem.fe.engines.Engine.point_sampler`): the 3-D quadrant folds a
point into the meshed quadrant and unfolds the field with its sector's parities
(:mod:`copdea_fem.fe.quadrant.points`), the axisymmetric engine revolves its order-m
amplitudes (:mod:`copdea_fem.fe.axisymmetric.points`).
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


class PointSampler:
    """FE fields of one prestressed state at points of the prestressed device.

    Parameters
    ----------
    state : copdea_fem.fe.prestress.PrestressedState
        The prestressed state the fields belong to (the engine's own).
    positions : (P, 3) array
        Points [m] on the prestressed device, in the model's frame.

    Attributes
    ----------
    reference : (P, 2) array
        The material point (x, y) [m] of each point on the flat reference membrane.
    on_disc : (P,) bool array
        Points on the rigid disc.
    """

    def __init__(self, state, positions):
        self.state = state
        self.positions = np.asarray(positions, dtype=float).reshape(-1, 3)
        r_o, r_i = float(state.outer_radius), float(state.inner_radius)
        radius = np.hypot(self.positions[:, 0], self.positions[:, 1])
        self.on_disc = radius < r_i if r_i > 0 else np.zeros(len(radius), dtype=bool)
        self.angle = np.arctan2(self.positions[:, 1], self.positions[:, 0])
        self.reference_radius = self._reference_radii(radius.clip(max=r_o), r_i, r_o)
        self.reference = np.column_stack([self.reference_radius * np.cos(self.angle),
                                          self.reference_radius * np.sin(self.angle)])

    # -- what an engine's sampler provides ----------------------------------------------
    @staticmethod
    def prestress_profile(state, radii) -> np.ndarray:
        """(u_r, u_z) [m] of the prestress at reference radii ``radii`` [m] on the membrane:
        array (len, 2) (the prestress is axisymmetric: any angle will do)."""
        raise NotImplementedError

    def membrane_displacement(self, vector, operators, family: str) -> np.ndarray:
        """Cartesian displacement (M, 3) of a membrane field at the membrane's points
        (``~on_disc``) [units of ``vector``]; ``vector`` on the membrane space's DOFs of
        ``operators`` (a part's membrane operators: its sector or order), ``family`` the
        order's ``"cos"`` or ``"sin"`` member (the axisymmetric engine's)."""
        raise NotImplementedError

    def displacement(self, mode) -> np.ndarray:
        """Cartesian displacement (P, 3) of ``mode`` at the points [units of the mode
        vector: peak |u| = 1 for a normalised mode]."""
        raise NotImplementedError

    # -- shared -------------------------------------------------------------------------
    def _reference_radii(self, radius, r_i, r_o) -> np.ndarray:
        """Reference radii of the membrane points (module notes); the disc's keep theirs."""
        low, high = r_i + RIM_NUDGE * r_o, r_o * (1 - RIM_NUDGE)
        membrane = ~self.on_disc
        reference = radius.copy()
        if np.any(membrane):
            deformed = radius[membrane]
            guess = deformed.clip(low, high)
            for _ in range(REFERENCE_ITERATIONS):
                update = (deformed - self.prestress_profile(self.state, guess)[:, 0]).clip(
                    low, high)
                change = float(np.max(np.abs(update - guess), initial=0.0))
                guess = update
                if change <= 1e-12 * r_o:
                    break
            reference[membrane] = guess
        return reference

    def field_displacement(self, vector, disc=0.0, *, operators, family="cos") -> np.ndarray:
        """Cartesian displacement (P, 3) of any membrane field at the points [units of
        ``vector``]: ``vector`` on the membrane space's DOFs of ``operators`` (a part's
        membrane operators, ``operators.to_full``), ``disc`` the disc's axial displacement,
        ``family`` the order's ``"cos"`` or ``"sin"`` member on the axisymmetric engine."""
        out = np.zeros((len(self.positions), 3), dtype=complex)
        if np.any(~self.on_disc):
            out[~self.on_disc] = self.membrane_displacement(vector, operators, family)
        out[self.on_disc, 2] = complex(disc)
        return out

    def velocities(self, modes) -> np.ndarray:
        """Cartesian velocity ``-i omega u`` (P, 3, K) of each mode at the points [1/s per
        unit of the mode vector]."""
        out = np.zeros((len(self.positions), 3, len(modes)), dtype=complex)
        for k, mode in enumerate(modes):
            omega = 2 * np.pi * complex(mode.freq_hz, mode.freq_im_hz)
            out[:, :, k] = -1j * omega * self.displacement(mode)
        logger.debug("sampled %d modes at %d points", len(modes), len(self.positions))
        return out

    @classmethod
    def prestressed_positions(cls, state, reference_xy, disc_z: float) -> np.ndarray:
        """Where material points of the flat reference device lie on the prestressed one:
        (P, 3) [m] in the model's frame (the inverse of the sampler's mapping).

        Parameters
        ----------
        state : copdea_fem.fe.prestress.PrestressedState
        reference_xy : (P, 2) array
            Reference points [m]; those inside the disc's rim (``state.inner_radius``) are
            on the rigid disc.
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
            u_r, u_z = cls.prestress_profile(state, inside).T
            deformed = radius[membrane] + u_r
            out[membrane] = np.column_stack([deformed * np.cos(angle[membrane]),
                                             deformed * np.sin(angle[membrane]), u_z])
        return out


__all__ = ["PointSampler", "REFERENCE_ITERATIONS", "RIM_NUDGE"]
