"""Synthetic measured data from the model with chosen effects on, for the diagnosis
(:func:`synthesise`, :class:`SyntheticData`), and the catalogue of those effects
(:func:`catalogue_table`)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from copdea_fem.api.calls import as_study, input_files
from copdea_fem.api.folders import Output, claimed, claiming
from copdea_fem.folders import Claim
from copdea_fem.study import Study, StudyError

if TYPE_CHECKING:
    from copdea_fem.diagnosis.synth import SynthOptions
    from copdea_fem.diagnosis.synth_scan import ScanOptions

logger = logging.getLogger(__name__)

#: The file formats of :func:`synthesise`: resonance and spectrum CSVs from the ring model,
#: or a scanning vibrometer's export (UFF) per condition made by the FE.
SYNTHETIC_FORMATS = ("csv", "uff")


def synthesise(study: Study | str | Path, effects: str = "", conditions: str | None = None,
               parameters: list[str] | None = None, *, file_format: str = "csv",
               seed: int = 0, frequency_noise: float = 0.015, quality_noise: float = 0.15,
               amplitude_noise: float = 0.10, missing: float = 0.10, spurious: int = 1,
               label_fraction: float = 0.5, spectra: bool = True,
               options: SynthOptions | ScanOptions | None = None,
               out: str | Path | Claim | Output | None = None) -> SyntheticData:
    """A synthetic measured data set from the model with chosen effects on, for
    ``diagnose`` (``copdea-fem synth``).

    Parameters
    ----------
    study : Study, str or Path
        The base study (the model that will be diagnosed; written as the set's
        ``base_study.yaml``).
    effects : str, default ""
        Comma-separated effects switched on in the truth, e.g. ``"air_loading,spring_mass"``
        (:func:`catalogue_table`).
    conditions : str, optional
        ``"load.z=11 mm, load.voltage=2 kV; load.z=16 mm"`` (``;`` between conditions;
        default: five operating points of Sect. 4).
    parameters : list of str, optional
        Effect parameters of the truth, ``["air_loading.scale=1.2", ...]``.
    file_format : {"csv", "uff"}, default "csv"
        ``"csv"``: resonance and spectrum CSVs from the ring model; ``"uff"``: a scanning
        vibrometer's export per condition (FRFs of the velocity per volt on the paper's
        84-point grid, three components) made by the FE forced response of an imperfect
        electrode, for identify, correlate and diagnose.
    seed : int, default 0
        Random seed.
    frequency_noise : float, default 0.015
        1-sigma relative frequency scatter [-].
    quality_noise, amplitude_noise, missing, spurious, label_fraction, spectra
        ``"csv"`` only (``"uff"`` refuses any but the default): 1-sigma relative scatter of quality factors and of each spectral
        line [-], probability that a mode's peak is missing [-], spurious peaks in the
        whole set, share of peaks that keep their mode label [-], and whether spectra are
        made (else resonance lists only).
    options : SynthOptions or ScanOptions, optional
        All settings of the format's generator
        (:class:`copdea_fem.diagnosis.synth.SynthOptions`,
        :class:`copdea_fem.diagnosis.synth_scan.ScanOptions`: the scan grid and frequency
        axis too), in place of the keywords above.
    out : str, Path, Claim or Output, optional
        Where to write the set (claimed after the inputs are checked, before any work;
        :meth:`SyntheticData.write`); default: nothing written.

    Returns
    -------
    SyntheticData

    Raises
    ------
    StudyError
        A bad study file or key, an unknown effect or one the format cannot hold, a bad
        parameter, condition or setting.
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    ReducedModelError
        The ring model cannot be evaluated at a condition (the CLI's exit 3).
    SolveFailed, PrestressError
        An FE solve of ``"uff"`` fails (as in :func:`solve`).
    """
    from copdea_fem.diagnosis import synth_out_dir

    study = as_study(study)
    if file_format not in SYNTHETIC_FORMATS:
        raise StudyError(f"--format = {file_format!r} is not allowed; allowed: one of "
                         + ", ".join(SYNTHETIC_FORMATS))
    check_driven_conditions(study, conditions)
    if file_format == "uff":
        from copdea_fem.diagnosis import check_scan_truth
        from copdea_fem.diagnosis.synth_scan import ScanOptions, synthesise_scan_set
        given = {"--quality-noise": (quality_noise, 0.15), "--amplitude-noise":
                 (amplitude_noise, 0.10), "--missing": (missing, 0.10),
                 "--spurious": (spurious, 1), "--label-fraction": (label_fraction, 0.5),
                 "--no-spectra": (not spectra, False)}
        for option, (value, default) in given.items():
            if value != default:
                raise StudyError(f"{option} = {value!r} is not allowed with --format uff; "
                                 f"allowed: its default ({default!r}) -- it sets the csv "
                                 "format's resonance lists and spectra, which a scan export "
                                 "does not hold")
        options = options or ScanOptions(frequency_noise=frequency_noise, seed=seed)
        options.check()
        truth, named = check_scan_truth(study, effects, conditions, parameters)
    else:
        from copdea_fem.diagnosis.synth import SynthOptions
        from copdea_fem.study.imperfections import imperfections_given
        given = imperfections_given(study)
        if given:
            raise StudyError(f"{given} is not allowed with --format csv; allowed: a perfect "
                             "(round) device -- the csv format's data come from the ring "
                             "model, which is axisymmetric; --format uff makes the data of an "
                             "imperfect device with the 3-D FE")
        if study.geometry.enclosure != "none":
            logger.warning(
                "synth --format csv: the ring model makes these data and holds no enclosure: "
                f"geometry.enclosure = {study.geometry.enclosure} is not in them (--format uff "
                "solves the FE with it)")
        options = options or SynthOptions(
            frequency_noise=frequency_noise, quality_noise=quality_noise,
            amplitude_noise=amplitude_noise, missing_probability=missing, spurious=spurious,
            label_fraction=label_fraction, spectra=spectra, seed=seed)
        options.check()
    with claiming(out, "synth", input_files(study), synth_out_dir(study, options.seed)) \
            as folder:
        if file_format == "uff":
            items = synthesise_scan_set(study, truth, named, options)
        else:
            from copdea_fem.diagnosis import synthesise_set
            truth, items = synthesise_set(study, effects, conditions, parameters, options)
        result = SyntheticData(study, file_format, truth, items, options)
        if folder is not None:
            result.write(folder)
    return result


def check_driven_conditions(study: Study, conditions: str | None) -> None:
    """Refuse, before any work, a condition where the voltage drives nothing (the flat
    membrane, no bias): its data would be round-off.  The check is ``response``'s
    (:func:`copdea_fem.forced_response.run.check_driven_state`); a condition that does not
    parse is left to the format's own checks, which name it."""
    from copdea_fem.diagnosis.synth import parse_conditions
    from copdea_fem.forced_response.run import check_driven_state
    for index, overrides in enumerate(parse_conditions(conditions)):
        try:
            condition_study = study.replace(overrides)
        except StudyError:
            continue
        try:
            check_driven_state(condition_study, "synth")
        except StudyError as error:
            raise StudyError(f"--conditions #{index + 1}: {error}") from None


@dataclass
class SyntheticData:
    """The result of :func:`synthesise`: a synthetic measured data set.

    Parameters
    ----------
    study : Study
        The base study.
    file_format : str
        ``"csv"`` or ``"uff"``.
    effects : dict
        ``{effect id: parameter values}`` switched on in the truth.
    conditions : list
        Each condition's data: :class:`~copdea_fem.diagnosis.synth.SynthCondition`
        (resonances, spectrum) or :class:`~copdea_fem.diagnosis.synth_scan.ScannedCondition`
        (the export).
    options : SynthOptions or ScanOptions
        The generator's settings (the seed among them).
    """

    study: Study
    file_format: str
    effects: dict
    conditions: list
    options: SynthOptions | ScanOptions
    files: list = field(default_factory=list, repr=False)

    @property
    def names(self) -> list[str]:
        """The conditions' names."""
        return [item.name for item in self.conditions]

    def summary_lines(self, folder: str | Path | None = None) -> list[str]:
        """What ``copdea-fem synth`` prints: the conditions, the truth, and (``folder``:
        where the set was written) the files and how to diagnose them."""
        from copdea_fem.diagnosis import describe_truth
        if self.file_format == "uff":
            first = (f"{len(self.conditions)} scanned conditions: "
                     + ", ".join(self.names))
        else:
            first = f"{len(self.conditions)} conditions: " + ", ".join(
                f"{i.name} ({len(i.resonances)} peaks"
                f"{', spectrum' if i.spectrum is not None else ''})" for i in self.conditions)
        lines = [first, f"truth: {describe_truth(self.effects)}; seed {self.options.seed}"]
        if folder is not None:
            lines.append(f"wrote {len(self.files)} files to {folder}; diagnose with: "
                         f"copdea-fem diagnose {Path(folder) / 'measured.yaml'}")
        return lines

    def write(self, folder: str | Path | Claim) -> Path:
        """Write measured.yaml, base_study.yaml, the measured files (``<condition>_*.csv``
        or ``<condition>.uff``) and synth_truth.json in ``folder``; or into a held
        :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        from copdea_fem.folders import result_directory
        with claimed(folder, "synth", input_files(self.study)) as target:
            with result_directory(target, "synth") as staging:
                if self.file_format == "uff":
                    from copdea_fem.diagnosis.synth_scan import write_scan_set
                    files = write_scan_set(self.study, self.effects, self.conditions,
                                           self.options, staging)
                else:
                    from copdea_fem.diagnosis.synth import write_synthetic
                    files = write_synthetic(self.study, self.effects, self.conditions,
                                            self.options, staging)
                self.files = [target / path.name for path in files]
        return target


def catalogue_table() -> str:
    """The catalogue of the diagnosis's effects as a Markdown table (``copdea-fem effects``):
    each effect's id, what it is, its parameters and what it changes."""
    from copdea_fem.diagnosis import catalogue_table as table
    return table()
