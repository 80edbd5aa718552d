"""What measured data say: the missing effects (:func:`diagnose`, :class:`Diagnosis`), the
modes of vibrometer scans (:func:`identify`, :class:`IdentifyResult`) and their pairing
with the FE's by shape (:func:`correlate`, :class:`CorrelateResult`).  Each takes a
measured.yaml's path or the :class:`~copdea_fem.measured.MeasuredSet` that
:func:`load_measured` read from it (then no file is read again)."""

from __future__ import annotations

import functools
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from copdea_fem.api.calls import check_size, data_frame, reporting_to, solve_checked
from copdea_fem.api.folders import Output, claimed, claiming
from copdea_fem.folders import Claim
from copdea_fem.study import StudyError

if TYPE_CHECKING:
    import pandas as pd

    from copdea_fem.diagnosis.select import DiagnosisResult
    from copdea_fem.measured import MeasuredSet
    from copdea_fem.vibrometer.identified import IdentifiedSet

logger = logging.getLogger("copdea_fem")


def load_measured(path: str | Path) -> MeasuredSet:
    """Read and check a measured.yaml and every file it names (the base study, the resonance
    and spectrum CSVs, the scans), as :func:`diagnose`, :func:`identify` and
    :func:`correlate` do; give them the result to read each file once.

    Parameters
    ----------
    path : str or Path
        A measured.yaml (docs/diagnosis.md, docs/vibrometer.md).

    Returns
    -------
    copdea_fem.measured.MeasuredSet
        The base study, the conditions with their data (scans in SI and in the model's
        frame), the noise model, the candidate effects.

    Raises
    ------
    StudyError
        A missing or bad manifest, measured file or base study (a
        :class:`~copdea_fem.measured.MeasuredDataError`), or an unknown effect in
        ``candidates``.
    """
    from copdea_fem.diagnosis import load_measured as load
    return load(path)


def as_measured(measured: MeasuredSet | str | Path) -> MeasuredSet:
    """A measured.yaml read (:func:`load_measured`), or a
    :class:`~copdea_fem.measured.MeasuredSet` as it is."""
    from copdea_fem.measured import MeasuredSet
    if isinstance(measured, MeasuredSet):
        return measured
    if not isinstance(measured, (str, Path)):
        raise StudyError(f"measured = {type(measured).__name__} is not allowed; allowed: a "
                         "MeasuredSet from load_measured or a measured.yaml's path")
    return load_measured(measured)


