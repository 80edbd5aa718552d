"""The 3-D quadrant with an anisotropic pre-stretch against the perfect quadrant:
``python -m benchmarks.imperfections [--repeat 3] [--study PATH] [--anisotropy 0.02]
[--stages] [--set SECTION.KEY=VALUE ...]``.

Each repetition runs, as a user does, two fresh ``python -m copdea_fem.cli solve`` of the
study (default ``studies/g1_z16_v2.yaml``: G1 at z = 16 mm, 2 kV, square frame, coupled with
the air, the 3-D quadrant), one perfect and one with ``membrane.prestretch_anisotropy`` along
x (``prestretch_axis`` 0: both mirror planes kept, so the quadrant is solved too), the order
alternating between repetitions, files off (``output.paraview=false``,
``output.plots=false``: the CSV and JSON tables remain).  Reported: wall and CPU (user +
system of the child) seconds, the stages' seconds from ``modes.json`` (mesh, prestress,
assembly, eigen, classify), the prestress's Newton iterations, the medians over the
repetitions and the median of the per-repetition ratios imperfect / perfect (target: <= 1,
"no slower").  On a shared machine only the ratio of two runs close in time means something.
Each imperfect run's (1,1) split is printed too, so that a run that silently solved a
perfect device cannot pass.

``--stages`` then times, in this one process on one mesh, the CPU seconds
(:func:`time.process_time`) of the stages an imperfection can change -- the prestress
(Newton), the membrane matrices and the coupled assembly -- ``repeat`` times each, the
two devices alternating: less scatter than whole processes on a shared machine.
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

from benchmarks import ROOT, run_cli, spread

STUDY = ROOT / "studies" / "g1_z16_v2.yaml"
#: files off: no ParaView files, no plots (the command still writes its tables)
FILES_OFF = ["output.paraview=false", "output.plots=false"]
#: the target for the median of the pairs' ratios imperfect / perfect
TARGET_RATIO = 1.0


def _solve(study: Path, overrides: list[str], directory: Path) -> dict:
    """One fresh ``python -m copdea_fem.cli solve`` into ``directory``: wall and CPU (user +
    system) seconds of the child, the stages' seconds and the Newton iterations."""
    _, wall, cpu = run_cli(["solve", str(study), "--quiet", "--out", str(directory)],
                           FILES_OFF + overrides)
    document = json.loads((directory / "modes.json").read_text())
    with open(directory / "modes.csv", newline="") as handle:
        frequencies = {row["label"]: float(row["freq_hz"]) for row in csv.DictReader(handle)}
    split = None
    if "(1,1)a" in frequencies and "(1,1)b" in frequencies:
        split = abs(frequencies["(1,1)a"] - frequencies["(1,1)b"]) / frequencies["(1,1)a"]
    return {"wall_s": wall, "cpu_s": cpu, "stages_s": document.get("timings_s", {}),
            "newton_iterations": document.get("prestress", {}).get("newton_iterations"),
            "modes": len(frequencies), "split_11": split}


