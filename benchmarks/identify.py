"""Benchmark of the scan identification: ``python -m benchmarks.identify [--repeat 5]
[--commands] [--correlate]``.

A PSV-sized scan - 84 points x 3 velocity components x 800 lines (1.25 ... 1000 Hz at
1.25 Hz, the paper's chirp) - made analytically from a few modal poles (the closed form
``H_c = i w sum_r [A_cr / (i w - s_r) + conj(A_cr) / (i w - conj(s_r))]``, real shapes,
a split pair 1 % apart), with complex Gaussian noise 60 dB below the largest value; the
points are the paper's grid (5 rings x 16 on the membrane, 4 on the disc) on G1 at
z = 16 mm.  Timed: :func:`copdea_fem.vibrometer.identification.identify` on it (LSCF up to
order 120 on the principal response functions, the automatic choice, LSFD on all 252
channels), and reading the same scan from a binary UFF export
(:func:`~copdea_fem.measured.read_scan`).  Each repetition runs in process after one
warm-up; reported: median and range, and the largest frequency error of the identified
modes.  Target: <= 10 s for the identification.

``--commands``: the whole ``copdea-fem identify measured.yaml`` (the binary export written
by :func:`~copdea_fem.measured.write_scan` beside a measured.yaml on the bundled scan
example's base study, one condition at z = 16 mm, 2 kV) as a user runs it, a fresh
``python -m copdea_fem.cli`` process per repetition, its files written: wall seconds,
median and range, target <= 2 s; ``--correlate`` adds ``copdea-fem correlate`` on the same
files (the FE solve included), target <= 8 s.
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
#: Whole-command targets [s]: ``identify`` and ``correlate`` on the export.
COMMAND_TARGETS = {"identify": 2.0, "correlate": 8.0}
#: The measured.yaml of the command benchmark (the base study: the scan example's).
MEASURED_YAML = """name: psv_benchmark
base_study: base_study.yaml
model: fe
conditions:
- name: z16_v2
  set:
    load.z: 16 mm
    load.voltage: 2 kV
  scan: psv.uff
"""


def paper_grid(outer_radius=0.0355, inner_radius=0.017, disc_z=0.016) -> np.ndarray:
    """(84, 3) points [m]: 5 rings x 16 on the membrane (on the device's meridian), 4 on
    the disc."""
    from copdea_fem.measured.geometry import device_meridian

    meridian = device_meridian(outer_radius, inner_radius, disc_z)
    radii = inner_radius + (outer_radius - inner_radius) * np.array([0.1, 0.3, 0.5, 0.7, 0.9])
    points = []
    for ring, radius in enumerate(radii):
        z = np.interp(radius, meridian[1:, 0], meridian[1:, 1])
        for k in range(16):
            angle = 2 * math.pi * (k + 0.5 * (ring % 2)) / 16
            points.append([radius * math.cos(angle), radius * math.sin(angle), z])
    for k in range(4):
        angle = math.pi / 2 * k + math.pi / 4
        points.append([0.5 * inner_radius * math.cos(angle),
                       0.5 * inner_radius * math.sin(angle), disc_z])
    return np.array(points)


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
    positions = paper_grid()
    return ScanData(path=Path("benchmark.uff"), nodes=np.arange(1, n_points + 1),
                    positions=positions, channel_point=np.repeat(np.arange(n_points), 3),
                    channel_direction=np.tile(np.eye(3), (n_points, 1)),
                    frequencies=frequencies, values=values)


def write_export(folder: Path) -> Path:
    """The scan as a binary UFF export beside its measured.yaml in ``folder``; the
    measured.yaml's path."""
    import shutil

    from copdea_fem.measured import write_scan

    root = Path(__file__).resolve().parents[1]
    write_scan(folder / "psv.uff", make_scan(), binary=True)
    shutil.copy(root / "studies" / "measured_scan_example" / "base_study.yaml",
                folder / "base_study.yaml")
    (folder / "measured.yaml").write_text(MEASURED_YAML, encoding="utf-8")
    return folder / "measured.yaml"


def time_commands(repeat: int, commands) -> dict:
    """Wall seconds of each command (``identify``, ``correlate``) on the export, fresh
    processes, interleaved: {command: [seconds, ...]}."""
    import os
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=str(root))
    seconds = {command: [] for command in commands}
    with tempfile.TemporaryDirectory() as folder:
        measured = write_export(Path(folder))
        for run in range(repeat):
            for command in commands:
                out = Path(folder) / f"{command}_{run}"
                start = time.perf_counter()
                subprocess.run([sys.executable, "-m", "copdea_fem.cli", command,
                                str(measured), "--out", str(out), "--quiet"], check=True,
                               env=env, cwd=folder, capture_output=True)
                seconds[command].append(time.perf_counter() - start)
    return seconds


def main(argv=None) -> int:
    from copdea_fem.vibrometer.identification import identify
    from copdea_fem.measured import read_scan, write_scan

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--commands", action="store_true",
                        help="also time the whole identify command (fresh processes)")
    parser.add_argument("--correlate", action="store_true",
                        help="with --commands: correlate too (FE solve included)")
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
    met = median <= TARGET_SECONDS
    if args.commands:
        commands = ("identify", "correlate") if args.correlate else ("identify",)
        for command, seconds in time_commands(args.repeat, commands).items():
            middle = statistics.median(seconds)
            target = COMMAND_TARGETS[command]
            met = met and middle <= target
            print(f"copdea-fem {command} (whole command, fresh process): median {middle:.2f} s "
                  f"(range {min(seconds):.2f}-{max(seconds):.2f}, {len(seconds)} runs); target "
                  f"<= {target:g} s: {'met' if middle <= target else 'MISSED'}")
    return 0 if met else 1


if __name__ == "__main__":
    raise SystemExit(main())
