"""Command line: ``copdea-fem solve|check|force|schema ...`` (thin: parse, call, print).

Every command has one shape: one call of the Python API (:mod:`copdea_fem.api`, the only
module of the package imported here), given the command line's options and an
:class:`~copdea_fem.api.Output` for ``--out``; the API function checks its inputs and
options, claims the output folder (before any expensive work), runs and writes its result
(the result's ``write``, the only writer of its files); the command prints the result's
summary.

Exit codes: 0 success; 2 bad input (study, --set, options, input files, an
output folder that may not be written, a problem too large), before any
meshing; 3 a solve that failed for a physical or numerical reason (the message
says what, at which load, and which study key to change); 130 Ctrl-C and 143
SIGTERM (one line, no traceback; a result is either complete or not written);
1 otherwise.  A deprecated spelling (``--executor local``, ``--fe-workers``) still works
for one release, with one line on stderr naming the new one.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import logging
import os
import signal
import sys
import threading
import warnings
from pathlib import Path

from copdea_fem import api


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that every cleanup on the way out runs."""


def _print_progress(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@contextlib.contextmanager
def _progress(args):
    """The messages of the ``copdea_fem`` loggers on stderr while a command runs: INFO and
    above, WARNING and above with ``--quiet``; a command without ``--quiet`` shows only
    the output folder's messages (:mod:`copdea_fem.folders`) and warnings."""
    quiet = getattr(args, "quiet", None)
    with api.progress_to(_print_progress, logging.WARNING if quiet else logging.INFO) \
            as handler:
        if quiet is None:
            handler.addFilter(lambda record: record.levelno > logging.INFO
                              or record.name == "copdea_fem.folders")
        yield


def _one_line(message, category, filename, lineno, line=None) -> str:
    """A warning (a deprecated spelling) as one line on stderr: its message."""
    return f"{message}\n"


def _study(args):
    return api.load_study(args.study, args.set or None)


def _output(args) -> api.Output:
    """``--out`` (None: the command's default folder), claimed by the API call; kept on
    ``args`` for :func:`main`'s interrupt message."""
    args.output = api.Output(args.out)
    return args.output


def _print(lines) -> None:
    print("\n".join(lines))


def cmd_check(args) -> int:
    study = _study(args)
    api.check_size(study, args.allow_large)
    print(f"{args.study}: valid study '{study.name}'")
    return 0


def cmd_schema(args) -> int:
    print(api.reference_table())
    return 0


def cmd_solve(args) -> int:
    out = _output(args)
    solution = api.solve(_study(args), allow_large=args.allow_large, out=out)
    _print(solution.summary_lines(out.path))
    return 0


def cmd_response(args) -> int:
    """Forced response of the coupled FE under the chirp, with radiated sound."""
    solution = api.response(_study(args), allow_large=args.allow_large, out=_output(args))
    _print(solution.summary_lines())
    return 0


def cmd_excite(args) -> int:
    """The drive of each input that lights the target mode(s)."""
    result = api.excite(_study(args), args.target, max_ac=args.max_ac,
                        hold_in_plane=args.hold_in_plane, allow_large=args.allow_large,
                        out=_output(args))
    _print(result.summary_lines())
    return 0


def cmd_statespace(args) -> int:
    """The coupled modal model as a real LTI system."""
    result = api.statespace(_study(args), allow_large=args.allow_large, out=_output(args))
    _print(result.summary_lines())
    return 0


def cmd_force(args) -> int:
    out = _output(args)
    curve = api.force(_study(args), args.voltages, args.z_max or None, args.points,
                      allow_large=args.allow_large, out=out)
    _print(curve.summary_lines(out.path))
    return 0


# -- reduced model (Sect. 3.2, Annex I): spectrum, fit-material, calibrate-damping ---------------
def cmd_spectrum(args) -> int:
    out = _output(args)
    spectrum = api.spectrum(_study(args), modes_json=args.modes_json, out=out)
    _print(spectrum.summary_lines(out.path))
    return 0


def cmd_fit_material(args) -> int:
    fit = api.fit_material(_study(args), args.data, out=_output(args))
    _print(fit.summary_lines())
    return 0


def cmd_calibrate_damping(args) -> int:
    out = _output(args)
    calibration = api.calibrate_damping(
        _study(args), args.spectrum, fit=args.fit, quality_factors=args.quality_factors,
        relaxation_time=args.relaxation_time, modes_json=args.modes_json, window=args.window,
        allow_large=args.allow_large, out=out)
    _print(calibration.summary_lines(out.path))
    return 0


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
    result = api.sweep(args.sweep, args.set or None, out=_output(args), executor=args.executor,
                       workers=args.workers, scheduler=args.scheduler,
                       chain_length=args.chain_length,
                       reuse=False if args.no_reuse else None, allow_large=args.allow_large)
    _print(result.summary_lines())                # run in the claimed folder: nothing to copy
    return 3 if result.all_failed else 0


def _add_sweep_command(commands) -> None:
    sweep = commands.add_parser(
        "sweep", help="parameter sweep with tracked modes (Fig. 11): sweep.csv, sweep.png")
    sweep.add_argument("sweep", help="SWEEP.yaml: base study, axes over study keys, model")
    sweep.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE",
                       help="override a key of the base study, with units")
    sweep.add_argument("--out", help="result directory (default: output.directory of the file)")
    sweep.add_argument("--executor", metavar="{inline,processes,dask}",
                       help="inline: in this process (default); processes: worker processes "
                       "of this machine; dask: a Dask cluster (the one at --scheduler, else "
                       "a local one started for the sweep).  The old local and pool: inline "
                       "and processes (deprecated)")
    sweep.add_argument("--workers", type=int, help="worker processes of --executor processes, "
                       "or of the local cluster of --executor dask (default: the file's "
                       "execution.workers for processes, one per core for dask)")
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
    out = _output(args)
    diagnosis = api.diagnose(args.measured, alpha=args.alpha, model=args.model,
                             fe_cache=args.fe_cache, workers=args.workers,
                             fe_workers=args.fe_workers, executor=args.executor,
                             scheduler=args.scheduler, out=out)
    _print(diagnosis.summary_lines(out.path))
    return 0


