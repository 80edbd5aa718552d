"""An analytic circular membrane as a scanning vibrometer would export it, made without the
FE: modes ``J_m(j_mn r / a) cos(m theta + phi)`` with frequencies proportional to ``j_mn``
(the zeros of J_m), on a PSV-like grid.  The "model" has its pairs in the nominal
orientation (phi = 0 and a quarter wave); the "measurement" has its m = 0 modes 20 % higher
(an effect the model lacks: they cross m >= 1 modes), its pairs split by 0.5 % at a random
orientation, complex shapes and noise.  Shared by the correlation and the diagnosis tests.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import jn_zeros, jv

from copdea_fem.vibrometer.pairing import FEShapes

RADIUS = 0.0355          # m, G1's outer radius (Table 1)
BASE_HZ = 200.0          # Hz per unit of j_mn
M_ZERO_SHIFT = 1.20      # the measured m = 0 modes are 20 % above the model's
ORDERS = [(m, n) for m in range(5) for n in range(1, 4)]


def psv_grid(rings=5, per_ring=16, disc_points=4, inner=0.0):
    """80 membrane points on rings (Fig. 5d's layout, coarse) and 4 near the centre, (84, 3)."""
    radii = inner + (RADIUS - inner) * (np.arange(rings) + 0.6) / (rings + 0.2)
    angles = 2 * np.pi * (np.arange(per_ring) + 0.25) / per_ring
    rr, tt = np.meshgrid(radii, angles, indexing="ij")
    membrane = np.column_stack([rr.ravel() * np.cos(tt.ravel()),
                                rr.ravel() * np.sin(tt.ravel()), np.zeros(rr.size)])
    centre = 0.1 * RADIUS * np.column_stack([np.cos(np.arange(disc_points) * np.pi / 2),
                                             np.sin(np.arange(disc_points) * np.pi / 2),
                                             np.zeros(disc_points)])
    return np.vstack([membrane, centre])


def channels(positions, components=(0, 1, 2)):
    """(channel_point, channel_direction): one channel per point and global axis."""
    points = np.repeat(np.arange(len(positions)), len(components))
    directions = np.tile(np.eye(3)[list(components)], (len(positions), 1))
    return points, directions


def membrane_shape(m, n, phase, positions, channel_point, channel_direction):
    """Normal velocity J_m(j_mn r/a) cos(m theta + phase) along each channel (z only)."""
    x, y = positions[channel_point, 0], positions[channel_point, 1]
    r, theta = np.hypot(x, y), np.arctan2(y, x)
    zero = jn_zeros(m, n)[-1]
    w = jv(m, zero * r / RADIUS) * np.cos(m * theta + phase)
    return w * channel_direction[:, 2]


def model_modes(positions, channel_point, channel_direction):
    """The analytic model: labels, frequencies [Hz], shapes (C, K); pairs at phi = 0, -pi/2."""
    labels, freq, shapes = [], [], []
    for m, n in ORDERS:
        zero = jn_zeros(m, n)[-1]
        members = [("", 0.0)] if m == 0 else [("a", 0.0), ("b", -math.pi / 2)]
        for letter, phase in members:
            labels.append(f"({m},{n}){letter}")
            freq.append(BASE_HZ * zero)
            shapes.append(membrane_shape(m, n, phase, positions, channel_point,
                                         channel_direction))
    order = np.argsort(freq, kind="stable")
    return FEShapes(tuple(labels[k] for k in order), np.array(freq)[order],
                    np.array(shapes).T[:, order])


def measured_modes(rng, positions, channel_point, channel_direction, snr_db=60.0):
    """The measurement: m = 0 moved up 20 %, pairs split by 0.5 % at a random orientation,
    complex shapes (a random phase each) with noise ``snr_db`` below each shape's RMS."""
    truth, freq, shapes = [], [], []
    for m, n in ORDERS:
        zero = jn_zeros(m, n)[-1]
        if m == 0:
            members = [("", M_ZERO_SHIFT, 0.0)]
        else:
            phi = rng.uniform(0, 2 * math.pi)
            members = [("a", 1.0, phi), ("b", 1.005, phi - math.pi / 2)]
        for letter, factor, phase in members:
            shape = membrane_shape(m, n, phase, positions, channel_point, channel_direction)
            shape = shape * np.exp(1j * rng.uniform(0, 2 * math.pi))
            rms = np.sqrt(np.mean(np.abs(shape) ** 2))
            noise = rms * 10 ** (-snr_db / 20) * (rng.standard_normal(shape.shape)
                                                   + 1j * rng.standard_normal(shape.shape))
            truth.append(f"({m},{n})")
            freq.append(BASE_HZ * zero * factor)
            shapes.append(shape + noise / math.sqrt(2))
    order = np.argsort(freq, kind="stable")
    return [truth[k] for k in order], np.array(freq)[order], np.array(shapes).T[:, order]
