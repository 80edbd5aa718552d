"""Recall and precision of the automatic identification on dense spectra:
``python -m benchmarks.identification_recall [--seeds 10] [--case NAME] [--snr 60]``.

The scans are not made by the FE: the closed form of a sum of modes (Ewins, *Modal
testing*, Eq. 2.92 with ``i w`` for velocity; ``tests/vibrometer_helpers.py``'s
``modal_frfs``) with prescribed membrane shapes ``cos(m theta + phi) sin(n pi (r - r_i) /
(r_o - r_i))`` and a radial in-plane part, so that all three velocity components move, on
the paper's grid (Fig. 5d: 5 rings x 16 points on the membrane, 4 on the disc;
``paper_grid``), 0-1000 Hz at 1.25 or 2.5 Hz lines, complex Gaussian noise ``snr`` dB
below the largest |FRF| (or none).  Per seed, the cases draw:

``cluster3``
    (0,1), (1,1), (2,1) within 5 % (2.5 % apart) at 1 % damping near 400 Hz - the dry
    membrane's cluster - among five isolated modes in 150-850 Hz.
``cluster4``
    four modes 1-1.5 % apart (2-5 % in all) near 600 Hz, damping 0.5-2 %, among four
    isolated modes.
``pairs``
    four split pairs (m,n)a/b 0.2-0.8 % apart at a random orientation, damping 0.5-1 %.
``membrane``
    a membrane spectrum: frequencies proportional to ``j_mn`` (the zeros of J_m, m = 0..4,
    n = 1..3) within 150-850 Hz, every m >= 1 family a pair split 0.3-0.5 %, damping 0.5-2 %.

A true mode is found when one identified mode (one to one, nearest first) lies within
``min(0.4 x the gap to its nearest true neighbour, zeta f)``: closer than to any other true
mode and inside half its half-power width.  Recall = found / true, precision = found /
identified.  Printed per case, spacing and noise: recall, precision (summed over the
seeds), seeds on which every mode was found, the worst frequency error in line spacings,
the worst relative damping error, and the median time per identification.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from vibrometer_helpers import membrane_scan

CASES = ("cluster3", "cluster4", "pairs", "membrane")
SPACINGS = (1.25, 2.5)      # Hz: the paper's chirp, and half its lines
SNRS = (60.0, 40.0, math.inf)
F_MIN, F_MAX = 150.0, 850.0     # Hz: the band of synth_scan's battery exports


def case_modes(case: str, rng) -> list[tuple[tuple, float, float]]:
    """The modes of ``case`` for one seed: ((m, n, orientation), frequency [Hz], damping)."""
    def isolated(frequencies):
        families = [(0, 2), (1, 2), (3, 1), (2, 2), (4, 1), (3, 2)]
        return [((m, n, rng.uniform(0, 2 * math.pi)), f, rng.uniform(0.005, 0.02))
                for (m, n), f in zip(families, frequencies)]

    if case == "cluster3":
        base = rng.uniform(380, 420)
        cluster = [((m, 1, rng.uniform(0, 2 * math.pi)), base * (1 + 0.025 * k), 0.01)
                   for k, m in enumerate((0, 1, 2))]
        return cluster + isolated([170.0, 260.0, 560.0, 690.0, 820.0])
    if case == "cluster4":
        base, frequencies = rng.uniform(560, 620), []
        for _ in range(4):
            frequencies.append(base)
            base *= 1 + rng.uniform(0.01, 0.015)
        cluster = [((m, 1, rng.uniform(0, 2 * math.pi)), f, rng.uniform(0.005, 0.02))
                   for m, f in zip((0, 1, 2, 3), frequencies)]
        return cluster + isolated([180.0, 300.0, 420.0, 800.0])
    if case == "pairs":
        modes = []
        for (m, n), f in zip([(1, 1), (2, 1), (1, 2), (3, 1)], [220.0, 380.0, 540.0, 720.0]):
            f *= rng.uniform(0.97, 1.03)
            phi = rng.uniform(0, 2 * math.pi)
            zeta = rng.uniform(0.005, 0.01)
            split = rng.uniform(0.002, 0.008)
            modes += [((m, n, phi), f, zeta), ((m, n, phi - math.pi / 2), f * (1 + split), zeta)]
        return modes
    if case == "membrane":
        from scipy.special import jn_zeros

        scale = 150.0 / jn_zeros(0, 1)[0] * rng.uniform(1.0, 1.05)
        modes = []
        for m in range(5):
            for n, zero in enumerate(jn_zeros(m, 3), start=1):
                f = scale * zero
                if f > 850:
                    continue
                phi = rng.uniform(0, 2 * math.pi)
                members = [(phi, 1.0)] if m == 0 else [
                    (phi, 1.0), (phi - math.pi / 2, 1 + rng.uniform(0.003, 0.005))]
                for orientation, factor in members:
                    modes.append(((m, n, orientation), f * factor, rng.uniform(0.005, 0.02)))
        return modes
    raise ValueError(f"case = {case!r} is not allowed; allowed: {', '.join(CASES)}")


def case_scan(case: str, seed: int, spacing: float, snr_db: float):
    """(scan, true frequencies [Hz], true damping ratios) of ``case`` for ``seed``."""
    rng = np.random.default_rng(seed)
    modes = sorted(case_modes(case, rng), key=lambda mode: mode[1])
    # the modal participation: a uniform drive moves the axisymmetric modes (m = 0) fully,
    # the others by a device's imperfections only (as synth_scan's exports: a third, scattered)
    modes = [(family, f, zeta, 1.0 if family[0] == 0 else 0.3 * math.exp(rng.normal(0, 0.5)))
             for family, f, zeta in modes]
    axis = F_MIN + spacing * np.arange(round((F_MAX - F_MIN) / spacing) + 1)
    return (membrane_scan(modes, axis, snr_db, rng), np.array([mode[1] for mode in modes]),
            np.array([mode[2] for mode in modes]))


def match(true_frequencies, true_dampings, found_frequencies):
    """Index of the identified mode matched to each true mode (-1: missed); see the notes."""
    gaps = np.full(true_frequencies.size, np.inf)
    if true_frequencies.size > 1:
        difference = np.abs(true_frequencies[:, None] - true_frequencies[None, :])
        np.fill_diagonal(difference, np.inf)
        gaps = difference.min(axis=1)
    tolerance = np.minimum(0.4 * gaps, true_dampings * true_frequencies)
    pairs = sorted((abs(f - t), i, j) for i, t in enumerate(true_frequencies)
                   for j, f in enumerate(found_frequencies) if abs(f - t) <= tolerance[i])
    matched, used = np.full(true_frequencies.size, -1), set()
    for _, i, j in pairs:
        if matched[i] < 0 and j not in used:
            matched[i] = j
            used.add(j)
    return matched


def run_case(case, spacing, snr_db, seeds, **options) -> dict:
    """Identify ``case`` for each seed; the summed counts and the worst errors."""
    from copdea_fem.vibrometer.identification import identify

    true_count = found_count = matched_count = complete = 0
    frequency_error = damping_error = 0.0
    seconds = []
    for seed in seeds:
        scan, frequencies, dampings = case_scan(case, seed, spacing, snr_db)
        start = time.perf_counter()
        modes = identify(scan, **options)
        seconds.append(time.perf_counter() - start)
        found = np.array([mode.freq_hz for mode in modes])
        found_damping = np.array([mode.damping_ratio for mode in modes])
        matched = match(frequencies, dampings, found)
        hit = matched >= 0
        true_count += frequencies.size
        found_count += found.size
        matched_count += int(hit.sum())
        complete += bool(hit.all())
        if hit.any():
            frequency_error = max(frequency_error, float(
                np.max(np.abs(found[matched[hit]] - frequencies[hit])) / spacing))
            damping_error = max(damping_error, float(
                np.max(np.abs(found_damping[matched[hit]] / dampings[hit] - 1))))
    return {"recall": matched_count / true_count,
            "precision": matched_count / found_count if found_count else 1.0,
            "complete": complete, "seeds": len(seeds), "true": true_count,
            "found": found_count, "frequency_error_lines": frequency_error,
            "damping_error": damping_error, "seconds": statistics.median(seconds)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--case", choices=CASES, action="append")
    parser.add_argument("--spacing", type=float, choices=SPACINGS, action="append")
    parser.add_argument("--snr", type=float, action="append",
                        help="noise [dB below the largest |FRF|]; inf: none")
    args = parser.parse_args(argv)
    seeds = range(args.seeds)
    print(f"{'case':9s} {'lines':>5s} {'SNR':>4s}  {'recall':>6s} {'precision':>9s} "
          f"{'all found':>9s} {'df/line':>7s} {'dzeta':>6s} {'time':>6s}")
    for case in args.case or CASES:
        for spacing in args.spacing or SPACINGS:
            for snr in args.snr or SNRS:
                row = run_case(case, spacing, snr, seeds)
                print(f"{case:9s} {spacing:5.2f} {snr:4.0f}  {row['recall']:6.3f} "
                      f"{row['precision']:9.3f} {row['complete']:4d}/{row['seeds']:<4d} "
                      f"{row['frequency_error_lines']:7.3f} {row['damping_error']:6.2f} "
                      f"{row['seconds']:5.2f}s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