def diagnose(measured: MeasuredSet | str | Path, *, alpha: float = 0.05,
             model: str | None = None, fe_cache: str | Path | None = None,
             workers: int | None = None,
             executor: str | None = None, scheduler: str | Any | None = None,
             progress: Callable[[str], None] | None = None,
             out: str | Path | Claim | Output | None = None,
             fe_workers: int | None = None) -> Diagnosis:
    """Which catalogued effects the model lacks, from measured resonances and spectra
    (``copdea-fem diagnose``, nothing written).

    Parameters
    ----------
    measured : MeasuredSet, str or Path
        From :func:`load_measured`, or a measured.yaml: the base study, the conditions and
        their measured files.
    alpha : float, default 0.05
        Significance level of each step (false-alarm probability), in (0, 1).
    model : str, optional
        ``"fe"`` or ``"reduced"``: the model of record, in place of measured.yaml's
        ``model``.
    fe_cache : str or Path, optional
        Cache folder of the FE solves (``model: fe``; default as the CLI's
        ``--fe-cache``).
    workers : int, optional
        Processes solving FE studies side by side (``model: fe``; default as the CLI's
        ``--workers``); with ``executor="dask"`` and no ``scheduler``, the local
        cluster's workers.
    executor : str, optional
        Where the FE studies are solved (``model: fe``; :mod:`copdea_fem.parallel`):
        ``"processes"`` (default), side by side in processes of this machine;
        ``"inline"``, in this process, one at a time; ``"dask"``, a Dask cluster.  The old
        ``"local"`` is ``"processes"`` (with a deprecation warning).
    scheduler : str or distributed.Client, optional
        With ``executor="dask"``: a running Dask scheduler's address or a connected client;
        without it a local cluster is started for the diagnosis and closed at its end.
    progress : callable(str), optional
        As :func:`solve`'s.
    out : str, Path, Claim or Output, optional
        As :func:`solve`'s (:meth:`Diagnosis.write`; an :class:`Output` without a folder:
        ``results/diagnose_<name>``).
    fe_workers : int, optional
        The old name of ``workers`` (with a deprecation warning).

    Returns
    -------
    Diagnosis
        The verdict, the missing effects and the report's content;
        :meth:`Diagnosis.write` writes the report.

    Raises
    ------
    StudyError
        ``alpha`` outside (0, 1), a bad worker count or cache folder, an unknown executor,
        a scheduler without ``executor="dask"`` or one that does not answer (all before the
        measured file is read), a bad measured.yaml, measured file or base study (a
        :class:`~copdea_fem.measured.MeasuredDataError`), or conditions the
        base model cannot evaluate.
    ReducedModelError
        The model cannot be built or evaluated (with ``model: fe``, an FE that cannot be
        solved: :class:`~copdea_fem.diagnosis.anchored.FEFailure`; the CLI's exit 3).
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    """
    from copdea_fem.diagnosis import check_options, diagnose_measured, diagnose_out_dir

    option = "--workers"
    if fe_workers is not None:
        if workers is not None:
            raise StudyError(f"--fe-workers = {fe_workers!r} is not allowed with --workers; "
                             "allowed: --workers alone (--fe-workers is its old name)")
        from copdea_fem.parallel import deprecated
        deprecated("--fe-workers", "--workers")
        workers, option = fe_workers, "--fe-workers"
    workers, executor = check_options(alpha, fe_cache, workers, executor, scheduler, option)
    measured = as_measured(measured)
    inputs = [measured.path, *(path for condition in measured.conditions
                               for path in condition.files.values())]
    with claiming(out, "diagnose", inputs, diagnose_out_dir(measured)) as folder:
        with reporting_to(progress):
            result = diagnose_measured(measured, alpha=alpha, model=model, fe_cache=fe_cache,
                                       fe_workers=workers, executor=executor,
                                       scheduler=scheduler)
        diagnosis = Diagnosis(result, measured.path)
        if folder is not None:
            diagnosis.write(folder)
    return diagnosis