def cmd_correlate(args) -> int:
    """Pair each scanned condition's identified modes with the FE's by shape."""
    out = _output(args)
    result = api.correlate(args.measured, allow_large=args.allow_large, out=out)
    _print(result.summary_lines(out.path))
    return 0


def cmd_identify(args) -> int:
    """The modes of every scan of a measured.yaml (identified.csv, stabilisation PNGs,
    VTU), or of one UFF export without a study (modes.csv, shapes.csv, stabilisation.png,
    VTU)."""
    out = _output(args)
    options = {} if args.max_order is None else {"max_order": args.max_order}
    if args.resolve_pairs:
        options["resolve_pairs"] = True
    if Path(args.measured).suffix.lower() in (".uff", ".unv"):
        band = None if args.band is None else tuple(_band_value(v) for v in args.band)
        result = api.identify_file(args.measured, band=band, out=out, **options)
    elif args.band is not None:
        raise api.StudyError(f"--band = {' '.join(args.band)} is not allowed with a "
                             "measured.yaml; allowed: --band with a .uff/.unv file (a "
                             "measured.yaml's conditions have band:)")
    else:
        result = api.identify(args.measured, out=out, **options)
    _print(result.summary_lines(out.path))
    return 0


def _band_value(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise api.StudyError(f"--band = {text!r} is not allowed; allowed: two frequencies "
                             "F1 < F2 in Hz (numbers)") from None


def cmd_synth(args) -> int:
    """Synthetic measured.yaml set from the model with chosen effects on."""
    out = _output(args)
    synthetic = api.synthesise(
        _study(args), args.effects, args.conditions, args.param, file_format=args.format,
        seed=args.seed, frequency_noise=args.frequency_noise, quality_noise=args.quality_noise,
        amplitude_noise=args.amplitude_noise, missing=args.missing, spurious=args.spurious,
        label_fraction=args.label_fraction, spectra=not args.no_spectra, out=out)
    _print(synthetic.summary_lines(out.path))
    return 0


def cmd_effects(args) -> int:
    print(api.catalogue_table())
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
    diagnose.add_argument("--workers", metavar="N",
                          help="processes solving FE studies side by side (default: "
                               "$COPDEA_FEM_FE_WORKERS, else the cores, at most 4; 1: one at "
                               "a time); with --executor dask, the local cluster's workers")
    diagnose.add_argument("--fe-workers", metavar="N",
                          help="the old name of --workers (deprecated)")
    diagnose.add_argument("--executor", metavar="{processes,inline,dask}",
                          help="where the FE studies are solved: processes: side by side in "
                               "worker processes of this machine (default); inline: in this "
                               "process, one at a time; dask: a Dask cluster (the one at "
                               "--scheduler, else a local one started for the run).  The old "
                               "local: processes (deprecated)")
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
    correlate.add_argument("--allow-large", action="store_true",
                           help="solve a condition even when its FE problem is estimated "
                                "above the size limit")
    correlate.add_argument("--quiet", action="store_true", help="no progress messages")
    correlate.set_defaults(handler=cmd_correlate)

    identify = commands.add_parser(
        "identify", help="identify the modes of the vibrometer scans (UFF exports) of a "
        "measured.yaml: identified.csv, stabilisation_<condition>.png, shapes VTU")
    identify.add_argument("measured", help="measured.yaml whose conditions name scan: FILE, "
                          "or a .uff/.unv export of any structure (no study)")
    identify.add_argument("--out", help="output directory (default: results/identify_<name>)")
    identify.add_argument("--band", nargs=2, metavar=("F1", "F2"),
                          help="band [Hz] of a .uff/.unv file (default: all its lines above "
                               "0 Hz)")
    identify.add_argument("--max-order", type=int, metavar="N",
                          help="highest LSCF model order (default 120: up to 60 modes in the "
                               "band)")
    identify.add_argument("--resolve-pairs", action="store_true",
                          help="split a close pair (two modes a few %% apart) the fit merged "
                          "into one pole (default: the measured.yaml's "
                          "identification.resolve_pairs, else off)")
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
    command.add_argument("--mesh-cache", metavar="DIR",
                         help=f"mesh cache folder (default: ${api.MESH_CACHE_VARIABLE}, else "
                         "the source checkout's meshes/, else the user cache folder)")
    command.add_argument("--allow-large", action="store_true",
                         help=f"start even when the problem is estimated above "
                         f"{api.MAX_UNKNOWNS:.0e} unknowns")


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
    excite = with_study("excite", "the drive of each electrode segment that lights the "
                        "target mode(s): drive.csv, selectivity.csv, response_set.txt, PNG, "
                        "operating-shape VTU")
    excite.add_argument("--target", action="append", metavar="LABEL",
                        help="a mode label of the band, e.g. '(2,1)' (repeat for several)")
    excite.add_argument("--max-ac", type=float, metavar="V",
                        help="peak AC amplitude of the drive [V] (default: "
                        "excitation.amplitude)")
    excite.add_argument("--hold-in-plane", action="store_true",
                        help="hold the in-plane modes down too (default: only reported, "
                        "kind in-plane in selectivity.csv)")
    excite.add_argument("--out", help="result directory (default: output.directory)")
    excite.add_argument("--quiet", action="store_true", help="no progress messages")
    _add_mesh_options(excite)
    excite.set_defaults(handler=cmd_excite)
    statespace = with_study("statespace", "the coupled modal model as a real LTI system: "
                            "statespace.npz, statespace.mat")
    statespace.add_argument("--out", help="result directory (default: output.directory)")
    statespace.add_argument("--quiet", action="store_true", help="no progress messages")
    _add_mesh_options(statespace)
    statespace.set_defaults(handler=cmd_statespace)
    _add_reduced_commands(commands, with_study)
    _add_sweep_command(commands)
    _add_diagnose_commands(commands, with_study)
    return parser


def _terminate(signum, frame):
    raise Terminated


def _interrupted(args) -> str:
    output = getattr(args, "output", None)
    record = output.claim if output is not None else None
    if record is not None and record.command == "sweep":
        return f"interrupted; the points finished so far are kept in {record.target}; run " \
               "the sweep again to resume"
    if record is not None:
        return f"interrupted; {record.whereabouts()}"
    return "interrupted; no result written"


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    cache_variable = api.MESH_CACHE_VARIABLE
    saved_cache = os.environ.get(cache_variable)
    if getattr(args, "mesh_cache", None):
        os.environ[cache_variable] = args.mesh_cache   # reaches sweep worker processes too
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    saved_format, warnings.formatwarning = warnings.formatwarning, _one_line
    try:
        with _progress(args):
            return _run(args)
    finally:
        warnings.formatwarning = saved_format
        if main_thread:
            signal.signal(signal.SIGTERM, previous)
        if saved_cache is None:
            os.environ.pop(cache_variable, None)
        else:
            os.environ[cache_variable] = saved_cache


def _run(args) -> int:
    """The command, its errors mapped to exit codes (module notes); an error class that
    lives in a heavy module is looked up only when an error arrives."""
    try:
        return args.handler(args)
    except KeyboardInterrupt as interruption:
        print(_interrupted(args), file=sys.stderr)
        return 143 if isinstance(interruption, Terminated) else 130
    except (api.StudyError, api.OutputFolderError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except (api.SolveFailed, api.PrestressError, api.ReducedModelError,
            NotImplementedError) as error:
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

#: OpenBLAS thread count of a command's process where the environment sets none: one.  The
#: eigen stages run on one BLAS thread anyway (:func:`copdea_fem.progress.single_threaded_blas`);
#: each further thread an OpenBLAS library (NumPy's, SciPy's, NGSolve's) starts when it loads
#: spins a while, CPU time taken from the command's own thread on a busy machine.  (MKL is
#: left alone: a study may choose its PARDISO.)
COMMAND_BLAS_THREADS = {"OPENBLAS_NUM_THREADS": "1"}


def console_main() -> int:
    """The ``copdea-fem`` command (and ``python -m copdea_fem.cli``): :func:`main` in a
    process that ends with it.  The BLAS libraries load with :data:`COMMAND_BLAS_THREADS`
    (unless the environment says otherwise; NumPy is not imported before this).  The garbage
    collector runs less often (:data:`COMMAND_GC_THRESHOLD`), and the objects still alive
    when the command returns are frozen (:func:`gc.freeze`) so that the interpreter's last
    collection does not walk them all (many objects after a solve); the operating system
    frees the process's memory anyway, and every file is closed and every result folder in
    place by then."""
    for name, threads in COMMAND_BLAS_THREADS.items():
        os.environ.setdefault(name, threads)
    gc.set_threshold(COMMAND_GC_THRESHOLD, *gc.get_threshold()[1:])
    code = main()
    gc.freeze()
    return code


if __name__ == "__main__":
    sys.exit(console_main())
