"""Command line: ``copdea-fem solve|check|force|schema ...`` (thin: parse, call, print).

Every command has one shape: read and check its inputs, claim the output folder once
(:func:`_output`, before any expensive work), call the Python API (:mod:`copdea_fem.api`;
``fit-material``, ``calibrate-damping`` and ``synth``: their action), hand the claim to the
result's ``write`` (the only writer of its files), print a summary.

Exit codes: 0 success; 2 bad input (study, --set, options, input files, an
output folder that may not be written, a problem too large), before any
meshing; 3 a solve that failed for a physical or numerical reason (the message
says what, at which load, and which study key to change); 130 Ctrl-C and 143
SIGTERM (one line, no traceback; a result is either complete or not written);
1 otherwise.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import os
import signal
import sys
import threading
from pathlib import Path

from copdea_fem.api import SolveFailed, solving
from copdea_fem.folders import OutputFolderError, claim
from copdea_fem.study import StudyError, load_study, parse_overrides


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that every cleanup on the way out runs."""


def _print_progress(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@contextlib.contextmanager
def _progress(args):
    """The messages of the ``copdea_fem`` loggers on stderr while a command runs: INFO and
    above, WARNING and above with ``--quiet``; a command without ``--quiet`` shows only
    the output folder's messages (:mod:`copdea_fem.folders`) and warnings."""
    import logging

    from copdea_fem.progress import progress_to

    quiet = getattr(args, "quiet", None)
    with progress_to(_print_progress, logging.WARNING if quiet else logging.INFO) as handler:
        if quiet is None:
            handler.addFilter(lambda record: record.levelno > logging.INFO
                              or record.name == "copdea_fem.folders")
        yield


def _study(args):
    return load_study(args.study, overrides=parse_overrides(args.set))


def _out_dir(args, study) -> Path:
    return Path(args.out) if args.out else Path(study.output.directory)


@contextlib.contextmanager
def _output(args, out_dir, command: str, inputs):
    """Check and lock the output folder before any work (:func:`copdea_fem.folders.claim`).

    Without ``--out`` the folder comes from the first input file, so it must stay
    inside the working folder.  The claim is kept on ``args`` for :func:`main`'s
    interrupt message.
    """
    inputs = [item for item in inputs if item]
    with claim(out_dir, command, inputs=inputs,
               from_file=None if args.out else inputs[0]) as record:
        args.claim = record
        yield record


def _check_size(args, *studies) -> None:
    """The resource guard (:func:`copdea_fem.fe.engines.check_size`) unless --allow-large."""
    from copdea_fem.api import check_size
    for study in studies:
        check_size(study, args.allow_large)


def cmd_check(args) -> int:
    study = _study(args)
    _check_size(args, study)
    print(f"{args.study}: valid study '{study.name}'")
    return 0


def cmd_schema(args) -> int:
    from copdea_fem.study import reference_table
    print(reference_table())
    return 0


def cmd_solve(args) -> int:
    from copdea_fem import api
    from copdea_fem.output.tables import frequency_table

    study = _study(args)
    _check_size(args, study)
    out_dir = _out_dir(args, study)
    with _output(args, out_dir, "solve", [args.study]) as folder:
        solution = api.solve(study, allow_large=True)
        solution.write(folder)
    result = solution.result
    print(frequency_table(solution.rows))
    state = result.state
    print(f"prestress: z = {state.z * 1e3:g} mm, V_b = {state.voltage:g} V, disc force "
          f"{state.disc_force:.4g} N, {state.newton_iterations} Newton iterations")
    print(f"results in {out_dir}")
    return 0


def cmd_response(args) -> int:
    """Forced response of the coupled FE under the chirp, with radiated sound."""
    from copdea_fem import api
    from copdea_fem.forced_response.run import summary_lines

    study = _study(args)
    _check_size(args, study)
    out_dir = _out_dir(args, study)
    with _output(args, out_dir, "response", [args.study]) as folder:
        solution = api.response(study, allow_large=True)
        solution.write(folder)
    print("\n".join(summary_lines(solution.result)))
    return 0


def cmd_force(args) -> int:
    from copdea_fem import api

    study = _study(args)
    study, z_values, voltages = api.prepare_force(study, args.voltages, args.z_max or None,
                                                  args.points, args.allow_large)
    out_dir = _out_dir(args, study)
    with _output(args, out_dir, "force", [args.study]) as folder:
        curve = api.compute_force(study, z_values, voltages)
        curve.write(folder)
    forces = curve.forces
    print(f"{'z [mm]':>8}" + "".join(f"{f'F @ {v / 1e3:g} kV [N]':>16}" for v in voltages))
    for j, z in enumerate(z_values):
        print(f"{z * 1e3:8.3f}" + "".join(f"{forces[i, j]:16.5f}" for i in range(len(voltages))))
    print(f"results in {out_dir}")
    return 0


# -- reduced model (Sect. 3.2, Annex I): spectrum, fit-material, calibrate-damping ---------------
def _reduced_action(action) -> int:
    """Run a :mod:`copdea_fem.reduced.io` action and print its summary lines.

    Its physical/numerical failures (ReducedModelError) exit with 3 like a
    failed solve; study and input errors (StudyError) reach :func:`main` (2).
    """
    from copdea_fem.reduced.rings import ReducedModelError
    try:
        summary = action()
    except ReducedModelError as error:
        print(f"error: {error}", file=sys.stderr)
        return 3
    print("\n".join(summary["lines"]))
    return 0


def _existing(path, what: str):
    """An input file named on the command line, checked before the output folder."""
    from copdea_fem.inputs import read_text
    if path is not None:
        read_text(path, what, error=StudyError)
    return path


def _modes_json(args, study):
    if args.modes_json:
        return _existing(args.modes_json, "--modes-json")
    return _existing(study.reduced.modes_json, "reduced.modes_json")


def cmd_spectrum(args) -> int:
    from copdea_fem import api
    study = _study(args)
    out_dir = _out_dir(args, study)
    modes_json = _modes_json(args, study)
    with _output(args, out_dir, "spectrum", [args.study, modes_json]) as folder:
        def action():
            spectrum = api.spectrum(study, modes_json=args.modes_json)
            spectrum.write(folder)
            return {"lines": spectrum.summary["lines"] + [f"results in {out_dir}"]}
        return _reduced_action(action)


def cmd_fit_material(args) -> int:
    from copdea_fem.reduced.io import fit_material_cli
    study = _study(args)
    out_dir = _out_dir(args, study)
    with _output(args, out_dir, "fit-material", [args.study, _existing(args.data, "data file")]):
        return _reduced_action(lambda: fit_material_cli(study, args.data, out_dir))


def cmd_calibrate_damping(args) -> int:
    from copdea_fem.reduced.io import calibrate_damping_cli
    study = _study(args)
    out_dir = _out_dir(args, study)
    modes_json = _modes_json(args, study)
    inputs = [args.study, _existing(args.spectrum, "spectrum file"), modes_json,
              _existing(args.quality_factors, "--quality-factors")]
    relaxation_time = None
    if args.relaxation_time is not None and args.fit != "prony":
        raise StudyError(f"--relaxation-time is not allowed with --fit {args.fit}; allowed: "
                         "with --fit prony")
    if args.relaxation_time is not None:
        from copdea_fem.study import convert_quantity
        relaxation_time = convert_quantity("--relaxation-time", args.relaxation_time, "s",
                                           minimum=1e-12, maximum=1e3)
    if args.fit == "modal" and (args.spectrum is None or args.quality_factors):
        raise StudyError("--fit modal (the reduced model's b/m) needs SPECTRUM.csv and no "
                         "--quality-factors; allowed: a spectrum CSV, or --fit rayleigh|prony "
                         "with --quality-factors Q.csv or a spectrum CSV")
    if args.fit != "modal":
        if args.quality_factors is not None:     # every row checked before any work
            from copdea_fem.damping_fit import check_measured, read_quality_csv
            check_measured(read_quality_csv(args.quality_factors))
        if args.spectrum is None and args.quality_factors is None:
            raise StudyError(f"--fit {args.fit} needs measured damping; allowed: "
                             "--quality-factors Q.csv or a SPECTRUM.csv")
        _check_size(args, study)
    if args.fit == "modal":
        def action():
            return calibrate_damping_cli(study, args.spectrum, out_dir,
                                         modes_json=args.modes_json, window=args.window)
    else:
        from copdea_fem.damping_fit import calibrate_structural_damping

        def action():
            return calibrate_structural_damping(
                study, args.spectrum, out_dir, args.fit, args.quality_factors,
                modes_json=args.modes_json, window=args.window, relaxation_time=relaxation_time)
    with _output(args, out_dir, "calibrate-damping", inputs), solving(study):
        return _reduced_action(action)


def _add_reduced_commands(commands, with_study) -> None:
    modes_help = "FE modes.json whose coupled frequencies set the added masses " \
                 "(default: reduced.modes_json)"
    spectrum = with_study("spectrum", "reduced-model velocity spectra under the chirp "
                          "(Sect. 5.3): spectrum_average.csv, spectrum_points.csv, "
                          "reduced_modes.csv")
    spectrum.add_argument("--out", help="result directory (default: output.directory)")
    spectrum.add_argument("--modes-json", help=modes_help)
    spectrum.set_defaults(handler=cmd_spectrum)

    fit = with_study("fit-material", "fit c10, c20, c01 of eq. (20) to force-displacement "
                     "data with the ring model (Sect. 5.1)")
    fit.add_argument("data", help="CSV with columns z_m, force_n [, voltage_v, prestretch, "
                     "inner_radius_m, force_std_n] (SI)")
    fit.add_argument("--out", help="result directory (default: output.directory)")
    fit.set_defaults(handler=cmd_fit_material)

    calibrate = with_study("calibrate-damping", "modal damping b/m from the peak heights of a "
                           "measured average spectrum (Sect. 5.3)")
    calibrate.add_argument("spectrum", nargs="?", help="CSV with columns freq_hz, v_axial, "
                           "v_radial (Hz, m/s), measured with the study's excitation "
                           "(optional with --quality-factors)")
    calibrate.add_argument("--fit", choices=("modal", "rayleigh", "prony"), default="modal",
                           help="modal: b/m of the reduced model (default); rayleigh: the FE's "
                           "membrane.rayleigh_alpha/beta; prony: one membrane.prony term "
                           "(docs/damping.md)")
    calibrate.add_argument("--quality-factors", metavar="Q.csv",
                           help="measured modes for --fit rayleigh|prony: CSV with columns "
                           "label, quality_factor (or damping_ratio) [, freq_hz]")
    calibrate.add_argument("--relaxation-time", metavar="TIME",
                           help="--fit prony: fix tau (e.g. '1 ms') and fit the modulus ratio only")
    calibrate.add_argument("--allow-large", action="store_true",
                           help="--fit rayleigh|prony: do not refuse a FE mesh estimated above "
                           "the size limit")
    calibrate.add_argument("--quiet", action="store_true", help="no FE progress messages")
    calibrate.add_argument("--window", type=float, default=0.15,
                           help="relative half-width of the peak search around each mode")
    calibrate.add_argument("--modes-json", help=modes_help)
    calibrate.add_argument("--out", help="result directory (default: output.directory)")
    calibrate.set_defaults(handler=cmd_calibrate_damping)


# -- parameter sweeps: sweep SWEEP.yaml ---------------------------------------------------------
def cmd_sweep(args) -> int:
    """Run or resume a sweep; exit 3 if no point produced a result."""
    from copdea_fem import api
    from copdea_fem.study import parse_overrides
    from copdea_fem.sweeps import format_summary, load_sweep
    from copdea_fem.sweeps.cluster import check_scheduler

    sweep = load_sweep(args.sweep, overrides=parse_overrides(args.set))
    check_scheduler(args.executor or sweep.execution.executor, args.scheduler)
    if sweep.model != "reduced":
        _check_size(args, *(point.study for point in sweep.points))
    out_dir = Path(args.out or sweep.output_directory)
    with _output(args, out_dir, "sweep", [args.sweep]) as folder:
        result = api.sweep(args.sweep, args.set or None, out=folder, executor=args.executor,
                           workers=args.workers, scheduler=args.scheduler,
                           chain_length=args.chain_length,
                           reuse=False if args.no_reuse else None, allow_large=True)
    outcome = result.outcome                  # run in the claimed folder: nothing to copy
    print(format_summary(sweep, outcome))
    return 3 if len(outcome.failed) == len(sweep.points) else 0


def _add_sweep_command(commands) -> None:
    sweep = commands.add_parser(
        "sweep", help="parameter sweep with tracked modes (Fig. 11): sweep.csv, sweep.png")
    sweep.add_argument("sweep", help="SWEEP.yaml: base study, axes over study keys, model")
    sweep.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE",
                       help="override a key of the base study, with units")
    sweep.add_argument("--out", help="result directory (default: output.directory of the file)")
    sweep.add_argument("--executor", choices=("local", "pool", "dask"),
                       help="local (default), a pool of worker processes, or a Dask cluster "
                       "(the one at --scheduler, else a local one started for the sweep)")
    sweep.add_argument("--workers", type=int, help="worker processes of --executor pool, or "
                       "of the local cluster of --executor dask (default: one per core)")
    sweep.add_argument("--scheduler", metavar="ADDRESS",
                       help="a running Dask scheduler for --executor dask, e.g. "
                       "tcp://host:8786 (default: a local cluster for the sweep)")
    sweep.add_argument("--chain-length", help="points per continuation chain: auto or N")
    sweep.add_argument("--no-reuse", action="store_true",
                       help="solve every point from scratch (benchmark baseline)")
    sweep.add_argument("--quiet", action="store_true", help="no per-point progress")
    _add_mesh_options(sweep)
    sweep.set_defaults(handler=cmd_sweep)