@dataclass
class Diagnosis:
    """The result of :func:`diagnose`: ``result`` (the diagnosis), ``document`` (the
    content of diagnosis.json), ``write``.

    Parameters
    ----------
    result : copdea_fem.diagnosis.select.DiagnosisResult
        Everything the report and diagnosis.json need.
    source : Path, optional
        The measured.yaml (an input the folder checks of ``write`` protect).
    """

    result: DiagnosisResult
    source: Path | None = None

    @property
    def verdict(self) -> str:
        return self.result.verdict

    @property
    def missing_effects(self) -> list[str]:
        return list(self.result.missing_effects)

    @property
    def document(self) -> dict:
        from copdea_fem.diagnosis.report import diagnosis_document
        return diagnosis_document(self.result)

    def summary_lines(self, folder: str | Path) -> list[str]:
        """What ``copdea-fem diagnose`` prints: the verdict, the gap, where the report is
        (``folder``, where it was written)."""
        from copdea_fem.diagnosis import summary_lines
        return summary_lines(self.result, Path(folder))

    def write(self, folder: str | Path | Claim) -> Path:
        """Write report.md, diagnosis.json, figures and final_study.yaml in ``folder``; or
        into a held :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        from copdea_fem.diagnosis.report import write_report
        from copdea_fem.folders import result_directory
        inputs = [self.source] + [path for condition in self.result.measured.conditions
                                  for path in condition.files.values()]
        with claimed(folder, "diagnose", inputs) as target:
            with result_directory(target, "diagnose") as staging:
                write_report(self.result, staging)
        return target


def identify(measured: MeasuredSet | str | Path, *,
             progress: Callable[[str], None] | None = None,
             out: str | Path | Claim | Output | None = None, **options) -> IdentifyResult:
    """The modes of every scan of a measured.yaml (``copdea-fem identify``, nothing written).

    Each condition with ``scan: FILE`` is read (:func:`copdea_fem.measured.read_scan`,
    checked on the device) and identified automatically in its ``band`` (default: the
    scan's lines above 0 Hz): LSCF poles stable over the model orders, LSFD residues as
    shapes (:mod:`copdea_fem.vibrometer.identification`; nothing from the FE).

    Parameters
    ----------
    measured : MeasuredSet, str or Path
        From :func:`load_measured`, or a measured.yaml; at least one condition with a
        ``scan``.
    progress : callable(str), optional
        As :func:`solve`'s.
    out : str, Path, Claim or Output, optional
        As :func:`solve`'s (:meth:`IdentifyResult.write`; an :class:`Output` without a
        folder: ``results/identify_<name>``).
    **options
        Passed to :func:`copdea_fem.vibrometer.identification.identify_scan` (``f_min``,
        ``f_max`` [Hz] in place of the conditions' bands, ``max_order``, ``components``, ``frequency_tolerance``,
        ``damping_tolerance``, ``max_damping``, ``min_stable_orders``).

    Returns
    -------
    IdentifyResult

    Raises
    ------
    StudyError
        A bad measured.yaml, scan file or option, or no condition with a scan (a
        :class:`~copdea_fem.measured.MeasuredDataError`).
    """
    from copdea_fem.measured import MeasuredDataError
    from copdea_fem.vibrometer.identification import (
        OPTIONS,
        check_options,
        check_scan,
        condition_band,
        identify_scan,
    )
    from copdea_fem.vibrometer.identified import IdentifiedSet

    for name in options:
        if name not in OPTIONS:
            raise StudyError(f"identify option {name!r} is not allowed (unknown option); "
                             f"allowed: {', '.join(OPTIONS)}")
    check_options({name: value for name, value in options.items()
                   if name not in ("f_min", "f_max")})
    measured_set = as_measured(measured)
    # the measured.yaml's identification: settings, overridden by the caller's options
    options = {**measured_set.identification,
               **{name: value for name, value in options.items() if value is not None}}
    scanned = [c for c in measured_set.conditions if c.scan is not None]
    if not scanned:
        source = measured_set.path or measured_set.name if measured is measured_set \
            else measured
        raise MeasuredDataError(f"measured file {source}: no condition has a scan; "
                                "allowed: at least one condition with scan: FILE (.uff/.unv)")
    files = [p for c in measured_set.conditions for p in c.files.values()]
    bands = [dict(zip(("f_min", "f_max"), condition_band(condition)))
             for condition in scanned]
    for condition, band in zip(scanned, bands):
        check_scan(condition.scan, **{**band, **options})           # before any work
    sets = []
    with claiming(out, "identify", [measured_set.path, *files],
                  Path("results") / f"identify_{measured_set.name}") as folder, \
            reporting_to(progress):
        for condition, band in zip(scanned, bands):
            logger.info("identifying %s (%d channels, %d lines, largest distance off the "
                        "device %.2f mm)", condition.name, condition.scan.n_channels,
                        condition.scan.frequencies.size, 1e3 * condition.scan_distance)
            found = identify_scan(condition.scan, **{**band, **options})
            sets.append(IdentifiedSet(condition.name, condition.scan, found.modes,
                                      found.diagram))
        result = IdentifyResult(tuple(sets), measured_set.path, files)
        if folder is not None:
            result.write(folder)
    return result


@dataclass
class IdentifyResult:
    """The result of :func:`identify`: ``sets`` (one
    :class:`~copdea_fem.vibrometer.identified.IdentifiedSet` per scanned condition), ``table``,
    ``write``."""

    sets: tuple[IdentifiedSet, ...]
    source: Path | None = None
    files: list = field(default_factory=list)

    def summary_lines(self, folder: str | Path) -> list[str]:
        """What ``copdea-fem identify`` prints: the modes of each condition [Hz] and the
        folder written."""
        lines = []
        for item in self.sets:
            modes = ", ".join(f"{m.freq_hz:.1f}" for m in item.modes)
            lines.append(f"{item.condition}: {len(item.modes)} modes [Hz]: {modes}")
        lines.append(f"wrote {folder}")
        return lines

    @property
    def table(self) -> pd.DataFrame:
        """identified.csv as a DataFrame (condition, test_mode, freq_hz, damping_ratio, mpc)."""
        from copdea_fem.vibrometer.identification_files import IDENTIFIED_COLUMNS, identified_rows
        return data_frame(identified_rows(self.sets), IDENTIFIED_COLUMNS)

    def write(self, folder: str | Path | Claim) -> Path:
        """Write identified.csv, stabilisation_<condition>.png and shapes_<condition>/
        (VTU per mode, shapes.pvd) in ``folder``; or into a held
        :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        from copdea_fem.folders import result_directory
        from copdea_fem.vibrometer.identification_files import write_identified
        with claimed(folder, "identify", [self.source, *self.files]) as target:
            with result_directory(target, "identify") as staging:
                write_identified(staging, self.sets)
        return target


