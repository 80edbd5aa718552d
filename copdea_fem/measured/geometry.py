"""Where the scan points lie on the device: the prestressed surface, and the on-device check.

On-device check.  The prestressed device is axisymmetric: the disc (radius r_i) at
z = z_d = ``load.z``, the membrane from the disc's rim to the clamped outer rim (r_o,
z = 0).  A cheap geometric model of the membrane's meridian stands in for the FE
prestress (which needs a mesh and a Newton solve): the surface of uniform isotropic
tension, the catenoid ``r = a cosh((z - c) / a)`` through (r_o, 0) and (r_i, z_d), on
its stable branch (the larger ``a``; a soap film's shape, exact for any slope when the
tension is uniform).  When no catenoid spans the two rims (z_d too large for the radii)
the small-slope solution of the same problem, ``z = z_d ln(r_o / r) / ln(r_o / r_i)``,
is used.  The FE's hyperelastic membrane has a tension that varies along the meridian,
so its surface departs from this one: by at most 1.3 mm on G1 at z_d = 16 mm, 2 kV (the
axisymmetric FE's prestressed membrane, coarse mesh; the catenoid and the log profile
themselves differ by 1.4 mm there): the check
is for frames that put points off the device (a wrong origin, axis or length unit), and
its default tolerance, a tenth of r_o (3.55 mm on G1), is meant to be wider than that
model error and narrower than those mistakes (a millimetre file read as metres, a 16 mm
shift of the origin).
A full membrane (r_i = 0) is the flat disc of radius r_o at z = 0.
"""

from __future__ import annotations

import math

import numpy as np

from copdea_fem.measured.errors import MeasuredDataError
from copdea_fem.measured.scan import ScanData

#: Default on-device tolerance as a fraction of the outer radius (module notes).
TOLERANCE_OF_OUTER_RADIUS = 0.1


def device_meridian(outer_radius: float, inner_radius: float, disc_z: float,
                    samples: int = 400) -> np.ndarray:
    """(n, 2) points (r, z) [m] of the device's meridian: the disc, then the membrane."""
    if inner_radius <= 0 or disc_z == 0:
        return np.array([[0.0, 0.0], [outer_radius, 0.0]]) if inner_radius <= 0 else \
            np.array([[0.0, disc_z], [inner_radius, disc_z], [outer_radius, 0.0]])
    radii = np.geomspace(inner_radius, outer_radius, samples)
    a = _catenoid_parameter(outer_radius, inner_radius, abs(disc_z))
    if a is None:
        height = np.log(outer_radius / radii) / math.log(outer_radius / inner_radius)
    else:
        neck = a * math.acosh(outer_radius / a)
        height = (neck - a * np.arccosh(np.maximum(radii / a, 1.0))) / abs(disc_z)
    membrane = np.column_stack([radii, math.copysign(1.0, disc_z) * abs(disc_z) * height])
    return np.vstack([[0.0, disc_z], membrane])


def _catenoid_parameter(outer_radius: float, inner_radius: float, height: float):
    """``a`` of the stable catenoid through (r_o, 0) and (r_i, height), else None."""
    from scipy.optimize import brentq

    def mismatch(a):
        neck = a * np.arccosh(outer_radius / a)
        with np.errstate(over="ignore"):
            return a * np.cosh((height - neck) / a) - inner_radius

    grid = np.linspace(inner_radius * 1e-2, inner_radius * (1 - 1e-9), 400)
    values = mismatch(grid)
    changes = np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0)
    if changes.size == 0:
        return None
    i = changes[-1]
    return brentq(mismatch, grid[i], grid[i + 1], xtol=1e-15 * inner_radius)


def device_distances(positions: np.ndarray, outer_radius: float, inner_radius: float,
                     disc_z: float) -> np.ndarray:
    """Distance [m] of each point (P, 3) [m, model frame] from the prestressed device
    (the meridian of :func:`device_meridian` turned about the z axis)."""
    positions = np.asarray(positions, float)
    points = np.column_stack([np.hypot(positions[:, 0], positions[:, 1]), positions[:, 2]])
    meridian = device_meridian(outer_radius, inner_radius, disc_z)
    start, end = meridian[:-1], meridian[1:]
    segment = end - start
    length2 = np.maximum(np.sum(segment ** 2, axis=1), 1e-300)
    along = np.clip(((points[:, None, :] - start[None]) * segment[None]).sum(-1) / length2,
                    0.0, 1.0)
    nearest = start[None] + along[..., None] * segment[None]
    return np.sqrt(((points[:, None, :] - nearest) ** 2).sum(-1)).min(axis=1)


def check_on_device(scan: ScanData, study, tolerance: float | None = None,
                    where: str = "scan") -> float:
    """The largest distance [m] of a scan point from the device (the study's geometry
    and ``load.z``); :class:`MeasuredDataError` when one is farther than ``tolerance``
    [m] (default a tenth of the outer radius), naming the point and the frame."""
    outer = float(study.geometry.outer_radius)
    inner = float(study.geometry.inner_radius)
    disc_z = float(study.load.z)
    tolerance = TOLERANCE_OF_OUTER_RADIUS * outer if tolerance is None else tolerance
    distances = device_distances(scan.positions, outer, inner, disc_z)
    worst = int(np.argmax(distances))
    if distances[worst] > tolerance:
        x, y, z = (1e3 * scan.positions[worst]).tolist()
        raise MeasuredDataError(
            f"{where}: node {int(scan.nodes[worst])} of {scan.path} lies "
            f"{1e3 * distances[worst]:.2f} mm from the device (at x, y, z = {x:.2f}, {y:.2f}, "
            f"{z:.2f} mm in the model's frame; {int(np.sum(distances > tolerance))} of "
            f"{scan.n_points} points off it) is not allowed; allowed: every point within "
            f"{1e3 * tolerance:.2f} mm of the membrane (r_o = {1e3 * outer:g} mm, rim at z = 0) "
            f"or the disc (r_i = {1e3 * inner:g} mm at z = {1e3 * disc_z:g} mm): check "
            "scan_frame (origin, axes, length_unit)")
    return float(distances[worst])


__all__ = ["TOLERANCE_OF_OUTER_RADIUS", "check_on_device", "device_distances",
           "device_meridian"]