# -- diagnosis: diagnose MEASURED.yaml, synth STUDY.yaml, effects ---------------------------------
def cmd_diagnose(args) -> int:
    """Which catalogued effect the model lacks; report.md, diagnosis.json, PNGs."""
    from copdea_fem import api
    from copdea_fem.diagnosis import diagnose_out_dir, load_measured, summary_lines
    if args.fe_cache:
        from copdea_fem.diagnosis.fe import check_cache_dir
        check_cache_dir(args.fe_cache, "--fe-cache")    # a file: exit 2 before any work
    if args.fe_workers is not None:
        from copdea_fem.diagnosis.fe import check_workers
        check_workers(args.fe_workers, "--fe-workers")
    from copdea_fem.sweeps.cluster import check_scheduler
    check_scheduler(args.executor, args.scheduler)      # exit 2 before any work
    measured = load_measured(args.measured)
    out_dir = Path(args.out) if args.out else diagnose_out_dir(measured)
    inputs = [args.measured, *(path for condition in measured.conditions
                               for path in condition.files.values())]
    with _output(args, out_dir, "diagnose", inputs) as folder:
        def action():
            diagnosis = api.diagnose(args.measured, alpha=args.alpha, model=args.model,
                                     fe_cache=args.fe_cache, fe_workers=args.fe_workers,
                                     executor=args.executor, scheduler=args.scheduler)
            diagnosis.write(folder)
            return {"lines": summary_lines(diagnosis.result, out_dir)}
        return _reduced_action(action)