def identify_file(path: str | Path, *, band: tuple[float, float] | None = None,
                  progress: Callable[[str], None] | None = None,
                  out: str | Path | Claim | Output | None = None,
                  **options) -> FileIdentifyResult:
    """The modes of any structure's UFF export, without a study (``copdea-fem identify
    FILE.uff``, nothing written).

    The file is read (:func:`copdea_fem.measured.read_scan` with ``geometry=False``: FRFs
    of one reference, or of one response and several references by reciprocity; nodal
    coordinate systems applied) and identified as a study's scan is (LSCF poles, LSFD
    residues: :mod:`copdea_fem.vibrometer.identification`).

    Parameters
    ----------
    path : str or Path
        A ``.uff``/``.unv`` file with dataset 58 FRFs (function type 4) on one frequency
        axis; datasets 2411/15 (points), 18/2420 (coordinate systems), 82 (trace lines)
        and 164 (units) are used when present.
    band : (float, float), optional
        The band [Hz] (``--band F1 F2``); default: the file's lines above 0 Hz.  A band
        reaching past the file's lines is clipped to them with a warning.
    progress : callable(str), optional
        As :func:`solve`'s.
    out : str, Path, Claim or Output, optional
        As :func:`solve`'s (:meth:`FileIdentifyResult.write`; an :class:`Output` without
        a folder: ``results/identify_<file name>``).
    **options
        As :func:`identify`'s (``max_order``, ``components``, ...; not ``f_min``,
        ``f_max``: ``band``).

    Returns
    -------
    FileIdentifyResult

    Raises
    ------
    StudyError
        A file that cannot be read or identified (a
        :class:`~copdea_fem.measured.MeasuredDataError` naming the file and dataset), a
        bad band or option.
    """
    from copdea_fem.inputs import as_path
    from copdea_fem.measured import read_scan
    from copdea_fem.measured.uff import read_trace_lines
    from copdea_fem.vibrometer.export_identification import ExportIdentification
    from copdea_fem.vibrometer.identification import OPTIONS, check_options, identify_scan

    path = as_path(path, "identify file", StudyError)
    for name in options:
        if name not in OPTIONS or name in ("f_min", "f_max"):
            raise StudyError(f"identify option {name!r} is not allowed (unknown option); "
                             "allowed: band, " + ", ".join(o for o in OPTIONS
                                                           if o not in ("f_min", "f_max")))
    check_options(options)
    band = _checked_band(band)
    scan = read_scan(path, geometry=False)
    frequencies = scan.frequencies
    positive = frequencies[frequencies > 0]
    if positive.size == 0:
        raise StudyError(f"identify file {str(path)!r}: no frequency line above 0 Hz; "
                         "allowed: FRFs on a frequency axis")
    low, high = (float(positive[0]), float(frequencies[-1])) if band is None else band
    if band is not None and (high <= positive[0] or low >= frequencies[-1]):
        raise StudyError(f"--band = [{low:g}, {high:g}] Hz is not allowed (outside the file's "
                         f"lines); allowed: a band within {positive[0]:g}..{frequencies[-1]:g}"
                         " Hz")
    if band is not None and (low < positive[0] or high > frequencies[-1]):
        clipped = max(low, float(positive[0])), min(high, float(frequencies[-1]))
        logger.warning("--band = [%g, %g] Hz reaches past the file's lines %g..%g Hz: "
                       "clipped to [%g, %g] Hz", low, high, positive[0], frequencies[-1],
                       *clipped)
        low, high = clipped
    with claiming(out, "identify", [path], Path("results") / f"identify_{path.stem}") \
            as folder, reporting_to(progress):
        logger.info("identifying %s (%d channels on %d nodes, %d lines, %g-%g Hz)",
                    path, scan.n_channels, scan.n_points, frequencies.size, low, high)
        found = identify_scan(scan, f_min=low, f_max=high, **options)
        traces = read_trace_lines(path)
        result = FileIdentifyResult(ExportIdentification(scan, found, traces), path)
        if folder is not None:
            result.write(folder)
    return result


