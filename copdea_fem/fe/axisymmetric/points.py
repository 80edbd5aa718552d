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

    @staticmethod
    def prestress_profile(state, radii) -> np.ndarray:
        """(u_r, u_z) [m] of the prestress at reference radii (the meridian's profile)."""
        return state.profile(radii)

    def membrane_displacement(self, vector, operators, family: str = "cos",
                              orientation: float = math.nan) -> np.ndarray:
        """Cartesian displacement (M, 3) of a field of ``operators``' order m (its ``family``
        member, turned to ``orientation`` [deg] where given:
        :func:`.modes.order_harmonics`) at the membrane's points."""
        import ngsolve as ngs

        membrane = ~self.on_disc
        field = ngs.GridFunction(operators.space)
        amplitudes = []
        for part in (np.real(vector), np.imag(vector)):
            field.vec.FV().NumPy()[:] = part
            amplitudes.append(self.state.line().at(ngs.CF(tuple(operators.amplitudes(field))),
                                                   self.reference_radius[membrane]))
        a, b, c = (amplitudes[0] + 1j * amplitudes[1]).T
        theta = self.angle[membrane]
        main, cross = order_harmonics(int(operators.m), family, theta, orientation)
        u_r, u_t, u_z = a * main, b * cross, c * main
        return np.column_stack([u_r * np.cos(theta) - u_t * np.sin(theta),
                                u_r * np.sin(theta) + u_t * np.cos(theta), u_z])

    def displacement(self, mode) -> np.ndarray:
        out = self.field_displacement(mode.vector, mode.disc_displacement,
                                      operators=mode.operators, family=mode.family)
        if mode.m and not math.isnan(mode.orientation) and np.any(~self.on_disc):
            # a member of a split pair, turned to its orientation (.perturbation)
            out[~self.on_disc] = self.membrane_displacement(mode.vector, mode.operators,
                                                            mode.family, mode.orientation)
        return out