def cmd_correlate(args) -> int:
    """Pair each scanned condition's identified modes with the FE's by shape."""
    from copdea_fem import api
    from copdea_fem.diagnosis import load_measured
    measured = load_measured(args.measured)
    if not any(condition.scan is not None for condition in measured.conditions):
        raise StudyError(f"{args.measured}: no condition names a scan; allowed: conditions "
                         "with scan: FILE.uff")
    out_dir = Path(args.out) if args.out else Path("results") / f"correlate_{measured.name}"
    inputs = [args.measured, *(path for condition in measured.conditions
                               for path in condition.files.values())]
    with _output(args, out_dir, "correlate", inputs) as folder:
        result = api.correlate(args.measured)
        result.write(folder)
    for correlation in result.correlations:
        paired = sum(1 for pair in correlation.pairs if pair.label)
        print(f"{correlation.condition}: {paired} of {len(correlation.pairs)} test modes "
              "paired by shape")
    print(f"wrote pairs.csv, comac.csv, mac.png and report.md to {out_dir}")
    return 0


def cmd_identify(args) -> int:
    """The modes of every scan of a measured.yaml: identified.csv, stabilisation PNGs, VTU."""
    from copdea_fem import api
    from copdea_fem.diagnosis import load_measured
    measured = load_measured(args.measured)
    if not any(condition.scan is not None for condition in measured.conditions):
        raise StudyError(f"measured file {args.measured}: no condition has a scan; allowed: "
                         "at least one condition with scan: FILE (.uff/.unv)")
    out_dir = Path(args.out) if args.out else Path("results") / f"identify_{measured.name}"
    inputs = [args.measured, *(path for condition in measured.conditions
                               for path in condition.files.values())]
    options = {} if args.max_order is None else {"max_order": args.max_order}
    if options:
        from copdea_fem.vibrometer.identification import check_options
        check_options(options)                       # exit 2 before any work
    with _output(args, out_dir, "identify", inputs) as folder:
        result = api.identify(args.measured, **options)
        result.write(folder)
    for item in result.sets:
        modes = ", ".join(f"{m.freq_hz:.1f}" for m in item.modes)
        print(f"{item.condition}: {len(item.modes)} modes [Hz]: {modes}")
    print(f"wrote {out_dir}")
    return 0


