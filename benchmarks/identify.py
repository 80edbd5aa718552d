"""Benchmark of the scan identification: ``python -m benchmarks.identify [--repeat 5]``.

A PSV-sized scan - 84 points x 3 velocity components x 800 lines (1.25 ... 1000 Hz at
1.25 Hz, the paper's chirp) - made analytically from a few modal poles (the closed form
``H_c = i w sum_r [A_cr / (i w - s_r) + conj(A_cr) / (i w - conj(s_r))]``, real shapes,
a split pair 1 % apart), with complex Gaussian noise 60 dB below the largest value.
Timed: :func:`copdea_fem.vibrometer.identification.identify` on it (LSCF up to order 120 on the
principal response functions, the automatic choice, LSFD on all 252 channels), and reading
the same scan from a binary UFF export (:func:`~copdea_fem.measured.read_scan`).
Each repetition runs in process after one warm-up; reported: median and range, and the
largest frequency error of the identified modes.  Target: <= 10 s for the identification.
"""

from __future__ import annotations

import argparse
import math
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

#: (frequency [Hz], damping ratio) of the modes
MODES = [(62.0, 0.03), (148.0, 0.015), (300.0, 0.01), (303.0, 0.01), (455.0, 0.012),
         (610.0, 0.015), (760.0, 0.01), (905.0, 0.012)]
TARGET_SECONDS = 10.0


def make_scan(seed: int = 0):
    """The synthetic 84 x 3 x 800 scan (module notes)."""
    from copdea_fem.measured import ScanData

    rng = np.random.default_rng(seed)
    n_points = 84
    frequencies = np.arange(1, 801) * 1.25
    omega = 2 * math.pi * frequencies
    shapes = rng.normal(size=(len(MODES), 3 * n_points))
    values = np.zeros((3 * n_points, frequencies.size), complex)
    for (frequency, damping), shape in zip(MODES, shapes):
        omega_d = 2 * math.pi * frequency
        omega_n = omega_d / math.sqrt(1 - damping ** 2)
        s = complex(-damping * omega_n, omega_d)
        residue = -1j * shape / (2 * omega_d)
        values += np.outer(residue, 1 / (1j * omega - s)) + np.outer(residue.conj(),
                                                                     1 / (1j * omega - s.conjugate()))
    values *= 1j * omega
    size = 1e-3 * np.abs(values).max()
    values += size * (rng.normal(size=values.shape) + 1j * rng.normal(size=values.shape))
    angles = np.linspace(0, 2 * math.pi, n_points, endpoint=False)
    positions = np.column_stack([0.03 * np.cos(angles), 0.03 * np.sin(angles),
                                 np.zeros(n_points)])
    return ScanData(path=Path("benchmark.uff"), nodes=np.arange(1, n_points + 1),
                    positions=positions, channel_point=np.repeat(np.arange(n_points), 3),
                    channel_direction=np.tile(np.eye(3), (n_points, 1)),
                    frequencies=frequencies, values=values)


def main(argv=None) -> int:
    from copdea_fem.vibrometer.identification import identify
    from copdea_fem.measured import read_scan, write_scan

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    scan = make_scan()
    identify(scan)                               # warm-up: imports, first BLAS calls
    identify_seconds, cpu_seconds, read_seconds, errors = [], [], [], []
    with tempfile.TemporaryDirectory() as folder:
        path = write_scan(Path(folder) / "scan.uff", scan, binary=True)
        read_scan(path)
        for _ in range(args.repeat):
            start, cpu = time.perf_counter(), time.process_time()
            modes = identify(scan)
            identify_seconds.append(time.perf_counter() - start)
            cpu_seconds.append(time.process_time() - cpu)
            start = time.perf_counter()
            read_scan(path)
            read_seconds.append(time.perf_counter() - start)
            found = np.array([m.freq_hz for m in modes])
            errors.append(max(min(abs(found - f)) / f for f, _ in MODES)
                          if len(found) else math.inf)
    median = statistics.median(identify_seconds)
    print(f"scan: {scan.n_points} points x 3 components x {scan.frequencies.size} lines, "
          f"{len(MODES)} modes, noise -60 dB")
    print(f"identify: median {median:.2f} s (range {min(identify_seconds):.2f}-"
          f"{max(identify_seconds):.2f}, {args.repeat} runs; CPU "
          f"{statistics.median(cpu_seconds):.2f} s), {len(modes)} modes, largest "
          f"relative frequency error {max(errors):.2e}; target <= {TARGET_SECONDS:g} s: "
          f"{'met' if median <= TARGET_SECONDS else 'MISSED'}")
    print(f"read_scan (binary UFF, {path.name}): median {statistics.median(read_seconds):.3f} s")
    return 0 if median <= TARGET_SECONDS else 1


if __name__ == "__main__":
    raise SystemExit(main())
