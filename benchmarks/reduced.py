"""Benchmark of the reduced model: ``python -m benchmarks.reduced``.

Times (medians of repeated runs, wall clock, one process):

- setup: static equilibrium + linearisation (eq. 14) + dry modes (eq. 15) +
  Annex I + eq. (19) for G1 at z = 16 mm, V_b = 2 kV with n = 6 rings
  (:func:`copdea_fem.reduced.model.build_reduced`), its memoised static
  solves cleared before every run;
- spectrum: average (5 scan radii) and Q1-Q3 spectra, axial and radial, on
  the 800 lines of the paper's chirp (input lines precomputed once, as a
  controller or optimiser would keep them).

Targets from issue 4: spectrum <= 1 ms, setup <= 1 s.
"""

from __future__ import annotations

import argparse
import statistics
import time

from copdea_fem.reduced import model
from copdea_fem.reduced.model import build_reduced
from copdea_fem.study import parse_study


def _median_seconds(action, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def run(setup_repeats: int = 21, spectrum_repeats: int = 201, rings: int = 6) -> dict:
    """Medians [s] of the setup and of one 800-line spectrum."""
    study = parse_study({"disc": {"motion": "spring"}, "reduced": {"rings": rings},
                         "load": {"z": 0.016, "voltage": 2000.0}}, name="bench_g1_z16_2kV")
    setup = build_reduced(study)
    frequency, lines = setup.chirp.lines()

    def cold_setup():
        # the static solves are memoised (model.operating_point): time them, not the cache
        model.operating_point.cache_clear()
        model._air_added_mass_ratio.cache_clear()
        build_reduced(study)

    setup_time = _median_seconds(cold_setup, setup_repeats)
    spectrum_time = _median_seconds(lambda: setup.reduced.spectra(frequency, lines),
                                    spectrum_repeats)
    chirp_time = _median_seconds(setup.chirp.lines, spectrum_repeats)
    return {"setup_s": setup_time, "spectrum_s": spectrum_time, "chirp_lines_s": chirp_time,
            "lines": int(frequency.size), "rings": rings}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rings", type=int, default=6)
    parser.add_argument("--repeats", type=int, default=21, help="setup repeats (spectrum: x10)")
    args = parser.parse_args(argv)
    result = run(args.repeats, 10 * args.repeats, args.rings)
    print(f"reduced-model benchmark, G1 z = 16 mm, V_b = 2 kV, n = {result['rings']} rings "
          f"(medians)")
    print(f"  setup (static + linearise + modes + Annex I + eq. 19): "
          f"{1e3 * result['setup_s']:8.3f} ms   (target <= 1000 ms)")
    print(f"  spectrum ({result['lines']} lines, average + Q1-Q3):      "
          f"{1e3 * result['spectrum_s']:8.3f} ms   (target <= 1 ms)")
    print(f"  chirp input lines (FFT of 2000 samples, once per chirp): "
          f"{1e3 * result['chirp_lines_s']:8.3f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