def cmd_synth(args) -> int:
    """Synthetic measured.yaml set from the model with chosen effects on."""
    from copdea_fem.diagnosis import run_synth, synth_out_dir
    from copdea_fem.diagnosis.synth import SynthOptions
    study = _study(args)
    out_dir = Path(args.out) if args.out else synth_out_dir(study, args.seed)
    options = SynthOptions(frequency_noise=args.frequency_noise, quality_noise=args.quality_noise,
                           amplitude_noise=args.amplitude_noise,
                           missing_probability=args.missing, spurious=args.spurious,
                           label_fraction=args.label_fraction, spectra=not args.no_spectra,
                           seed=args.seed)
    if args.format == "uff":
        from copdea_fem.diagnosis import run_synth_scan
        from copdea_fem.diagnosis.synth_scan import ScanOptions
        options = ScanOptions(frequency_noise=args.frequency_noise, seed=args.seed)
        options.check()
        with _output(args, out_dir, "synth", [args.study]):
            return _reduced_action(lambda: run_synth_scan(study, args.effects, args.conditions,
                                                          args.param, options, out_dir))
    with _output(args, out_dir, "synth", [args.study]):
        return _reduced_action(lambda: run_synth(study, args.effects, args.conditions,
                                                 args.param, options, out_dir))


