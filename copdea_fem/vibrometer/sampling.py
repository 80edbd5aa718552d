r"""FE mode shapes where a vibrometer measured: along a scan's channels.

A scan point lies on the *prestressed* device (:mod:`copdea_fem.measured.scan`: the
membrane's outer rim in the plane z = 0, the disc at z = +load.z).  The engine of the solve
samples its fields there (:meth:`copdea_fem.fe.engines.Engine.point_sampler`: each point
mapped back to the material point of the flat reference membrane that the prestress carried
there, :mod:`copdea_fem.fe.points`); a mode's velocity at the point is ``v = -i omega u`` in
the convention of :class:`copdea_fem.fe.Mode` (fields go as ``e^{-i omega t}``), and a
channel measures ``v . d`` along its unit direction ``d`` (:func:`project_channels`).
"""

from __future__ import annotations

import numpy as np


def project_channels(point_values, channel_point, channel_direction) -> np.ndarray:
    """Per-channel values ``v(point) . direction``: (C, ...) from point vectors (P, 3, ...).

    Parameters
    ----------
    point_values : (P, 3, ...) array
        A vector field (Cartesian) at the scan points, e.g.
        :meth:`copdea_fem.fe.points.PointSampler.velocities`.
    channel_point : (C,) int array
        The point of each channel.
    channel_direction : (C, 3) array
        Each channel's unit direction.
    """
    values = np.asarray(point_values)[np.asarray(channel_point, dtype=int)]
    direction = np.asarray(channel_direction, dtype=float)
    return np.einsum("cd...,cd->c...", values, direction)


def mode_shapes_at_scan(solution, modes, scan) -> np.ndarray:
    """The FE modes' velocity shapes along a scan's channels: (C, K) complex.

    Parameters
    ----------
    solution : copdea_fem.fe.SolveResult
        The solve the modes belong to (its engine samples its prestressed state).
    modes : sequence of copdea_fem.fe.Mode
        Structural modes of the solve (either engine).
    scan : copdea_fem.measured.ScanData
    """
    sampler = solution.engine.point_sampler(solution.state, scan.positions)
    return project_channels(sampler.velocities(modes), scan.channel_point,
                            scan.channel_direction)


__all__ = ["mode_shapes_at_scan", "project_channels"]
