"""The enclosure's cost: ``python -m benchmarks.enclosure [--repeat 3]``.

G1 at z = 16 mm, V_b = 2 kV in a baffle on the axisymmetric engine (the ``axisymmetric``
case of :mod:`benchmarks.command`: every coupled mode below 1 kHz with its result files)
without and with a closed cylinder 20 mm deep under the membrane
(``geometry.enclosure: cylinder``), interleaved in fresh processes; medians per stage and
the ratio of the totals, against the target: the enclosed solve no more than 2x the open
one (docs/enclosures.md, docs/benchmarks.md).
"""

from __future__ import annotations

import argparse
import json
import sys

from benchmarks.command import run_pair

#: Largest accepted ratio of the enclosed solve's median total to the open one's.
TARGET_RATIO = 2.0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.enclosure")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    args = parser.parse_args(argv)
    report = run_pair("enclosure", args.repeat, args.set)
    report["target_ratio"] = TARGET_RATIO
    report["target_met"] = report["ratio_total"] <= TARGET_RATIO
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
