"""Benchmarks you can rerun: ``python -m benchmarks.command dry [--repeat 3]``.

Each repetition runs in a fresh subprocess (cold caches except the mesh file,
separate peak memory); the report gives the median and the spread of every
stage.  Targets live here and in the issue notes, never in timed tests.

``dry``: prestress + dry modes below 1 kHz of G1 at z = 16 mm, V_b = 2 kV on
the default mesh (issue 2's benchmark).
``coupled``: the same with the air (issue 3's benchmark): mesh, prestress,
assembly, factorisation, eigen iterations, output -- every coupled mode below
1 kHz, result files written to a temporary directory (no plots).
``axisymmetric`` / ``axisymmetric-3d``: the same in a baffle (frame: baffle) on the
axisymmetric engine / on the 3-D quadrant; ``engines`` runs both interleaved and
reports the ratio of the medians (issue 12's benchmark).
``prony-dry`` / ``prony-coupled`` / ``prony-axisymmetric``: ``dry`` / ``coupled`` /
``axisymmetric`` interleaved with the same case plus one Prony term (``membrane.prony``,
ratio 0.5, 1 ms: the damped eigen step in omega of :mod:`copdea_fem.fe.eigen.damped`),
ratio of the medians (issue 23's target: <= 2).
``response``: the forced response of issue 15 (``copdea_fem.forced_response``): G1, z = 16 mm, 2 kV,
disc on the spring, baffle (``studies/g1_z16_v2_response.yaml``), 800 chirp lines: prestress and
m = 0 pencil, the modal solve, then the 800-line velocity spectra + SPL (``after_modal``), and
the direct path per frequency (``direct_per_line``, mean of 10 lines across the band);
``response-3d`` the same on the 3-D quadrant (its even-even sector).
``response-reduced`` (issue 23): ``copdea-fem response studies/g1_z16_v2.yaml --set
response.method=reduced`` (square frame, 3-D quadrant, 800 lines; the study states no loss of
its own, so ``auto`` would keep the modal path of its modal b/m) as a user runs it,
a fresh ``python -m copdea_fem.cli`` process with its files (``command_wall``, target 30 s),
then in process the reduced path's spectra against the direct path at its peaks and 8 lines
spread over the band: largest relative error of the average and point velocity spectra and
of the complex pressure at the microphones (target 0.5 %), and the largest SPL difference.
``drum``: the 0.65 m Mylar drum head of ``studies/drum_mylar_650mm.yaml`` (50-450 Hz,
baffle, in air) on the axisymmetric engine; ``drum-3d`` the same on the 3-D quadrant
(``mesh.engine: 3d``, issue 14's benchmark): its four sectors of ~47k unknowns hold many
lightly damped air/PML modes of the 1.14 m air sphere; they run one after the other under
the default ``eigen.factor_memory_gb`` (``--set eigen.factor_memory_gb=1.2`` runs two at
a time: faster, above 2 GB).  Both report the structural modes (m,1), m = 0..5, and the
ratios f(m,1)/f(1,1).

Coupled cases also report, per sector, the factorisations, the right-hand sides solved
(``solves_per_sector``) and the block solves they took (``block_solves_per_sector``).

``command`` (issue 25): the baffled G1 command as a user runs it, ``copdea-fem solve
studies/g1_z16_v2.yaml --set geometry.frame=baffle --out DIR``, each repetition a fresh
``python -m copdea_fem.cli`` process, with its ParaView files and plots (``files``) and
without them (``bare``: ``--set output.paraview=false --set output.plots=false``), one after
the other; wall and CPU seconds (user + system of the child) per run, medians, against the
targets (``files`` <= 2 s, ``bare`` <= the FreeFEM peer's whole process, 1.07 s).  ``warm``:
the second ``cf.solve`` of one process (no imports, nothing written: a notebook's or a
server's next solve), in-process wall and CPU seconds, against the same 1.07 s.
``command-peer``: the same two variants on the FreeFEM peer's own case (flat G1 in a baffle,
``studies/g1_z00_v2.yaml`` at 0 V, every coupled mode below 400 Hz: (0,1) at 350.02 Hz,
zeta 2.00e-2; the peer solves the (0,1) alone in 1.07 s as a whole process) -- a smaller
problem than ``command`` (6 orders against 17, 3 modes against 48) -- and, where the peer
can run here, the peer's whole process in the same repetitions: each ``bare`` run (the
command without files) is paired with one run of the peer (the order alternating), and the
report gives the paired wall ratio bare / peer (median, range) against
:data:`PEER_RATIO_LIMIT`.  The peer is the command line of ``--peer`` (e.g. ``--peer
'FreeFem++ -nw -ne g1_flat_baffle.edp'``) or of ``$COPDEA_FEM_PEER``; the repository holds no
FreeFEM script.  Without one, or without FreeFEM on this machine, the benchmark says so on
stderr and in the report (``peer.measured: false`` and why) and skips the pairing: the
recorded 1.07 s is then a reference only, not a measurement.
``--baseline PATH`` runs another checkout (e.g. ``/work/main``, by ``PYTHONPATH``) interleaved
with this one and reports the ratios this / baseline (median of the pairwise ratios): on a
shared machine the CPU ratios carry the comparison.

``total`` is the in-process time of the solve with its result files; ``process_wall``
adds the start of a fresh Python (imports of NGSolve, SciPy, pint: ~1-2 s).
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
G1_Z16 = ROOT / "studies" / "g1_z16_v2.yaml"
G1_Z00 = ROOT / "studies" / "g1_z00_v2.yaml"
DRUM = ROOT / "studies" / "drum_mylar_650mm.yaml"
#: one Prony term of the damped benchmarks (issue 23)
PRONY = "membrane.prony=[{modulus_ratio: 0.5, relaxation_time: 1 ms}]"
#: case -> (study file, overrides); every case but dry is a coupled solve with result files
CASES = {
    "dry": (G1_Z16, []),
    "coupled": (G1_Z16, []),
    # issue 12: G1, z = 16 mm, 2 kV in a baffle on the axisymmetric engine / the 3-D quadrant
    "axisymmetric": (G1_Z16, ["geometry.frame=baffle", "mesh.engine=axisymmetric"]),
    "axisymmetric-3d": (G1_Z16, ["geometry.frame=baffle", "mesh.engine=3d"]),
    # the same over a closed cylinder 20 mm deep (benchmarks/enclosure.py)
    "axisymmetric-enclosure": (G1_Z16, ["geometry.frame=baffle", "mesh.engine=axisymmetric",
                                        "geometry.enclosure=cylinder",
                                        "geometry.enclosure_depth=20 mm"]),
    "drum": (DRUM, []),
    "drum-3d": (DRUM, ["mesh.engine=3d"]),
    # issue 23: the same with one Prony term (the damped eigen step in omega)
    "dry-prony": (G1_Z16, [PRONY]),
    "coupled-prony": (G1_Z16, [PRONY]),
    "axisymmetric-prony": (G1_Z16, ["geometry.frame=baffle", "mesh.engine=axisymmetric",
                                    PRONY]),
    "response": (ROOT / "studies" / "g1_z16_v2_response.yaml", []),
    "response-3d": (ROOT / "studies" / "g1_z16_v2_response.yaml", ["mesh.engine=3d"]),
    # issue 23: the square-frame command on the 3-D quadrant, reduced basis against direct
    "response-reduced": (G1_Z16, ["response.method=reduced"]),
}
#: benchmarks that run two cases interleaved and report the ratio of their medians
PAIRS = {"engines": ("axisymmetric", "axisymmetric-3d"),
         "enclosure": ("axisymmetric", "axisymmetric-enclosure"),
         # issue 23: one Prony term against the undamped solve (target: ratio <= 2)
         "prony-dry": ("dry", "dry-prony"), "prony-coupled": ("coupled", "coupled-prony"),
         "prony-axisymmetric": ("axisymmetric", "axisymmetric-prony")}


def _once(case: str, overrides: list[str]) -> dict:
    from copdea_fem.fe import engine_for
    from copdea_fem.fe.pipeline import Timings, dry_modes, prepare_mesh
    from copdea_fem.study import load_study, parse_overrides

    path, fixed = CASES[case]
    study = load_study(path, overrides=parse_overrides(fixed + overrides))
    if case == "response-reduced":
        return _once_response_reduced(study, fixed + overrides)
    if case.startswith("response"):
        return _once_response(study)
    if not case.startswith("dry"):
        return _once_coupled(study)
    engine = engine_for(study)
    timings = Timings()
    start = time.perf_counter()
    with timings.stage("mesh"):
        mesh = prepare_mesh(study, with_air=False, engine=engine)
    state, modes, result = dry_modes(study, mesh=mesh, timings=timings, engine=engine)
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

    from copdea_fem.api import Solution
    from copdea_fem.fe import engine_for, run_solve

    study = study.replace({"air.enabled": True, "output.plots": False})
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as directory:
        result = run_solve(study, engine=engine_for(study))
        Solution(result).write(Path(directory) / "out")
    total = time.perf_counter() - start
    seconds = dict(result.timings.seconds)
    seconds["factorisation"] = result.eigen.factorisation_seconds
    seconds["eigen_iterations"] = result.eigen.iteration_seconds
    seconds["total"] = total
    coupled = result.coupled
    labels = {mode.label: mode.freq_hz for mode in result.modes if mode.kind != "air"}
    sectors = result.eigen.by_sector
    drum_modes = {}
    for order in range(6):                  # (m,1): the "a" member of a degenerate pair
        label = next((name for name in (f"({order},1)", f"({order},1)a") if name in labels),
                     None)
        if label is not None:
            drum_modes[label] = labels[label]
    reference = drum_modes.get("(1,1)a") or drum_modes.get("(1,1)")
    return {"seconds": seconds,
            "engine": getattr(result.state, "engine", "3d"),
            "frequencies_hz": {label: labels[label] for label in
                               ("P1", "(0,1)", "(1,1)a", "(2,1)a", "(3,1)a", "(4,1)a", "(5,1)a",
                                "(0,2)") if label in labels},
            "unknowns": int(result.eigen.unknowns),
            "unknowns_per_sector": [int(part.stiffness.shape[0]) for part in coupled.operators],
            "symmetry": result.state.symmetry.kind,
            "membrane_dofs": int(result.state.space.ndof),
            "pressure_dofs": int(coupled.operators[0].pressure_space.ndof),
            "newton_iterations": result.state.newton_iterations,
            "modes": sum(1 for mode in result.modes if mode.kind != "air"),
            "factorisations": int(result.eigen.n_factorisations),
            "factorisations_per_sector": {key: int(part.n_factorisations)
                                          for key, part in sectors.items()},
            "solves_per_sector": {key: int(part.n_solves) for key, part in sectors.items()},
            "block_solves_per_sector": {key: int(part.n_block_solves)
                                        for key, part in sectors.items()},
            "eigen_seconds_per_sector": {key: float(part.total_seconds)
                                         for key, part in sectors.items()},
            "m1_modes_hz": drum_modes,
            "m1_ratios_to_11": ({label: f / reference for label, f in drum_modes.items()}
                                if reference else {}),
            "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def _once_response(study) -> dict:
    import numpy as np

    from copdea_fem.fe import engine_for
    from copdea_fem.forced_response.run import forced_response, prepare_order_zero
    from copdea_fem.reduced.chirp_response import Chirp

    start = time.perf_counter()
    problem = prepare_order_zero(study, engine=engine_for(study))
    prepared = time.perf_counter()
    result = forced_response(problem)
    done = time.perf_counter()
    frequencies, _ = Chirp.from_study(study).lines()
    chosen = frequencies[np.linspace(0, frequencies.size - 1, 10).astype(int)]
    direct_start = time.perf_counter()
    problem.forced.direct(chosen)
    per_line = (time.perf_counter() - direct_start) / chosen.size
    seconds = {"prepare": prepared - start, "modal_solve": result.timings["solve"],
               "after_modal": result.timings["velocity"] + result.timings["sound"],
               "response_total": done - prepared, "direct_per_line": per_line,
               "total": done - start}
    return {"seconds": seconds, "engine": problem.engine, "unknowns": int(problem.forced.size),
            "lines": int(result.frequency_hz.size), "modes_used": len(result.modes),
            "peaks_hz": result.peaks_hz,
            "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def _once_response_reduced(study, overrides) -> dict:
    """The ``response-reduced`` case (module doc)."""
    import dataclasses
    import os
    import tempfile

    import numpy as np

    from copdea_fem.fe import engine_for
    from copdea_fem.forced_response.run import forced_response, prepare_order_zero, resolved_method
    from copdea_fem.progress import single_threaded_blas

    command = [sys.executable, "-m", "copdea_fem.cli", "response", str(CASES[
        "response-reduced"][0])]
    for item in overrides:
        command += ["--set", item]
    with tempfile.TemporaryDirectory() as directory:
        started = time.perf_counter()
        subprocess.run(command + ["--out", str(Path(directory) / "out")], cwd=directory,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)), check=True,
                       capture_output=True)
        command_wall = time.perf_counter() - started
        document = json.loads((Path(directory) / "out" / "response.json").read_text())
    start = time.perf_counter()
    problem = prepare_order_zero(study, engine=engine_for(study))
    prepared = time.perf_counter()
    result = forced_response(problem)
    done = time.perf_counter()
    picks = sorted({int(np.argmin(abs(result.frequency_hz - f))) for f in result.peaks_hz}
                   | set(np.linspace(0, result.frequency_hz.size - 1, 8).astype(int).tolist()))
    picks = np.array(picks)
    direct_problem = dataclasses.replace(problem, study=study.replace(
        {"response.method": "direct"}))
    from copdea_fem.reduced.chirp_response import Chirp
    _, volts = Chirp.from_study(study).lines()
    direct_start = time.perf_counter()
    with single_threaded_blas():
        direct = forced_response(direct_problem, result.frequency_hz[picks], volts[picks])
    per_line = (time.perf_counter() - direct_start) / picks.size

    def worst(a, b):
        return float(np.max(np.abs(np.asarray(a) - np.asarray(b)) / np.abs(np.asarray(b))))
    errors = {"average_axial": worst(result.average_axial[picks], direct.average_axial),
              "average_radial": worst(result.average_radial[picks], direct.average_radial),
              "point_axial": worst(result.point_axial[picks], direct.point_axial),
              "point_radial": worst(result.point_radial[picks], direct.point_radial),
              "pressure": worst(result.pressure[picks], direct.pressure)}
    seconds = {"command_wall": command_wall, "prepare": prepared - start,
               "reduced_solve": result.timings["solve"],
               "after_solve": result.timings["velocity"] + result.timings["sound"],
               "response_total": done - prepared, "direct_per_line": per_line,
               "total": done - start}
    basis = result.basis.summary() if result.basis is not None else {}
    return {"seconds": seconds, "engine": problem.engine, "method": resolved_method(problem),
            "command_timings_s": document["timings_s"], "unknowns": int(problem.forced.size),
            "lines": int(result.frequency_hz.size), "checked_hz": result.frequency_hz[
                picks].tolist(), "max_relative_error": errors,
            "max_relative_error_all": max(errors.values()),
            "max_spl_difference_db": float(np.max(np.abs(result.spl_db[picks]
                                                         - direct.spl_db))),
            "reduced_basis": basis, "peaks_hz": result.peaks_hz,
            "targets": {"command_wall_s": 30.0, "max_relative_error": 0.005},
            "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


#: issue 25: the FreeFEM peer's whole process on the same case [s] and the targets
PEER_PROCESS_S = 1.07
#: the paired wall ratio bare / peer must stay at or below this: at parity when last
#: measured (1.00-1.11 over 5 runs), the top of that range
PEER_RATIO_LIMIT = 1.11
#: the peer's command line, when no --peer is given
PEER_VARIABLE = "COPDEA_FEM_PEER"
#: the names the FreeFEM executable goes by
FREEFEM_NAMES = ("FreeFem++", "FreeFem++-nw", "freefem++", "FreeFem++-mpi")
COMMAND_TARGETS_S = {"files": 2.0, "bare": PEER_PROCESS_S}
COMMAND_VARIANTS = {"files": [], "bare": ["output.paraview=false", "output.plots=false"],
                    "warm": ["output.paraview=false", "output.plots=false"]}
#: the ``warm`` variant: a fresh process solves the study twice through the API and reports
#: the second ``cf.solve`` (a notebook's or a server's next solve: no imports, no files)
WARM_SCRIPT = """
import json, sys, time
import copdea_fem as cf
study = cf.load_study(sys.argv[1], sys.argv[2:])
cf.solve(study)
wall, cpu = time.perf_counter(), time.process_time()
cf.solve(study)
print(json.dumps({"wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu}))
"""
#: the command cases: study file and overrides (issue 25)
COMMAND_CASES = {"command": (G1_Z16, ["geometry.frame=baffle"]),
                 "command-peer": (G1_Z00, ["geometry.frame=baffle", "load.voltage=0 V",
                                           "eigen.f_max=400 Hz"])}


def _command_once(variant: str, overrides: list[str], checkout: Path,
                  case: str = "command") -> dict:
    """One fresh ``python -m copdea_fem.cli solve`` of the baffled G1 command (``case``: a
    key of :data:`COMMAND_CASES`) from ``checkout``: wall and CPU (user + system) seconds
    of the child process."""
    import os
    import tempfile

    study, fixed = COMMAND_CASES[case]
    environment = dict(os.environ, PYTHONPATH=str(checkout))
    if variant == "warm":        # cwd elsewhere: ``-c`` puts the cwd before PYTHONPATH
        with tempfile.TemporaryDirectory() as directory:
            completed = subprocess.run([sys.executable, "-c", WARM_SCRIPT, str(study)] + fixed
                                       + COMMAND_VARIANTS[variant] + overrides,
                                       env=environment, cwd=directory, check=True,
                                       capture_output=True, text=True)
        return json.loads(completed.stdout.strip().splitlines()[-1])
    command = [sys.executable, "-m", "copdea_fem.cli", "solve", str(study)]
    for item in fixed + COMMAND_VARIANTS[variant] + overrides:
        command += ["--set", item]
    with tempfile.TemporaryDirectory() as directory:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        subprocess.run(command + ["--out", str(Path(directory) / "out")], cwd=directory,
                       env=environment, check=True, capture_output=True)
        wall = time.perf_counter() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": wall, "cpu_s": cpu}


def find_peer(peer: str | None) -> tuple[list[str] | None, str]:
    """The FreeFEM peer's command line (``peer``, else ``$COPDEA_FEM_PEER``) as a list, and
    where it came from; or None and why the peer cannot run on this machine."""
    import os
    import shlex
    import shutil

    text = peer or os.environ.get(PEER_VARIABLE)
    freefem = next((found for name in FREEFEM_NAMES if (found := shutil.which(name))), None)
    if not text:
        where = (f"FreeFEM is installed ({freefem}) but" if freefem else
                 "FreeFEM is not installed on this machine (none of " +
                 ", ".join(FREEFEM_NAMES) + " on PATH), and")
        return None, (f"{where} no peer command was given (--peer 'FreeFem++ -nw SCRIPT.edp' or "
                      f"${PEER_VARIABLE}; the repository holds no FreeFEM script)")
    command = shlex.split(text)
    if not command or shutil.which(command[0]) is None:
        return None, (f"the peer command {text!r} cannot run here: {command[0] if command else ''}"
                      f" is not found" + ("" if freefem else " (FreeFEM is not installed)"))
    return command, "--peer" if peer else f"${PEER_VARIABLE}"


def _peer_once(command: list[str]) -> dict:
    """One whole process of the peer: wall and CPU (user + system) seconds."""
    import tempfile
    with tempfile.TemporaryDirectory() as directory:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        subprocess.run(command, cwd=directory, check=True, capture_output=True)
        wall = time.perf_counter() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {"wall_s": wall,
            "cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)}


def run_command(repeat: int, overrides: list[str], baseline: str | None,
                case: str = "command", peer: str | None = None) -> dict:
    """The ``command`` benchmark (or ``command-peer``): both variants, this checkout (and
    ``baseline``) interleaved; for ``command-peer`` each ``bare`` run paired with one of
    the FreeFEM peer's whole process where it can run (:func:`find_peer`)."""
    checkouts = {"this": ROOT}
    if baseline:
        checkouts["baseline"] = Path(baseline).resolve()
    peer_command, peer_source = find_peer(peer) if case == "command-peer" else (None, "")
    if case == "command-peer" and peer_command is None:
        print(f"command-peer: the FreeFEM peer is NOT measured: {peer_source}. The paired "
              f"ratio is skipped; the recorded {PEER_PROCESS_S} s is a reference only.",
              file=sys.stderr)
    runs = {(name, variant): [] for name in checkouts for variant in COMMAND_VARIANTS}
    peer_runs, pairs = [], []
    for k in range(repeat):
        for variant in COMMAND_VARIANTS:
            for name, checkout in checkouts.items():
                if peer_command and variant == "bare" and name == "this" and k % 2:
                    peer_runs.append(_peer_once(peer_command))     # odd runs: peer first
                runs[name, variant].append(_command_once(variant, overrides, checkout, case))
                print(f"run {k + 1}/{repeat} {name} {variant}: "
                      f"{runs[name, variant][-1]['wall_s']:.2f} s wall, "
                      f"{runs[name, variant][-1]['cpu_s']:.2f} s CPU", file=sys.stderr)
                if peer_command and variant == "bare" and name == "this":
                    if not k % 2:
                        peer_runs.append(_peer_once(peer_command))
                    pairs.append(runs[name, variant][-1]["wall_s"] / peer_runs[-1]["wall_s"])
                    print(f"run {k + 1}/{repeat} peer: {peer_runs[-1]['wall_s']:.2f} s wall, "
                          f"{peer_runs[-1]['cpu_s']:.2f} s CPU; bare / peer {pairs[-1]:.3f}",
                          file=sys.stderr)
    report = {"case": case, "peer_process_s": PEER_PROCESS_S, "targets_s": COMMAND_TARGETS_S,
              "repeat": repeat}
    for (name, variant), values in runs.items():
        report.setdefault(name, {})[variant] = {
            key: {"median": statistics.median(r[key] for r in values),
                  "min": min(r[key] for r in values), "max": max(r[key] for r in values)}
            for key in ("wall_s", "cpu_s")}
    for variant, target in COMMAND_TARGETS_S.items():
        report["this"][variant]["wall_target_met"] = \
            report["this"][variant]["wall_s"]["median"] <= target
    report["this"]["warm"]["wall_below_peer_process"] = \
        report["this"]["warm"]["wall_s"]["median"] <= PEER_PROCESS_S
    if case == "command-peer":
        report["peer"] = {"measured": peer_command is not None, "source": peer_source}
        if peer_command is not None:
            report["peer"].update({"command": peer_command, **{
                key: {"median": statistics.median(r[key] for r in peer_runs),
                      "min": min(r[key] for r in peer_runs),
                      "max": max(r[key] for r in peer_runs)} for key in ("wall_s", "cpu_s")}})
            report["paired_wall_ratio_bare_to_peer"] = {
                "median": statistics.median(pairs), "min": min(pairs), "max": max(pairs),
                "all": pairs, "limit": PEER_RATIO_LIMIT,
                "held": statistics.median(pairs) <= PEER_RATIO_LIMIT}
    if baseline:
        report["ratio_this_to_baseline"] = {
            variant: {key: statistics.median(a[key] / b[key] for a, b in
                                             zip(runs["this", variant], runs["baseline", variant]))
                      for key in ("wall_s", "cpu_s")}
            for variant in COMMAND_VARIANTS}
    return report


def _run_once(case: str, overrides: list[str]) -> dict:
    command = [sys.executable, "-m", "benchmarks.command", case, "--once"]
    for item in overrides:
        command += ["--set", item]
    started = time.perf_counter()
    completed = subprocess.run(command, capture_output=True, text=True, check=True)
    result = json.loads(completed.stdout.strip().splitlines()[-1])
    result["seconds"]["process_wall"] = time.perf_counter() - started   # incl. imports
    return result


def run(case: str, repeat: int, overrides: list[str]) -> dict:
    runs = []
    for k in range(repeat):
        runs.append(_run_once(case, overrides))
        print(f"run {k + 1}/{repeat}: {runs[-1]['seconds']['total']:.2f} s", file=sys.stderr)
    return _summary(runs, repeat)


def run_pair(pair: str, repeat: int, overrides: list[str]) -> dict:
    """Both cases of ``pair`` interleaved (a, b, a, b, ...): medians and their ratio b / a."""
    first, second = PAIRS[pair]
    runs = {first: [], second: []}
    for k in range(repeat):
        for case in (first, second):
            runs[case].append(_run_once(case, overrides))
            print(f"run {k + 1}/{repeat} {case}: {runs[case][-1]['seconds']['total']:.2f} s",
                  file=sys.stderr)
    report = {case: _summary(values, repeat) for case, values in runs.items()}
    report["ratio_total"] = report[second]["median_s"]["total"] / report[first]["median_s"]["total"]
    return report


def _summary(runs: list[dict], repeat: int) -> dict:
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
    parser = argparse.ArgumentParser(prog="python -m benchmarks.command")
    parser.add_argument("case", choices=sorted(CASES) + sorted(PAIRS) + sorted(COMMAND_CASES))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    parser.add_argument("--baseline", metavar="PATH",
                        help="command, command-peer: another checkout run interleaved "
                        "(ratios to it)")
    parser.add_argument("--peer", metavar="COMMAND",
                        help="command-peer: the FreeFEM peer's command line, run as a whole "
                        "process paired with each bare run (default $COPDEA_FEM_PEER)")
    parser.add_argument("--once", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.once:
        print(json.dumps(_once(args.case, args.set)))
        return 0
    if args.case in COMMAND_CASES:
        report = run_command(args.repeat, args.set, args.baseline, args.case, args.peer)
    else:
        report = (run_pair if args.case in PAIRS else run)(args.case, args.repeat, args.set)
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