def cmd_effects(args) -> int:
    from copdea_fem.diagnosis import catalogue_table
    print(catalogue_table())
    return 0


def _add_diagnose_commands(commands, with_study) -> None:
    diagnose = commands.add_parser(
        "diagnose", help="find the physical effects the model lacks from measured resonances "
        "and spectra: report.md, diagnosis.json, PNG figures, final_study.yaml")
    diagnose.add_argument("measured", help="measured.yaml (base study, conditions, resonance "
                          "and spectrum CSVs; see README 'Measured data and diagnosis')")
    diagnose.add_argument("--out", help="report directory (default: results/diagnose_<name>)")
    diagnose.add_argument("--alpha", type=float, default=0.05,
                          help="false-alarm probability per step (default 0.05)")
    diagnose.add_argument("--model", choices=("fe", "reduced"),
                          help="model of record (default: measured.yaml's model, else fe: the "
                               "FE as the base study is written, the ring model its anchored "
                               "surrogate; reduced: the ring model alone)")
    diagnose.add_argument("--fe-cache", metavar="DIR",
                          help="folder of cached FE solves (default: $COPDEA_FEM_FE_CACHE, else "
                               "the user cache folder; a $COPDEA_FEM_FE_CACHE that names a "
                               "file is ignored with a warning)")
    diagnose.add_argument("--fe-workers", metavar="N",
                          help="processes solving FE studies side by side (default: "
                               "$COPDEA_FEM_FE_WORKERS, else the cores, at most 4; 1: one at "
                               "a time); with --executor dask, the local cluster's workers")
    diagnose.add_argument("--executor", choices=("local", "dask"),
                          help="where the FE studies are solved side by side: local "
                               "processes (default) or a Dask cluster (the one at "
                               "--scheduler, else a local one started for the run)")
    diagnose.add_argument("--scheduler", metavar="ADDRESS",
                          help="a running Dask scheduler for --executor dask, e.g. "
                               "tcp://host:8786 (the workers must reach the --fe-cache folder "
                               "to share it)")
    diagnose.add_argument("--quiet", action="store_true", help="no progress messages")
    diagnose.set_defaults(handler=cmd_diagnose)

    correlate = commands.add_parser(
        "correlate", help="pair the modes identified in each condition's vibrometer scan "
        "with the FE's by shape: pairs.csv, comac.csv, mac.png, report.md")
    correlate.add_argument("measured", help="measured.yaml with conditions that name a scan "
                           "(scan: FILE.uff)")
    correlate.add_argument("--out", help="result directory (default: "
                           "results/correlate_<name>)")
    correlate.add_argument("--quiet", action="store_true", help="no progress messages")
    correlate.set_defaults(handler=cmd_correlate)

    identify = commands.add_parser(
        "identify", help="identify the modes of the vibrometer scans (UFF exports) of a "
        "measured.yaml: identified.csv, stabilisation_<condition>.png, shapes VTU")
    identify.add_argument("measured", help="measured.yaml whose conditions name scan: FILE")
    identify.add_argument("--out", help="output directory (default: results/identify_<name>)")
    identify.add_argument("--max-order", type=int, metavar="N",
                          help="highest LSCF model order (default 120: up to 60 modes in the "
                               "band)")
    identify.add_argument("--quiet", action="store_true", help="no progress messages")
    identify.set_defaults(handler=cmd_identify)

    synth = with_study("synth", "synthetic measured data from the model with chosen effects on "
                       "(frequency noise, missing and spurious peaks, spectra), for diagnose")
    synth.add_argument("--effects", default="", help="comma-separated effects switched on in the "
                       "truth, e.g. air_loading,spring_mass (see copdea-fem effects)")
    synth.add_argument("--param", action="append", metavar="EFFECT.PARAMETER=VALUE",
                       help="an effect parameter of the truth, e.g. air_loading.scale=1.2")
    synth.add_argument("--conditions", help="'load.z=11 mm, load.voltage=2 kV; load.z=16 mm' "
                       "(';' between conditions; default: five operating points of Sect. 4)")
    synth.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    synth.add_argument("--frequency-noise", type=float, default=0.015,
                       help="1-sigma relative frequency scatter (default 0.015)")
    synth.add_argument("--quality-noise", type=float, default=0.15,
                       help="1-sigma relative scatter of quality factors (default 0.15)")
    synth.add_argument("--amplitude-noise", type=float, default=0.10,
                       help="1-sigma relative noise per spectral line (default 0.10)")
    synth.add_argument("--missing", type=float, default=0.10,
                       help="probability that a mode's peak is missing (default 0.10)")
    synth.add_argument("--spurious", type=int, default=1,
                       help="spurious peaks in the whole set (default 1)")
    synth.add_argument("--label-fraction", type=float, default=0.5,
                       help="share of peaks that keep their mode label (default 0.5)")
    synth.add_argument("--no-spectra", action="store_true", help="resonance lists only")
    synth.add_argument("--format", choices=("csv", "uff"), default="csv",
                       help="csv (default): resonance and spectrum CSVs from the ring model; "
                       "uff: a scanning vibrometer's export per condition (UFF, FRFs of the "
                       "velocity per volt on the paper's 84-point grid, three components) "
                       "made by the FE forced response of an imperfect electrode, for "
                       "identify, correlate and diagnose")
    synth.add_argument("--out", help="output directory (default: results/synth_<study>_seed<N>)")
    synth.set_defaults(handler=cmd_synth)
    commands.add_parser("effects", help="print the effect catalogue of diagnose").set_defaults(
        handler=cmd_effects)


