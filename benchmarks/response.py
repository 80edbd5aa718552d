"""The bundled 3-D study's ``response`` against its ``solve``: ``python -m benchmarks.response
[--repeat 5] [--accuracy] [--set SECTION.KEY=VALUE ...]``.

Each repetition runs, as a user does, a fresh ``python -m copdea_fem.cli solve`` and a fresh
``python -m copdea_fem.cli response`` of ``studies/g1_z16_v2.yaml`` (square frame, 3-D quadrant,
the paper's modal b/m; default ``response.method``), both with files off
(``output.paraview=false``, ``output.plots=false``: the CSV and JSON tables remain), one
right after the other, the order alternating between repetitions; wall and CPU (user +
system of the child) seconds per run.  On a shared machine only the ratio of two runs that
close in time means something: the report gives the medians of each and the median of the
per-repetition ratios response / solve (target: <= 4).  Each response's peaks are checked
against the coupled frequencies of its paired solve (``peaks_where_solve_puts_them``: every
peak within one chirp line of a structural mode of ``modes.csv``).

``--accuracy`` then, in one process, solves the response twice on the same prepared problem:
``response.method: modal`` (the modal path, converged in its band: the reference) and the
default method; it reports the largest relative difference of the average axial and radial
velocity at the modal path's peaks, on all lines, and of the on-axis SPL at the peaks [dB].
"""

from __future__ import annotations

import argparse
import csv
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks import ROOT, run_cli, spread

STUDY = ROOT / "studies" / "g1_z16_v2.yaml"
#: files off: no ParaView files, no plots (both commands still write their tables)
FILES_OFF = ["output.paraview=false", "output.plots=false"]
#: the target for the median of the pairs' ratios response / solve
TARGET_RATIO = 4.0


def _command(command: str, overrides: list[str], directory: Path) -> dict:
    """One fresh ``python -m copdea_fem.cli COMMAND`` of :data:`STUDY` into ``directory``:
    wall and CPU (user + system) seconds of the child."""
    _, wall, cpu = run_cli([command, str(STUDY), "--quiet", "--out", str(directory)],
                           FILES_OFF + overrides)
    return {"wall_s": wall, "cpu_s": cpu}


def _structural_frequencies(modes_csv: Path) -> np.ndarray:
    with open(modes_csv, newline="") as handle:
        return np.array([float(row["freq_hz"]) for row in csv.DictReader(handle)
                         if row["kind"] != "air"])


def _peaks_at_modes(response_dir: Path, solve_dir: Path) -> dict:
    """The response's peaks [Hz] and the distance to the nearest structural mode of the
    solve [Hz], against the chirp's line spacing."""
    document = json.loads((response_dir / "response.json").read_text())
    lines = np.loadtxt(response_dir / "response_average.csv", delimiter=",", skiprows=1)[:, 0]
    spacing = float(np.median(np.diff(lines)))
    modes = _structural_frequencies(solve_dir / "modes.csv")
    distances = [float(np.min(np.abs(modes - peak))) for peak in document["peaks_hz"]]
    return {"method": document["method"], "peaks_hz": document["peaks_hz"],
            "distance_to_solve_mode_hz": distances, "line_spacing_hz": spacing,
            "peaks_where_solve_puts_them": bool(max(distances, default=0.0) <= spacing)}


def run_pairs(repeat: int, overrides: list[str]) -> dict:
    """``repeat`` pairs solve / response, the order alternating (module doc)."""
    runs = {"solve": [], "response": []}
    peaks = None
    for k in range(repeat):
        order = ("solve", "response") if k % 2 == 0 else ("response", "solve")
        with tempfile.TemporaryDirectory() as directory:
            folders = {name: Path(directory) / name for name in order}
            for name in order:
                runs[name].append(_command(name, overrides, folders[name]))
                print(f"run {k + 1}/{repeat} {name}: {runs[name][-1]['wall_s']:.2f} s wall, "
                      f"{runs[name][-1]['cpu_s']:.2f} s CPU", file=sys.stderr)
            peaks = _peaks_at_modes(folders["response"], folders["solve"])
    report = {"study": str(STUDY.relative_to(ROOT)), "overrides": FILES_OFF + overrides,
              "repeat": repeat, "target_ratio": TARGET_RATIO}
    for name, values in runs.items():
        report[name] = {key: spread(r[key] for r in values) for key in ("wall_s", "cpu_s")}
    report["ratio_response_to_solve"] = {
        key: {"median": statistics.median(r[key] / s[key] for r, s in
                                          zip(runs["response"], runs["solve"])),
              "all": [round(r[key] / s[key], 3) for r, s in zip(runs["response"],
                                                                  runs["solve"])]}
        for key in ("wall_s", "cpu_s")}
    report["target_met"] = report["ratio_response_to_solve"]["wall_s"]["median"] <= TARGET_RATIO
    report["peaks"] = peaks
    return report


def run_accuracy(overrides: list[str]) -> dict:
    """The default method against the modal path on one prepared problem (module doc)."""
    from scipy.signal import find_peaks

    from copdea_fem.fe import engine_for
    from copdea_fem.forced_response.run import forced_response, prepare_order_zero
    from copdea_fem.study import load_study, parse_overrides

    study = load_study(STUDY, overrides=parse_overrides(FILES_OFF + overrides))
    problem = prepare_order_zero(study, engine=engine_for(study))
    results, seconds = {}, {}
    for name, method in (("default", study.response.method), ("modal", "modal")):
        variant = type(problem)(study.replace({"response.method": method}), problem.state,
                                problem.coupled, problem.forced, dict(problem.timings),
                                problem.sector)
        start = time.perf_counter()
        results[name] = forced_response(variant)
        seconds[name] = time.perf_counter() - start
    mine, modal = results["default"], results["modal"]
    total = modal.average_axial + modal.average_radial
    index, _ = find_peaks(total)
    index = index[total[index] >= 0.05 * total.max()]       # the resonances, not the ripple
    errors = {}
    for name in ("average_axial", "average_radial"):
        a, b = getattr(mine, name), getattr(modal, name)
        errors[name] = {"peaks": float(np.max(np.abs(a[index] / b[index] - 1))),
                        "all_lines": float(np.max(np.abs(a / b - 1)))}
    return {"method": mine.method, "peaks_hz": [float(f) for f in mine.frequency_hz[index]],
            "relative_error": errors,
            "spl_axis_db_at_peaks": float(np.max(np.abs(mine.spl_db[index, 0]
                                                        - modal.spl_db[index, 0]))),
            "seconds_in_process": seconds}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.response")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    parser.add_argument("--accuracy", action="store_true",
                        help="also the default method against the modal path (slow)")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat {args.repeat} is not allowed; allowed: >= 1")
    report = run_pairs(args.repeat, args.set)
    if args.accuracy:
        report["accuracy"] = run_accuracy(args.set)
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
