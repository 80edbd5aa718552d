"""The sweep benchmarks: ``python -m benchmarks.sweep benchmark SWEEP.yaml`` (the reuse
variants) and ``python -m benchmarks.sweep executors SWEEP.yaml`` (the local executor against
a local Dask cluster)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from copdea_fem.sweeps.executors import run_sweep
from copdea_fem.sweeps.spec import load_sweep, parse_reuse, sweep_error


def _benchmark(argv: list[str]) -> int:
    """``python -m benchmarks.sweep benchmark SWEEP.yaml [--repeat N] [--set K=V]``.

    Runs the sweep in fresh processes with every reuse switched off, then on
    one by one (mesh; + prestress continuation; + eigen start shifts),
    interleaved (one run of each variant per repetition, so a change of the
    machine's load hits all variants alike), and reports per variant the
    median wall time, the median CPU time of the process (user + system, all
    threads: less sensitive to other jobs on a shared machine) and the
    per-point stage medians, as JSON on stdout.
    """
    import argparse
    import resource
    import statistics
    import subprocess
    import tempfile

    parser = argparse.ArgumentParser(prog="python -m benchmarks.sweep benchmark")
    parser.add_argument("sweep")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--variants", default="independent,mesh,prestress,all")
    args = parser.parse_args(argv)
    variants = {"independent": {"mesh": False, "prestress": False, "shifts": False},
                "mesh": {"mesh": True, "prestress": False, "shifts": False},
                "prestress": {"mesh": True, "prestress": True, "shifts": False},
                "all": {"mesh": True, "prestress": True, "shifts": True}}
    names = args.variants.split(",")
    for name in names:
        if name not in variants:
            raise sweep_error("--variants", name, "a comma-separated list of " + ", ".join(variants))
    runs: dict[str, list] = {name: [] for name in names}
    for repetition in range(args.repeat):
        for name in names:
            with tempfile.TemporaryDirectory() as tmp:
                command = [sys.executable, "-m", "benchmarks.sweep", "_once", args.sweep,
                           tmp, json.dumps(variants[name])] + args.set
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                subprocess.run(command, check=True)
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                run = json.loads((Path(tmp) / "sweep.json").read_text())
                run["cpu_s"] = (after.ru_utime - before.ru_utime) + \
                    (after.ru_stime - before.ru_stime)
                timers = Path(tmp) / "factorisation_timers.json"
                run["factorisation_timers"] = json.loads(timers.read_text()) \
                    if timers.is_file() else {}
                runs[name].append(run)
            print(f"{name} {repetition + 1}/{args.repeat}: wall {run['wall_s']:.1f} s, "
                  f"process CPU {run['cpu_s']:.1f} s", file=sys.stderr)
    report = {}
    for name in names:
        variant_runs = runs[name]
        stages = sorted({s for run in variant_runs for p in run["points"]
                         for s in (p["timings_s"] or {})})
        per_point = {}
        for position, point in enumerate(variant_runs[0]["points"]):
            per_point[point["point"]] = {
                stage: statistics.median((run["points"][position]["timings_s"] or {}).get(
                    stage, 0.0) for run in variant_runs) for stage in stages}
        report[name] = {
            "wall_s_median": statistics.median(run["wall_s"] for run in variant_runs),
            "wall_s_all": [run["wall_s"] for run in variant_runs],
            "cpu_s_median": statistics.median(run["cpu_s"] for run in variant_runs),
            "cpu_s_all": [run["cpu_s"] for run in variant_runs],
            "stage_sum_s": {stage: statistics.median(
                sum((p["timings_s"] or {}).get(stage, 0.0) for p in run["points"])
                for run in variant_runs) for stage in stages},
            "per_point_s": per_point,
            "newton_iterations": [(p["prestress"] or {}).get("newton_iterations")
                                  for p in variant_runs[0]["points"]],
            "eigen_factorisations": [(p["eigen"] or {}).get("factorisations")
                                     for p in variant_runs[0]["points"]],
            "failed": variant_runs[0]["failed"],
            "factorisation_timers_s": variant_runs[-1].get("factorisation_timers", {})}
    print(json.dumps(report, indent=1))
    return 0


def _once(argv: list[str]) -> int:
    sweep_path, directory, reuse_text, *sets = argv
    from copdea_fem.study import parse_overrides
    sweep = load_sweep(sweep_path, overrides=parse_overrides(sets))
    from copdea_fem.progress import progress_to
    with progress_to(lambda message: print(message, file=sys.stderr, flush=True)):
        run_sweep(sweep, out_dir=directory, executor="inline",
                  reuse=parse_reuse(json.loads(reuse_text)))
    # what symbolic-analysis reuse could buy: NGSolve's own UMFPACK timers [s]
    import ngsolve
    timers = {t["name"]: {"seconds": t["time"], "counts": t["counts"]} for t in ngsolve.Timers()
              if "Umfpack Inverse" in t["name"] or "SparseCholesky" in t["name"]}
    (Path(directory) / "factorisation_timers.json").write_text(json.dumps(timers, indent=1))
    return 0


def _executors(argv: list[str]) -> int:
    """``python -m benchmarks.sweep executors SWEEP.yaml [--repeat N] [--workers 2]
    [--executors local,pool,dask] [--set K=V]``.

    Runs the sweep on the local executor (``--executor inline``: one process, one chain per
    context), the pool (``--executor processes``: ``--workers`` spawned processes) and with
    ``--executor dask`` and no scheduler (a local
    cluster of ``--workers`` processes started for the run, its start counted), interleaved,
    each run a fresh process with an empty result folder; reports the median wall time of
    the sweep (``sweep.json``'s ``wall_s``) and of the whole process, the CPU seconds of the
    process and its workers (user + system, the cluster's too), the speed-up of each
    over ``local``, and how far each table lies from the local one: the rows (point, label,
    kind, m, n, member) must be the same; the rows whose track differs are listed (with two
    workers the path is cut into two chains, so the second chain starts afresh and a
    degenerate pair's vectors, hence a MAC near the threshold, can differ), and the largest
    relative frequency difference.
    """
    import argparse
    import csv
    import resource
    import statistics
    import subprocess
    import tempfile
    import time

    parser = argparse.ArgumentParser(prog="python -m benchmarks.sweep executors")
    parser.add_argument("sweep")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--executors", default="local,pool,dask")
    parser.add_argument("--set", action="append", default=[])
    args = parser.parse_args(argv)
    names = args.executors.split(",")
    if "local" not in names:
        names.insert(0, "local")
    runs: dict[str, list] = {name: [] for name in names}
    tables: dict[str, list] = {name: [] for name in names}
    for repetition in range(args.repeat):
        for executor in names:
            with tempfile.TemporaryDirectory() as tmp:
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                started = time.perf_counter()
                subprocess.run([sys.executable, "-m", "benchmarks.sweep", "_run", args.sweep,
                                tmp, executor, str(args.workers)] + args.set, check=True)
                process = time.perf_counter() - started
                after = resource.getrusage(resource.RUSAGE_CHILDREN)   # workers included
                cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
                wall = json.loads((Path(tmp) / "sweep.json").read_text())["wall_s"]
                with open(Path(tmp) / "sweep.csv", newline="") as handle:
                    tables[executor].append(list(csv.DictReader(handle)))
            runs[executor].append({"sweep_s": wall, "process_s": process, "cpu_s": cpu})
            print(f"{executor} {repetition + 1}/{args.repeat}: sweep {wall:.1f} s, process "
                  f"{process:.1f} s, CPU {cpu:.1f} s", file=sys.stderr, flush=True)
    report = {"sweep": args.sweep, "workers": args.workers, "repeat": args.repeat}
    for executor, values in runs.items():
        report[executor] = {key: {"median": statistics.median(v[key] for v in values),
                                  "all": [v[key] for v in values]}
                            for key in ("sweep_s", "process_s", "cpu_s")}
    exact = ("point", "status", "label", "m", "n", "kind", "member")
    reference = tables["local"][0]
    for name in names:
        report[name]["speed_up_over_local"] = {
            key: report["local"][key]["median"] / report[name][key]["median"]
            for key in ("sweep_s", "process_s")}
        report[name]["same_rows"] = all(
            [tuple(r[k] for k in exact) for r in table] == [tuple(r[k] for k in exact)
                                                             for r in reference]
            for table in tables[name])
        report[name]["rows_with_another_track"] = sorted({
            f"{a['point']} {a['label']} ({a['kind']})" for table in tables[name]
            for a, b in zip(table, reference) if a["track"] != b["track"]})
        report[name]["largest_relative_frequency_difference"] = max(
            (abs(float(a["freq_hz"]) / float(b["freq_hz"]) - 1)
             for table in tables[name] for a, b in zip(table, reference)
             if a["freq_hz"] and b["freq_hz"]), default=None)
    print(json.dumps(report, indent=1))
    return 0


#: The variants of ``executors`` (the names of their reports) -> the executors they run.
EXECUTORS = {"local": "inline", "pool": "processes", "dask": "dask"}


def _run(argv: list[str]) -> int:
    sweep_path, directory, variant, workers, *sets = argv
    executor = EXECUTORS[variant]
    from copdea_fem.progress import progress_to
    from copdea_fem.study import parse_overrides
    sweep = load_sweep(sweep_path, overrides=parse_overrides(sets))
    sweep.plots = False
    with progress_to(lambda message: print(message, file=sys.stderr, flush=True)):
        run_sweep(sweep, out_dir=directory, executor=executor,
                  workers=None if executor == "inline" else int(workers))
    return 0


def main(argv: list[str]) -> int:
    """``python -m benchmarks.sweep benchmark|executors SWEEP.yaml [...]``."""
    command, *rest = argv or ["help"]
    if command == "benchmark":
        return _benchmark(rest)
    if command == "executors":
        return _executors(rest)
    if command == "_once":
        return _once(rest)
    if command == "_run":
        return _run(rest)
    print(_benchmark.__doc__)
    print(_executors.__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
