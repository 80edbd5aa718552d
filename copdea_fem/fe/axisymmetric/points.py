r"""The axisymmetric engine's fields at points of the prestressed device
(:class:`copdea_fem.fe.points.PointSampler`, the mapping to reference points there).

A field of order m is a set of amplitudes ``(a, b, c)(r)`` on the meridian; the cos family
is ``u_r = a cos m theta, u_theta = b sin m theta, u_z = c cos m theta``, the sin family its
copy turned by a quarter wave (``a sin, -b cos, c sin``:
:func:`copdea_fem.fe.axisymmetric.modes.order_harmonics`, also at m = 0).
"""

from __future__ import annotations

import math

import numpy as np

from copdea_fem.fe.axisymmetric.modes import order_harmonics
from copdea_fem.fe.points import PointSampler


class MeridianPoints(PointSampler):
    """Fields of an axisymmetric state at points of the prestressed device (module notes)."""

    def __init__(self, state, positions):
        super().__init__(state, positions)
        # (id(space), axis_m1) -> (space, :meth:`amplitude_map`)
        self.amplitude_maps: dict = {}

    @staticmethod
    def prestress_profile(state, radii) -> np.ndarray:
        """(u_r, u_z) [m] of the prestress at reference radii (the meridian's profile)."""
        return state.profile(radii)

    def membrane_displacement(self, vector, operators, family: str = "cos",
                              orientation: float = math.nan) -> np.ndarray:
        """Cartesian displacement (M, 3) of a field of ``operators``' order m (its ``family``
        member, turned to ``orientation`` [deg] where given:
        :func:`.modes.order_harmonics`) at the membrane's points."""
        membrane = ~self.on_disc
        a, b, c = (self.amplitude_map(operators) @ np.asarray(vector)).reshape(3, -1)
        theta = self.angle[membrane]
        main, cross = order_harmonics(int(operators.m), family, theta, orientation)
        u_r, u_t, u_z = a * main, b * cross, c * main
        return np.column_stack([u_r * np.cos(theta) - u_t * np.sin(theta),
                                u_r * np.sin(theta) + u_t * np.cos(theta), u_z])

    def amplitude_map(self, operators) -> np.ndarray:
        """The real matrix (3 M, ndof) from a field on ``operators``' space to its amplitudes
        ``(a, b, c)`` at the membrane's M points (rows: all a, then b, then c): the
        amplitudes are linear in the field, so one evaluation per DOF builds it, kept per
        space (the orders m >= 1 share one: a drive's many static orders sample through
        it)."""
        import ngsolve as ngs

        key = (id(operators.space), bool(getattr(operators, "axis_m1", False)))
        held = self.amplitude_maps.get(key)
        if held is not None and held[0] is operators.space:
            return held[1]
        radii = self.reference_radius[~self.on_disc]
        field = ngs.GridFunction(operators.space)
        amplitudes = ngs.CF(tuple(operators.amplitudes(field)))
        line = self.state.line()
        ndof = operators.space.ndof
        matrix = np.empty((3 * radii.size, ndof))
        for dof in range(ndof):
            field.vec.FV().NumPy()[:] = 0.0
            field.vec.FV().NumPy()[dof] = 1.0
            matrix[:, dof] = line.at(amplitudes, radii).T.ravel()
        self.amplitude_maps[key] = (operators.space, matrix)
        return matrix

    def displacement(self, mode) -> np.ndarray:
        out = self.field_displacement(mode.vector, mode.disc_displacement,
                                      operators=mode.operators, family=mode.family)
        if mode.m and not math.isnan(mode.orientation) and np.any(~self.on_disc):
            # a member of a split pair, turned to its orientation (.perturbation)
            out[~self.on_disc] = self.membrane_displacement(mode.vector, mode.operators,
                                                            mode.family, mode.orientation)
        return out
