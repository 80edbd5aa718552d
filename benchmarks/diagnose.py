"""Benchmark of a diagnosis with the FE as model of record: ``python -m benchmarks.diagnose``.

Each repetition runs ``copdea-fem diagnose`` in-process in a fresh subprocess
with an empty FE cache (cold: every FE solve is paid) or, with ``--warm``, with
the cache the first repetition filled.  ``--executors serial,local,dask`` runs each listed
way of solving the cold FE studies side by side, interleaved (one run of each per
repetition): ``serial`` one at a time in the process (``executor="inline"``), ``local``
the default spawned processes (``executor="processes"``, ``--workers``, default 2),
``dask`` a local Dask cluster of as many worker processes (``executor="dask"``, no
scheduler), and reports the medians, their
ratios to ``serial`` and ``local``, and whether every variant reached the same diagnosis
(missing effects, gaps, the FE frequencies of every condition).  Default data set:
``studies/measured_fe_example`` (G1, 5 conditions, coupled 3-D FE data with the
square frame; dry base): five 3-D coupled solves when cold.  Reported: median
and spread of the wall time, FE solves and FE seconds, the verdict.  Target of
issue 13: <= 2 min for 5 conditions, cold cache, on the 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "studies" / "measured_fe_example" / "measured.yaml"


#: variant -> (executor, workers or None for --workers)
VARIANTS = {"serial": ("inline", 1), "local": ("processes", None), "dask": ("dask", None)}


def _once(measured: str, cache: str, variant: str = "local", workers: int | None = None) -> dict:
    import copdea_fem as cf
    executor, fixed = VARIANTS[variant]
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        diagnosis = cf.diagnose(measured, fe_cache=cache, executor=executor,
                                workers=fixed or workers)
        diagnosis.write(Path(out) / "report")
        seconds = time.perf_counter() - start
    result = diagnosis.result
    entries = {path.stem: {m["label"]: m["frequency_hz"]
                           for m in json.loads(path.read_text())["modes"]}
               for path in Path(cache).glob("*.json")}
    return {"seconds": seconds, "fe_solves": result.fe_solves, "fe_seconds": result.fe_seconds,
            "missing": result.missing_effects, "gap_before": result.gap_before,
            "gap_after": result.gap_after, "fe_entries": entries}


def _compare(args) -> dict:
    """``--executors``: the listed variants interleaved, cold, in fresh processes."""
    names, workers = args.executors.split(","), args.workers or 2
    for name in names:
        if name not in VARIANTS:
            raise SystemExit(f"--executors: {name!r} is not one of {', '.join(VARIANTS)}")
    runs = {name: [] for name in names}
    with tempfile.TemporaryDirectory() as shared:
        for index in range(args.repeat):
            for name in names:
                cache = tempfile.mkdtemp(dir=shared)
                output = subprocess.run([sys.executable, "-m", "benchmarks.diagnose", "--once",
                                         args.measured, cache, "--variant", name, "--workers",
                                         str(workers)], check=True, capture_output=True,
                                        text=True).stdout
                runs[name].append(json.loads(output.strip().splitlines()[-1]))
                print(f"run {index + 1} {name}: {runs[name][-1]['seconds']:.1f} s, "
                      f"{runs[name][-1]['fe_solves']} FE solves", file=sys.stderr, flush=True)
    report = {"measured": args.measured, "cache": "cold", "workers": workers,
              "repeat": args.repeat}
    for name, values in runs.items():
        seconds = [r["seconds"] for r in values]
        report[name] = {"median_s": statistics.median(seconds), "all_s": seconds,
                        "fe_solves": values[0]["fe_solves"], "missing": values[0]["missing"]}
    for reference in ("serial", "local"):
        if reference in runs:
            report[f"speed_up_over_{reference}"] = {
                name: report[reference]["median_s"] / report[name]["median_s"] for name in runs}
    first = next(iter(runs.values()))[0]
    every = [r for values in runs.values() for r in values]
    report["same_missing_effects"] = all(r["missing"] == first["missing"] for r in every)
    report["same_fe_studies"] = all(set(r["fe_entries"]) == set(first["fe_entries"])
                                    for r in every)
    report["largest_relative_gap_difference"] = max(
        abs(r[gap] / first[gap] - 1) for r in every for gap in ("gap_before", "gap_after"))
    # the FE entries' frequencies: the same studies solved in other processes (and, one at
    # a time in the diagnosis's own process, NGSolve's threads), so round-off apart
    report["largest_relative_fe_frequency_difference"] = max(
        (abs(frequency / first["fe_entries"][key][label] - 1)
         for r in every for key, modes in r["fe_entries"].items()
         for label, frequency in modes.items()
         if label in first["fe_entries"].get(key, {})), default=None)
    return report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.diagnose")
    parser.add_argument("measured", nargs="?", default=str(EXAMPLE))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--warm", action="store_true", help="reuse the FE cache after run 1")
    parser.add_argument("--executors", help="compare these, cold, interleaved: a "
                        "comma-separated list of " + ", ".join(VARIANTS))
    parser.add_argument("--workers", type=int,
                        help="processes of the local and dask variants (default: 2 with "
                        "--executors, else the diagnosis's default)")
    parser.add_argument("--once", nargs=2, metavar=("MEASURED", "CACHE"), help=argparse.SUPPRESS)
    parser.add_argument("--variant", default="local", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.once:
        print(json.dumps(_once(*args.once, args.variant, args.workers)))
        return 0
    if args.executors:
        print(json.dumps(_compare(args), indent=1))
        return 0
    runs = []
    with tempfile.TemporaryDirectory() as shared:
        for index in range(args.repeat):
            cache = shared if args.warm else tempfile.mkdtemp(dir=shared)
            output = subprocess.run([sys.executable, "-m", "benchmarks.diagnose",
                                     "--once", args.measured, cache], check=True,
                                    capture_output=True, text=True).stdout
            runs.append(json.loads(output.strip().splitlines()[-1]))
            print(f"run {index + 1}: {runs[-1]['seconds']:.1f} s, {runs[-1]['fe_solves']} FE "
                  f"solves ({runs[-1]['fe_seconds']:.1f} s), missing {runs[-1]['missing']}",
                  flush=True)
    seconds = [r["seconds"] for r in runs]
    print(json.dumps({"measured": args.measured, "cache": "warm" if args.warm else "cold",
                      "median_s": statistics.median(seconds), "min_s": min(seconds),
                      "max_s": max(seconds), "runs": runs}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
