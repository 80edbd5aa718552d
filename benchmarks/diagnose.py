"""Benchmark of a diagnosis with the FE as model of record: ``python -m benchmarks.diagnose``.

Each repetition runs ``copdea-fem diagnose`` in-process in a fresh subprocess
with an empty FE cache (cold: every FE solve is paid) or, with ``--warm``, with
the cache the first repetition filled.  Default data set:
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


def _once(measured: str, cache: str) -> dict:
    import copdea_fem as cf
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        diagnosis = cf.diagnose(measured, fe_cache=cache)
        diagnosis.write(Path(out) / "report")
        seconds = time.perf_counter() - start
    result = diagnosis.result
    return {"seconds": seconds, "fe_solves": result.fe_solves, "fe_seconds": result.fe_seconds,
            "missing": result.missing_effects, "gap_before": result.gap_before,
            "gap_after": result.gap_after}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.diagnose")
    parser.add_argument("measured", nargs="?", default=str(EXAMPLE))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--warm", action="store_true", help="reuse the FE cache after run 1")
    parser.add_argument("--once", nargs=2, metavar=("MEASURED", "CACHE"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.once:
        print(json.dumps(_once(*args.once)))
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
