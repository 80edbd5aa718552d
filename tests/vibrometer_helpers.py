"""Helpers of the vibrometer tests: a PSV-like scan grid on G1, analytic modal FRFs, files.

The FRFs are the closed form of a sum of modes (Ewins, *Modal testing*, Eq. 2.92 with
i w for velocity), written here independently of the package:

    H_c(w) = i w sum_r [ A_cr / (i w - s_r) + conj(A_cr) / (i w - conj(s_r)) ],
    s_r = -zeta_r w_r + i w_r sqrt(1 - zeta_r^2),  A_cr = -i phi_cr / (2 w_r sqrt(1 - zeta^2))

(a normal mode phi_r of unit modal mass driven by a unit generalised force).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import yaml

from copdea_fem.measured import ScanData

ROOT = Path(__file__).resolve().parents[1]
REALDATA = Path(os.environ.get("COPDEA_FEM_REALDATA", ROOT.parent / "shared" / "realdata"))
BASE_STUDY = ROOT / "studies" / "measured_example" / "base_study.yaml"


def pole(frequency_hz: float, damping_ratio: float) -> complex:
    """s = -zeta w_n + i w_d, with the damped frequency w_d = 2 pi f given."""
    omega_d = 2 * math.pi * frequency_hz
    omega_n = omega_d / math.sqrt(1 - damping_ratio ** 2)
    return complex(-damping_ratio * omega_n, omega_d)


def modal_frfs(frequencies, poles, shapes, response="velocity"):
    """(C, F) FRFs of the closed form above; ``shapes`` (N, C) real."""
    omega = 2 * math.pi * np.asarray(frequencies, float)
    power = {"displacement": 0, "velocity": 1, "acceleration": 2}[response]
    values = np.zeros((np.shape(shapes)[1], omega.size), complex)
    for s, phi in zip(poles, shapes):
        residue = -1j * np.asarray(phi, float) / (2 * s.imag)
        values += (np.outer(residue, 1 / (1j * omega - s))
                   + np.outer(residue.conj(), 1 / (1j * omega - np.conj(s))))
    return values * (1j * omega) ** power


def paper_grid(outer_radius=0.0355, inner_radius=0.017, disc_z=0.016):
    """84 points as Fig. 5d: 80 on the membrane (5 rings x 16), 4 on the disc; z on the
    device's meridian (the package's geometric model, so the points lie on it)."""
    from copdea_fem.measured.geometry import device_meridian

    meridian = device_meridian(outer_radius, inner_radius, disc_z)
    radii = inner_radius + (outer_radius - inner_radius) * np.array([0.1, 0.3, 0.5, 0.7, 0.9])
    points = []
    for ring, radius in enumerate(radii):
        for k in range(16):
            angle = 2 * math.pi * (k + 0.5 * (ring % 2)) / 16
            z = np.interp(radius, meridian[1:, 0], meridian[1:, 1])
            points.append([radius * math.cos(angle), radius * math.sin(angle), z])
    for k in range(4):
        angle = 2 * math.pi * k / 4 + math.pi / 4
        points.append([0.5 * inner_radius * math.cos(angle),
                       0.5 * inner_radius * math.sin(angle), disc_z])
    return np.array(points)


def make_scan(frequencies, poles, point_shapes, positions, nodes=None, response="velocity"):
    """A three-component scan: ``point_shapes`` (N, P, 3) real, one channel per point and
    global axis (x, y, z), node numbers 1..P unless given."""
    n_points = len(positions)
    nodes = np.arange(1, n_points + 1) if nodes is None else np.asarray(nodes)
    shapes = np.asarray(point_shapes).reshape(len(poles), -1)
    return ScanData(path=Path("synthetic.uff"), nodes=nodes, positions=np.asarray(positions),
                    channel_point=np.repeat(np.arange(n_points), 3),
                    channel_direction=np.tile(np.eye(3), (n_points, 1)),
                    frequencies=np.asarray(frequencies, float),
                    values=modal_frfs(frequencies, poles, shapes, response), response=response)


def membrane_shapes(positions, families, outer_radius=0.0355, inner_radius=0.017):
    """(N, P, 3) out-of-plane shapes cos/sin(m theta) sin(n pi (r - r_i) / (r_o - r_i)) on
    the membrane, the disc moving as its rim; ``families``: (m, n, phase) triples."""
    r = np.hypot(positions[:, 0], positions[:, 1])
    theta = np.arctan2(positions[:, 1], positions[:, 0])
    radial = np.clip((r - inner_radius) / (outer_radius - inner_radius), 0, 1)
    out = []
    for m, n, phase in families:
        w = np.cos(m * theta + phase) * np.sin(n * math.pi * radial)
        w = np.where(r < inner_radius, 0.3 * (m == 0), w)
        shape = np.zeros((len(positions), 3))
        shape[:, 2] = w
        shape[:, 0] = 0.2 * w * np.cos(theta)      # a radial part: all three channels move
        shape[:, 1] = 0.2 * w * np.sin(theta)
        out.append(shape)
    return np.array(out)


def write_measured(folder: Path, scans: dict, extra: dict | None = None) -> Path:
    """measured.yaml in ``folder`` with one condition per ``{name: (scan file, set)}``."""
    conditions = []
    for name, (scan_file, overrides) in scans.items():
        conditions.append({"name": name, "set": overrides, "scan": str(scan_file),
                           **(extra or {}).get(name, {})})
    raw = {"name": "scan_test", "base_study": str(BASE_STUDY), "conditions": conditions}
    path = folder / "measured.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def mac(a, b) -> float:
    """Modal assurance criterion of two complex vectors."""
    a, b = np.asarray(a).ravel(), np.asarray(b).ravel()
    return float(abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real))


def add_noise(scan: ScanData, snr_db: float, rng) -> ScanData:
    """``scan`` plus complex Gaussian noise per channel and line, ``snr_db`` below the
    largest |FRF| value of the scan (inf: the scan itself)."""
    if not math.isfinite(snr_db):
        return scan
    size = 10 ** (-snr_db / 20) * np.abs(scan.values).max()
    noise = size * (rng.normal(size=scan.values.shape) + 1j * rng.normal(size=scan.values.shape))
    return ScanData(**{**scan.__dict__, "values": scan.values + noise / math.sqrt(2)})


def membrane_scan(modes, axis, snr_db, rng) -> ScanData:
    """A three-component scan on :func:`paper_grid` of ``modes`` - ((m, n, orientation),
    frequency [Hz], damping ratio, participation) - with :func:`membrane_shapes` scaled by
    their participation, on the frequency ``axis`` [Hz], with :func:`add_noise`."""
    positions = paper_grid()
    shapes = membrane_shapes(positions, [family for family, *_ in modes])
    participation = np.array([mode[3] for mode in modes])
    scan = make_scan(axis, [pole(f, zeta) for _, f, zeta, _ in modes],
                     shapes * participation[:, None, None], positions)
    return add_noise(scan, snr_db, rng)
