r"""The 3-D quadrant's fields at points of the prestressed device
(:class:`copdea_fem.fe.points.PointSampler`, the mapping to reference points there).

The membrane's Cartesian displacement lives on the meshed part; a point of another quadrant
is folded into the meshed one (:meth:`copdea_fem.fe.symmetry.Symmetry.fold`) and the field
unfolded with its sector's parities, ``u(q x) = s(q) R_q u(x)`` (:mod:`copdea_fem.fe.symmetry`).
"""

from __future__ import annotations

import numpy as np

from copdea_fem.fe.points import PointSampler


class QuadrantPoints(PointSampler):
    """Fields of a 3-D state at points of the prestressed device (module notes)."""

    def __init__(self, state, positions):
        import ngsolve as ngs

        super().__init__(state, positions)
        membrane = ~self.on_disc
        x, y = self.reference[membrane, 0], self.reference[membrane, 1]
        xs, ys, self.fold_x, self.fold_y = state.symmetry.fold(x, y)
        self.mesh_points = state.mesh(xs, ys, np.zeros_like(xs), ngs.BND)
        self.field = ngs.GridFunction(state.space)

    @staticmethod
    def prestress_profile(state, radii) -> np.ndarray:
        """(u_r, u_z) [m] of the prestress at reference radii on the x axis (axisymmetric:
        any angle will do; the mirror line's points nudged into the mesh)."""
        import ngsolve as ngs

        xs, ys, _, _ = state.symmetry.fold(radii, np.zeros_like(radii))
        points = state.mesh(xs, ys, np.zeros_like(xs), ngs.BND)
        return np.asarray(state.displacement(points)).reshape(-1, 3)[:, [0, 2]]

    def membrane_displacement(self, vector, operators, family: str = "cos") -> np.ndarray:
        """Cartesian displacement (M, 3) of a field of ``operators``' symmetry sector (None:
        a whole mesh) at the membrane's points, unfolded by its parities."""
        return self._unfolded(vector, operators.sector)

    def displacement(self, mode) -> np.ndarray:
        out = np.zeros((len(self.positions), 3), dtype=complex)
        if np.any(~self.on_disc):
            out[~self.on_disc] = self._unfolded(mode.vector, mode.sector)
        out[self.on_disc, 2] = complex(mode.disc_displacement)
        return out

    def _unfolded(self, vector, sector) -> np.ndarray:
        parts = []
        for part in (np.real(vector), np.imag(vector)):
            self.field.vec.FV().NumPy()[:] = part
            parts.append(np.asarray(self.field(self.mesh_points)).reshape(-1, 3))
        values = parts[0] + 1j * parts[1]
        if sector is not None:
            sign = sector.sign(self.fold_x, self.fold_y)
            values = values * (sign[:, None] * np.column_stack(
                [self.fold_x, self.fold_y, np.ones_like(self.fold_x)]))
        return values