def _add_mesh_options(command) -> None:
    from copdea_fem.fe.engines import MAX_UNKNOWNS
    from copdea_fem.fe.quadrant.geometry import CACHE_VARIABLE
    command.add_argument("--mesh-cache", metavar="DIR",
                         help=f"mesh cache folder (default: ${CACHE_VARIABLE}, else the source "
                         "checkout's meshes/, else the user cache folder)")
    command.add_argument("--allow-large", action="store_true",
                         help=f"start even when the problem is estimated above {MAX_UNKNOWNS:.0e} "
                         "unknowns")


def _version() -> str:
    from importlib import metadata
    try:
        return metadata.version("copdea-fem")
    except metadata.PackageNotFoundError:
        return "unknown (not installed)"


class _VersionAction(argparse.Action):
    """``--version``: the installed version, looked up only when asked (importlib.metadata
    scans every installed distribution, which would slow every command otherwise)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                 help="show program's version number and exit"):
        super().__init__(option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        parser._print_message(f"copdea-fem {_version()}\n", sys.stdout)   # as "version"
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="copdea-fem", description="Vibro-acoustic FE and reduced models of COP-DEAs.")
    parser.add_argument("--version", action=_VersionAction)
    commands = parser.add_subparsers(dest="command", required=True)

    def with_study(name, help_text):
        command = commands.add_parser(name, help=help_text)
        command.add_argument("study", help="study YAML file")
        command.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE",
                             help="override a study key, with units: --set load.voltage='3 kV'")
        return command

    check = with_study("check", "validate a study without solving")
    check.add_argument("--allow-large", action="store_true",
                       help="do not refuse a mesh estimated above the size limit")
    check.set_defaults(handler=cmd_check)
    commands.add_parser("schema", help="print the study reference table").set_defaults(
        handler=cmd_schema)

    solve = with_study("solve", "prestress + modes; writes modes.csv/json, ParaView files")
    solve.add_argument("--out", help="result directory (default: output.directory)")
    solve.add_argument("--quiet", action="store_true", help="no progress messages")
    _add_mesh_options(solve)
    solve.set_defaults(handler=cmd_solve)

    force = with_study("force", "static disc force F(z) at given voltages (Fig. 4b)")
    force.add_argument("--voltages", default="0 kV, 3 kV", help="comma separated voltages")
    force.add_argument("--z-max", help="largest z (default: max(load.z, 18 mm))")
    force.add_argument("--points", type=int, default=10, help="number of z values incl. 0")
    force.add_argument("--out", help="result directory (default: output.directory)")
    force.add_argument("--quiet", action="store_true", help="no progress messages")
    _add_mesh_options(force)
    force.set_defaults(handler=cmd_force)
    response = with_study("response", "forced response of the coupled FE under the chirp: "
                          "response_average.csv, response_points.csv, spl.csv, PNGs, ODS")
    response.add_argument("--out", help="result directory (default: output.directory)")
    response.add_argument("--quiet", action="store_true", help="no progress messages")
    _add_mesh_options(response)
    response.set_defaults(handler=cmd_response)
    _add_reduced_commands(commands, with_study)
    _add_sweep_command(commands)
    _add_diagnose_commands(commands, with_study)
    return parser


def _terminate(signum, frame):
    raise Terminated


def _interrupted(args) -> str:
    record = getattr(args, "claim", None)
    if record is not None and record.command == "sweep":
        return f"interrupted; the points finished so far are kept in {record.target}; run " \
               "the sweep again to resume"
    if record is not None:
        return f"interrupted; {record.whereabouts()}"
    return "interrupted; no result written"


def main(argv: list[str] | None = None) -> int:
    from copdea_fem.fe.quadrant.geometry import CACHE_VARIABLE

    args = build_parser().parse_args(argv)
    saved_cache = os.environ.get(CACHE_VARIABLE)
    if getattr(args, "mesh_cache", None):
        os.environ[CACHE_VARIABLE] = args.mesh_cache   # reaches sweep worker processes too
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    try:
        with _progress(args):
            return _run(args)
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous)
        if saved_cache is None:
            os.environ.pop(CACHE_VARIABLE, None)
        else:
            os.environ[CACHE_VARIABLE] = saved_cache


def _run(args) -> int:
    from copdea_fem.fe.prestress import PrestressError

    try:
        return args.handler(args)
    except KeyboardInterrupt as interruption:
        print(_interrupted(args), file=sys.stderr)
        return 143 if isinstance(interruption, Terminated) else 130
    except (StudyError, OutputFolderError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except (SolveFailed, PrestressError, NotImplementedError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 3
    except RuntimeError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1


#: gen-0 threshold of Python's cyclic garbage collector in a command's process (CPython's
#: default: 700).  A command's objects are long-lived: importing NGSolve and SciPy alone
#: starts ~110 collections that find nothing, a noticeable share of a small command's time;
#: every 100 000 container allocations still collect what cycles a long run leaves.
COMMAND_GC_THRESHOLD = 100_000


def console_main() -> int:
    """The ``copdea-fem`` command (and ``python -m copdea_fem.cli``): :func:`main` in a
    process that ends with it.  The garbage collector runs less often
    (:data:`COMMAND_GC_THRESHOLD`), and the objects still alive when the command returns
    are frozen (:func:`gc.freeze`) so that the interpreter's last collection does not walk
    them all (many objects after a solve); the operating system frees the process's memory
    anyway, and every file is closed and every result folder in place by then."""
    gc.set_threshold(COMMAND_GC_THRESHOLD, *gc.get_threshold()[1:])
    code = main()
    gc.freeze()
    return code


if __name__ == "__main__":
    sys.exit(console_main())