def run_pairs(study: Path, repeat: int, anisotropy: float, overrides: list[str]) -> dict:
    """``repeat`` pairs perfect / imperfect, the order alternating (module doc)."""
    variants = {"perfect": overrides,
                "anisotropic": overrides + [f"membrane.prestretch_anisotropy={anisotropy}",
                                            "membrane.prestretch_axis=0"]}
    runs = {name: [] for name in variants}
    for k in range(repeat):
        order = list(variants) if k % 2 == 0 else list(reversed(variants))
        with tempfile.TemporaryDirectory() as directory:
            for name in order:
                runs[name].append(_solve(study, variants[name], Path(directory) / name))
                run = runs[name][-1]
                split = "" if run["split_11"] is None else f", (1,1) split {run['split_11']:.4f}"
                print(f"run {k + 1}/{repeat} {name}: {run['wall_s']:.2f} s wall, "
                      f"{run['cpu_s']:.2f} s CPU, {run['modes']} modes{split}", file=sys.stderr)
    report = {"study": str(study), "overrides": FILES_OFF + overrides, "repeat": repeat,
              "anisotropy": anisotropy, "target_ratio": TARGET_RATIO}
    for name, values in runs.items():
        report[name] = {key: spread([r[key] for r in values]) for key in ("wall_s", "cpu_s")}
        stages = sorted({stage for r in values for stage in r["stages_s"]})
        report[name]["stages_s"] = {stage: statistics.median(r["stages_s"].get(stage, 0.0)
                                                             for r in values)
                                    for stage in stages}
        report[name]["newton_iterations"] = values[-1]["newton_iterations"]
        report[name]["modes"] = values[-1]["modes"]
        report[name]["split_11"] = values[-1]["split_11"]
    report["ratio_anisotropic_to_perfect"] = {
        key: {"median": statistics.median(a[key] / p[key] for a, p in
                                          zip(runs["anisotropic"], runs["perfect"])),
              "all": [round(a[key] / p[key], 3) for a, p in zip(runs["anisotropic"],
                                                                  runs["perfect"])]}
        for key in ("wall_s", "cpu_s")}
    report["target_met"] = (report["ratio_anisotropic_to_perfect"]["cpu_s"]["median"]
                            <= TARGET_RATIO * 1.05)   # CPU: the shared machine's wall is noise
    return report


def run_stages(study_path: Path, repeat: int, anisotropy: float, overrides: list[str]) -> dict:
    """CPU seconds per stage in one process, perfect and anisotropic alternating (module
    doc): medians and all values."""
    from copdea_fem.fe.coupled import assemble_coupled
    from copdea_fem.fe.linearise import membrane_matrices
    from copdea_fem.fe.prestress import solve_prestress
    from copdea_fem.fe.quadrant.geometry import study_mesh
    from copdea_fem.study import load_study, parse_overrides

    studies = {name: load_study(study_path,
                                overrides=parse_overrides(FILES_OFF + overrides + extra))
               for name, extra in (("perfect", []), ("anisotropic", [
                   f"membrane.prestretch_anisotropy={anisotropy}", "membrane.prestretch_axis=0"]))}
    mesh = study_mesh(studies["perfect"], with_air=True)
    seconds = {name: {"prestress": [], "membrane_matrices": [], "coupled_assembly": []}
               for name in studies}
    for k in range(repeat):
        for name in (list(studies) if k % 2 == 0 else list(reversed(studies))):
            start = time.process_time()
            state = solve_prestress(studies[name], mesh)
            seconds[name]["prestress"].append(time.process_time() - start)
            start = time.process_time()
            membrane_matrices(state)
            seconds[name]["membrane_matrices"].append(time.process_time() - start)
            start = time.process_time()
            assemble_coupled(studies[name], mesh, state)
            seconds[name]["coupled_assembly"].append(time.process_time() - start)
    return {name: {stage: {"median": statistics.median(values), "all": values}
                   for stage, values in stages.items()} for name, stages in seconds.items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.imperfections")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--study", type=Path, default=STUDY)
    parser.add_argument("--anisotropy", type=float, default=0.02)
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    parser.add_argument("--stages", action="store_true",
                        help="also the stages' CPU seconds in one process")
    args = parser.parse_args(argv)
    if args.repeat < 1:
        parser.error(f"--repeat {args.repeat} is not allowed; allowed: >= 1")
    if not 0 < args.anisotropy <= 0.5:
        parser.error(f"--anisotropy {args.anisotropy} is not allowed; allowed: 0 < e <= 0.5")
    report = run_pairs(args.study, args.repeat, args.anisotropy, args.set)
    if args.stages:
        report["stages_cpu_s"] = run_stages(args.study, args.repeat, args.anisotropy, args.set)
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
