"""``excite`` against ``response`` and ``statespace`` against ``solve`` of one study:
``python -m benchmarks.excite [--case 3d|axisymmetric] [--only excite|statespace]
[--repeat 3] [--target LABEL] [--set SECTION.KEY=VALUE ...]``.

Case ``3d`` (default): ``studies/g1_segments_quick.yaml`` (G1, z = 16 mm, 2 kV, coupled,
coarse mesh, eight 45-degree sectors; its default engine, the 3-D quadrant), both pairs.
Case ``axisymmetric``: the state-space tests' study (``studies/g1_z16_v2_quick.yaml`` on the
axisymmetric engine in a baffle, :data:`AXISYMMETRIC`) with three segments, an inner ring
and the outer ring split in two halves (:data:`THREE_SEGMENTS`: the halves drive every odd
order, whose static correction the modal model sums above the band), ``statespace`` with
``solve`` only.  Each repetition runs, as a user does, a fresh
``python -m copdea_fem.cli`` of each command with files off (``output.paraview=false``,
``output.plots=false``: the CSV, JSON, NPZ and MAT files remain), the commands of a pair one
right after the other, the order alternating between repetitions: ``excite --target
(2,1)`` with ``response``, then ``statespace`` with ``solve``.  Wall and CPU (user + system
of the child) seconds per run; the report gives the medians of each command and the
median of the per-repetition ratios, against the targets (issue 41, item 8):
``excite / response <= 2`` (:data:`EXCITE_TARGET`) and ``statespace / solve <= 1.5``
(:data:`STATESPACE_TARGET`).  On a shared machine only the ratio of two runs close in time
means something.  Each command's own stage timings (its summary's ``timings:`` line) are
kept for the last repetition.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

from benchmarks import ROOT, run_cli, spread

STUDY = ROOT / "studies" / "g1_segments_quick.yaml"
AXISYMMETRIC_STUDY = ROOT / "studies" / "g1_z16_v2_quick.yaml"
#: The axisymmetric case's overrides: the engine, a baffle (its frames), three segments.
THREE_SEGMENTS = "electrodes.segments=[" \
    "{name: inner, theta: [0, 360], r: [0.017, 0.026]}, " \
    "{name: east, theta: [-90, 90], r: [0.026, 0.0355]}, " \
    "{name: west, theta: [90, 270], r: [0.026, 0.0355]}]"
AXISYMMETRIC = ["mesh.engine=axisymmetric", "geometry.frame=baffle", THREE_SEGMENTS]
FILES_OFF = ["output.paraview=false", "output.plots=false"]
EXCITE_TARGET = 2.0
STATESPACE_TARGET = 1.5
PAIRS = (("excite", "response"), ("statespace", "solve"))
#: case -> (study, overrides, pairs)
CASES = {"3d": (STUDY, [], PAIRS),
         "axisymmetric": (AXISYMMETRIC_STUDY, AXISYMMETRIC, PAIRS[1:])}


def _command(command: str, study: Path, overrides: list[str], directory: Path,
             target: str) -> dict:
    """One fresh ``python -m copdea_fem.cli COMMAND`` of ``study`` into ``directory``:
    wall and CPU seconds of the child, and its summary's ``timings:`` line."""
    arguments = [command, str(study), "--out", str(directory)]
    if command == "excite":
        arguments += ["--target", target]
    output, wall, cpu = run_cli(arguments, FILES_OFF + overrides)
    stages = [line.strip() for line in output.splitlines()
              if line.strip().startswith("timings:")]
    return {"wall_s": wall, "cpu_s": cpu, "timings": stages[-1] if stages else ""}


def run(repeat: int, overrides: list[str], target: str, case: str = "3d",
        only: str | None = None) -> dict:
    study, case_overrides, pairs = CASES[case]
    if only is not None:
        pairs = tuple(pair for pair in pairs if pair[0] == only)
    overrides = case_overrides + list(overrides)
    runs = {name: [] for pair in pairs for name in pair}
    for k in range(repeat):
        for pair in pairs:
            order = pair if k % 2 == 0 else pair[::-1]
            with tempfile.TemporaryDirectory() as directory:
                for name in order:
                    runs[name].append(_command(name, study, overrides,
                                               Path(directory) / name, target))
                    print(f"run {k + 1}/{repeat} {name}: {runs[name][-1]['wall_s']:.2f} s "
                          f"wall, {runs[name][-1]['cpu_s']:.2f} s CPU", file=sys.stderr)
    report = {"case": case, "study": str(study.relative_to(ROOT)),
              "overrides": FILES_OFF + overrides, "target": target, "repeat": repeat}
    for name, values in runs.items():
        report[name] = {key: spread(r[key] for r in values) for key in ("wall_s", "cpu_s")}
        report[name]["stages_last_run"] = values[-1]["timings"]
    limits = {"excite": EXCITE_TARGET, "statespace": STATESPACE_TARGET}
    for mine, reference in pairs:
        limit = limits[mine]
        ratios = {key: [r[key] / s[key] for r, s in zip(runs[mine], runs[reference])]
                  for key in ("wall_s", "cpu_s")}
        report[f"ratio_{mine}_to_{reference}"] = {
            key: {"median": statistics.median(values),
                  "all": [round(value, 3) for value in values]}
            for key, values in ratios.items()}
        report[f"ratio_{mine}_to_{reference}"]["target"] = limit
        report[f"ratio_{mine}_to_{reference}"]["target_met"] = \
            statistics.median(ratios["wall_s"]) <= limit
    return report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.excite")
    parser.add_argument("--case", choices=sorted(CASES), default="3d")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--target", default="(2,1)", help="excite's --target")
    parser.add_argument("--only", choices=[pair[0] for pair in PAIRS], default=None,
                        help="run only this command's pair (e.g. statespace: with solve)")
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat {args.repeat} is not allowed; allowed: >= 1")
    if args.only is not None and all(pair[0] != args.only for pair in CASES[args.case][2]):
        parser.error(f"--only {args.only} is not allowed with --case {args.case}; allowed: "
                     + ", ".join(pair[0] for pair in CASES[args.case][2]))
    print(json.dumps(run(args.repeat, args.set, args.target, args.case, args.only), indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
