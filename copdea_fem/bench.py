"""Benchmarks you can rerun: ``python -m copdea_fem.bench dry [--repeat 3]``.

Each repetition runs in a fresh subprocess (cold caches except the mesh file,
separate peak memory); the report gives the median and the spread of every
stage.  Targets live here and in the issue notes, never in timed tests.

``dry``: prestress + dry modes below 1 kHz of G1 at z = 16 mm, V_b = 2 kV on
the default mesh (issue 2's benchmark).
``coupled``: the same with the air (issue 3's benchmark): mesh, prestress,
assembly, factorisation, eigen iterations, output -- every coupled mode below
1 kHz, result files written to a temporary directory.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CASES = {"dry": ROOT / "studies" / "g1_z16_v2.yaml", "coupled": ROOT / "studies" / "g1_z16_v2.yaml"}


def _once(case: str, overrides: list[str]) -> dict:
    from .solve import Timings, dry_modes, prepare_mesh
    from .study import load_study, parse_overrides

    study = load_study(CASES[case], overrides=parse_overrides(overrides))
    if case == "coupled":
        return _once_coupled(study)
    timings = Timings()
    start = time.perf_counter()
    with timings.stage("mesh"):
        mesh = prepare_mesh(study, with_air=False)
    state, modes, result = dry_modes(study, mesh=mesh, timings=timings)
    total = time.perf_counter() - start
    return {"seconds": {**timings.seconds, "total": total},
            "unknowns": int(result.vectors.shape[0]),
            "membrane_dofs": int(state.space.ndof),
            "newton_iterations": state.newton_iterations,
            "modes": len(modes),
            "factorisations": int(result.n_factorisations),
            "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def _once_coupled(study) -> dict:
    import tempfile

    from .solve import run_solve

    study = study.replace({"air.enabled": True, "output.plots": False})
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as directory:
        result = run_solve(study, out_dir=Path(directory) / "out")
    total = time.perf_counter() - start
    seconds = dict(result.timings.seconds)
    seconds["factorisation"] = result.eigen.factorisation_seconds
    seconds["eigen_iterations"] = result.eigen.iteration_seconds
    seconds["total"] = total
    coupled = result.coupled
    return {"seconds": seconds,
            "unknowns": int(result.eigen.unknowns),
            "unknowns_per_sector": [int(part.stiffness.shape[0]) for part in coupled.operators],
            "symmetry": result.state.symmetry.kind,
            "membrane_dofs": int(result.state.space.ndof),
            "pressure_dofs": int(coupled.operators[0].pressure_space.ndof),
            "newton_iterations": result.state.newton_iterations,
            "modes": sum(1 for mode in result.modes if mode.kind != "air"),
            "factorisations": int(result.eigen.n_factorisations),
            "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def run(case: str, repeat: int, overrides: list[str]) -> dict:
    runs = []
    for k in range(repeat):
        command = [sys.executable, "-m", "copdea_fem.bench", case, "--once"]
        for item in overrides:
            command += ["--set", item]
        completed = subprocess.run(command, capture_output=True, text=True, check=True)
        runs.append(json.loads(completed.stdout.strip().splitlines()[-1]))
        print(f"run {k + 1}/{repeat}: {runs[-1]['seconds']['total']:.2f} s", file=sys.stderr)
    stages = runs[0]["seconds"].keys()
    report = {key: runs[0][key] for key in runs[0] if key not in ("seconds", "peak_memory_mb")}
    report["median_s"] = {stage: statistics.median(r["seconds"][stage] for r in runs)
                          for stage in stages}
    report["min_s"] = {stage: min(r["seconds"][stage] for r in runs) for stage in stages}
    report["max_s"] = {stage: max(r["seconds"][stage] for r in runs) for stage in stages}
    report["peak_memory_mb"] = max(r["peak_memory_mb"] for r in runs)
    report["repeat"] = repeat
    return report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m copdea_fem.bench")
    parser.add_argument("case", choices=sorted(CASES))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    parser.add_argument("--once", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.once:
        print(json.dumps(_once(args.case, args.set)))
        return 0
    report = run(args.case, args.repeat, args.set)
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