def _checked_band(band) -> tuple[float, float] | None:
    import math
    import numbers

    if band is None:
        return None
    try:
        low, high = band
    except (TypeError, ValueError):
        raise StudyError(f"--band = {band!r} is not allowed; allowed: two frequencies "
                         "F1 < F2 [Hz]") from None
    if not all(isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)
               for v in (low, high)) or not 0 <= low < high:
        raise StudyError(f"--band = {low!r} {high!r} is not allowed; allowed: two "
                         "frequencies 0 <= F1 < F2 [Hz]")
    return float(low), float(high)


@dataclass
class FileIdentifyResult:
    """The result of :func:`identify_file`: ``result`` (the
    :class:`~copdea_fem.vibrometer.export_identification.ExportIdentification`), ``table``,
    ``write``."""

    result: Any
    source: Path | None = None

    @property
    def modes(self) -> tuple:
        return self.result.modes

    def summary_lines(self, folder: str | Path) -> list[str]:
        """What ``copdea-fem identify FILE`` prints: the modes [Hz] (damping [%]) and the
        folder written."""
        lines = [f"{self.source.name if self.source else 'file'}: {len(self.modes)} modes"]
        lines += [f"  {m.test_mode:3d}  {m.freq_hz:10.3f} Hz  damping {100 * m.damping_ratio:6.3f}"
                  f" %  MPC {m.mpc:.3f}" for m in self.modes]
        lines.append(f"wrote {folder}")
        return lines

    @property
    def table(self) -> pd.DataFrame:
        """modes.csv as a DataFrame (test_mode, freq_hz, damping_ratio, mpc)."""
        from copdea_fem.vibrometer.export_identification import MODES_COLUMNS
        return data_frame([{"test_mode": m.test_mode, "freq_hz": m.freq_hz,
                            "damping_ratio": m.damping_ratio, "mpc": m.mpc}
                           for m in self.modes], MODES_COLUMNS)

    def write(self, folder: str | Path | Claim) -> Path:
        """Write modes.csv, shapes.csv, stabilisation.png and (with a geometry) shapes/
        (VTU per mode, shapes.pvd) in ``folder``; or into a held
        :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        from copdea_fem.folders import result_directory
        from copdea_fem.vibrometer.export_identification import write_export_identification
        title = self.source.name if self.source else "identify"
        with claimed(folder, "identify", [self.source]) as target:
            with result_directory(target, "identify") as staging:
                write_export_identification(staging, self.result, title)
        return target


def correlate(measured: MeasuredSet | str | Path, *, allow_large: bool = False,
              progress: Callable[[str], None] | None = None,
              out: str | Path | Claim | Output | None = None) -> CorrelateResult:
    """Pair the modes identified in each condition's scan (or given by its mode set) with
    the FE's by shape (``copdea-fem correlate``, nothing written).

    For each condition of ``measured`` with a ``scan:`` or ``modes:``: the modes are
    identified (:func:`copdea_fem.vibrometer.identification.identify`, in the condition's
    band) or taken from the mode set (dataset 55, within the band), the base study at the
    condition is solved as the diagnosis solves it
    (:func:`copdea_fem.diagnosis.scanned.scan_fe_study`: the FE band reaching the pairing
    window past the condition's; solved as :func:`solve` solves: the resource guard first, a
    failed solve a :class:`SolveFailed`), its structural modes sampled at the measured
    points along the measured directions (:mod:`copdea_fem.vibrometer.sampling`) and paired
    one-to-one by shape (:func:`copdea_fem.vibrometer.pairing.correlate_shapes`,
    measured.yaml's ``pairing:`` window and smallest MAC): the pairing :func:`diagnose`
    uses (:func:`copdea_fem.diagnosis.scanned.pair_condition`).

    Parameters
    ----------
    measured : MeasuredSet, str or Path
        From :func:`load_measured`, or a measured.yaml; at least one condition that names a
        scan file or a mode set.
    allow_large : bool, default False
        Start even when a condition's FE problem is estimated above the size limit.
    progress : callable(str), optional
        As :func:`solve`'s.
    out : str, Path, Claim or Output, optional
        As :func:`solve`'s (:meth:`CorrelateResult.write`; an :class:`Output` without a
        folder: ``results/correlate_<name>``).

    Returns
    -------
    CorrelateResult
        The correlation of each scanned condition; :meth:`CorrelateResult.write` writes
        pairs.csv, comac.csv, mac.png and report.md.

    Raises
    ------
    StudyError
        A bad measured.yaml, scan file or base study
        (:class:`~copdea_fem.measured.MeasuredDataError`), no condition with a scan or a
        mode set, or a
        condition's problem above the size limit (without ``allow_large``; before any
        work).
    SolveFailed
        A condition's FE solve failed (as :func:`solve`'s).
    PrestressError
        A condition's prestress (Newton) solve failed.
    """
    from copdea_fem.diagnosis.scanned import pair_condition, scan_fe_study
    from copdea_fem.measured import MeasuredDataError
    from copdea_fem.vibrometer.identification import check_scan, condition_band

    measured = as_measured(measured)
    scanned = [c for c in measured.conditions if c.shapes_measured]
    if not scanned:
        raise MeasuredDataError(f"{measured.path or measured.name}: no condition names a "
                                "scan or a mode set; allowed: conditions with scan: FILE.uff "
                                "or modes: FILE.unv")
    studies = [scan_fe_study(measured, condition) for condition in scanned]
    for condition in scanned:                           # before any work
        if condition.scan is not None:
            f_min, f_max = condition_band(condition)
            check_scan(condition.scan, f_min=f_min, f_max=f_max)
    for study in studies:
        check_size(study, allow_large)                 # every condition's, before any work
    correlations, scans = [], []
    inputs = [measured.path, *(path for condition in measured.conditions
                               for path in condition.files.values())]
    with claiming(out, "correlate", inputs, Path("results") / f"correlate_{measured.name}") \
            as folder, reporting_to(progress):
        for condition in scanned:
            logger.info("correlate %s: the test modes, the FE's at the measured points",
                        condition.name)
            pairing = pair_condition(measured, condition, solve=functools.partial(
                solve_checked, allow_large=allow_large))
            correlations.append(pairing.correlation)
            scans.append(pairing.scan)
        result = CorrelateResult(measured, tuple(correlations), tuple(scans))
        if folder is not None:
            result.write(folder)
    return result


@dataclass
class CorrelateResult:
    """The result of :func:`correlate`: one
    :class:`~copdea_fem.vibrometer.pairing.Correlation` per scanned condition.

    Attributes
    ----------
    measured : copdea_fem.measured.MeasuredSet
    correlations : tuple of Correlation
    scans : tuple of ScanData
        Each correlation's scan (its channels: comac.csv).
    """

    measured: Any
    correlations: tuple
    scans: tuple

    def summary_lines(self, folder: str | Path) -> list[str]:
        """What ``copdea-fem correlate`` prints: how many test modes of each condition were
        paired by shape, and the files written in ``folder``."""
        lines = []
        for correlation in self.correlations:
            paired = sum(1 for pair in correlation.pairs if pair.label)
            lines.append(f"{correlation.condition}: {paired} of {len(correlation.pairs)} test "
                         "modes paired by shape")
        lines.append(f"wrote pairs.csv, comac.csv, mac.png and report.md to {folder}")
        return lines

    @property
    def pairs(self) -> pd.DataFrame:
        """pairs.csv as a DataFrame (one row per identified test mode)."""
        from copdea_fem.vibrometer.correlation_files import PAIR_COLUMNS
        rows = [{"condition": c.condition, "test_mode": p.test_mode,
                 "test_freq_hz": p.test_freq_hz, "test_damping_ratio": p.test_damping_ratio,
                 "label": p.label, "fe_freq_hz": p.fe_freq_hz, "freq_error": p.freq_error,
                 "mac": p.mac, "fe_auto_mac": p.fe_auto_mac}
                for c in self.correlations for p in c.pairs]
        return data_frame(rows, PAIR_COLUMNS)

    def write(self, folder: str | Path | Claim) -> Path:
        """Write pairs.csv, comac.csv, mac.png and report.md in ``folder``; or into a held
        :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        from copdea_fem.folders import result_directory
        from copdea_fem.vibrometer.correlation_files import (
            plot_mac,
            report_markdown,
            write_comac_csv,
            write_pairs_csv,
        )
        inputs = [self.measured.path] + [path for condition in self.measured.conditions
                                         for path in condition.files.values()]
        with claimed(folder, "correlate", [i for i in inputs if i]) as target, \
                result_directory(target, "correlate") as staging:
            write_pairs_csv(staging / "pairs.csv", self.correlations)
            write_comac_csv(staging / "comac.csv", self.correlations, self.scans)
            plot_mac(staging / "mac.png", self.correlations)
            (staging / "report.md").write_text(
                report_markdown(self.measured.name, self.correlations), encoding="utf-8")
        return target
