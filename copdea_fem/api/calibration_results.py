"""The model's parameters fitted to measurements: the membrane's material to a
force-displacement curve (:func:`fit_material`, :class:`MaterialFitResult`) and its damping to
a measured spectrum or measured quality factors (:func:`calibrate_damping`,
:class:`DampingCalibrationResult`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from copdea_fem.api.calls import (
    as_study,
    check_size,
    data_frame,
    input_files,
    reporting_to,
    solving,
)
from copdea_fem.api.folders import Output, claimed, claiming
from copdea_fem.folders import Claim
from copdea_fem.study import Study, StudyError

if TYPE_CHECKING:
    import numpy as np
    import pandas as pd

    from copdea_fem.damping_fit import DampingFit, MeasuredDamping
    from copdea_fem.reduced.chirp_response import DampingCalibration
    from copdea_fem.reduced.fit import MaterialFit
    from copdea_fem.reduced.model import ReducedSetup
    from copdea_fem.reduced.rings import RingModel

#: The fits of :func:`calibrate_damping`: the reduced model's b/m, the FE's Rayleigh keys,
#: one Prony term of the FE's membrane.
DAMPING_FITS = ("modal", "rayleigh", "prony")


def _existing(path, what: str):
    """An input file, checked (exists, readable text) before any work."""
    from copdea_fem.inputs import read_text
    if path is not None:
        read_text(path, what, error=StudyError)
    return path


def fit_material(study: Study | str | Path, data: str | Path, *,
                 out: str | Path | Claim | Output | None = None) -> MaterialFitResult:
    """Fit c10, c20, c01 of eq. (20) to force-displacement data with the ring model
    (Sect. 5.1; ``copdea-fem fit-material``).

    Parameters
    ----------
    study : Study, str or Path
        From :func:`load_study`, or a study file; its c10, c20, c01 are the start values,
        its load.voltage, membrane.prestretch and geometry.inner_radius the defaults of
        missing columns.
    data : str or Path
        A CSV with columns ``z_m, force_n`` [m, N] and optionally ``voltage_v`` [V],
        ``prestretch`` [-], ``inner_radius_m`` [m], ``force_std_n`` [N].
    out : str, Path, Claim or Output, optional
        Where to write the result (claimed after the inputs are checked, before the fit;
        :meth:`MaterialFitResult.write`); default: nothing written.

    Returns
    -------
    MaterialFitResult

    Raises
    ------
    StudyError
        A bad study file or key, a data file that is missing, unreadable or lacks a column.
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    ReducedModelError
        The ring model cannot be built or fitted for these data (the CLI's exit 3).
    """
    from copdea_fem.reduced.io import fit_force_data, read_force_csv

    study = as_study(study)
    _existing(data, "data file")
    columns = read_force_csv(data)
    inputs = [*input_files(study), data]
    with claiming(out, "fit-material", inputs, study.output.directory) as folder:
        model, fit, voltage = fit_force_data(study, columns)
        result = MaterialFitResult(study, model, fit, columns, voltage, Path(data))
        if folder is not None:
            result.write(folder)
    return result


@dataclass
class MaterialFitResult:
    """The result of :func:`fit_material`: the fitted c10, c20, c01 [Pa] and their errors.

    Parameters
    ----------
    study : Study
        The study whose ring model was fitted.
    model : copdea_fem.reduced.rings.RingModel
        That ring model (the start values).
    fit : copdea_fem.reduced.fit.MaterialFit
        The least-squares estimate, its covariance and residual.
    data : dict
        The data file's columns (SI).
    voltage : numpy.ndarray
        Each row's voltage [V] (the column, else the study's load.voltage).
    source : Path, optional
        The data file (an input the folder checks of ``write`` protect).
    """

    study: Study
    model: RingModel
    fit: MaterialFit
    data: dict
    voltage: np.ndarray
    source: Path | None = None

    @property
    def values(self) -> dict[str, float]:
        """The fitted ``{"c10": Pa, "c20": Pa, "c01": Pa}``."""
        return self.fit.as_dict()

    @property
    def standard_error(self) -> dict[str, float]:
        """The 1-sigma standard error of each value [Pa]."""
        from copdea_fem.reduced.fit import PARAMETERS
        return dict(zip(PARAMETERS, map(float, self.fit.standard_error)))

    @property
    def table(self) -> pd.DataFrame:
        """material_fit.csv: ``parameter, value_pa, standard_error_pa``."""
        from copdea_fem.reduced.fit import PARAMETERS
        from copdea_fem.reduced.io import MATERIAL_FIT_COLUMNS
        rows = [dict(zip(MATERIAL_FIT_COLUMNS, (name, float(value), float(error))))
                for name, value, error in zip(PARAMETERS, self.fit.values,
                                              self.fit.standard_error)]
        return data_frame(rows, MATERIAL_FIT_COLUMNS)

    def summary_lines(self) -> list[str]:
        """What ``copdea-fem fit-material`` prints: the values with their errors and the
        ``--set`` options to reuse them."""
        from copdea_fem.reduced.io import material_fit_lines
        return material_fit_lines(self.fit)

    def write(self, folder: str | Path | Claim) -> Path:
        """Write material_fit.csv (and, with ``output.plots``, material_fit.png) in
        ``folder``; or into a held :class:`~copdea_fem.folders.Claim`.  Parameters, return
        and errors as :meth:`Solution.write`."""
        from copdea_fem.folders import result_directory
        from copdea_fem.reduced.io import write_material_fit
        inputs = [*input_files(self.study), self.source]
        with claimed(folder, "fit-material", [item for item in inputs if item]) as target:
            with result_directory(target, "fit-material") as staging:
                write_material_fit(staging, self.study, self.model, self.fit, self.data,
                                   self.voltage)
        return target


def _relaxation_time(value, fit: str) -> float | None:
    """``--relaxation-time`` in s (a quantity such as ``"1 ms"``, or a number in s), only
    with the Prony fit."""
    if value is None:
        return None
    if fit != "prony":
        raise StudyError(f"--relaxation-time is not allowed with --fit {fit}; allowed: "
                         "with --fit prony")
    from copdea_fem.study import convert_quantity
    return convert_quantity("--relaxation-time", value, "s", minimum=1e-12, maximum=1e3)


def calibrate_damping(study: Study | str | Path, spectrum: str | Path | None = None, *,
                      fit: str = "modal", quality_factors: str | Path | None = None,
                      relaxation_time: str | float | None = None,
                      modes_json: str | Path | None = None, window: float = 0.15,
                      allow_large: bool = False,
                      progress: Callable[[str], None] | None = None,
                      out: str | Path | Claim | Output | None = None) -> DampingCalibrationResult:
    """Damping of the model fitted to measured damping (Sect. 5.3; ``copdea-fem
    calibrate-damping``).

    ``fit="modal"`` calibrates the reduced model's b/m of each kept mode on the peak
    heights of a measured average spectrum; ``"rayleigh"`` and ``"prony"`` fit the FE's
    ``membrane.rayleigh_alpha/beta`` or one ``membrane.prony`` term to measured modal
    damping by FE solves (:mod:`copdea_fem.damping_fit`, docs/damping.md).

    Parameters
    ----------
    study : Study, str or Path
        From :func:`load_study`, or a study file.
    spectrum : str or Path, optional
        A CSV with columns ``freq_hz, v_axial, v_radial`` [Hz, m/s], measured with the
        study's excitation (required by ``"modal"``; for the others the measured damping
        when ``quality_factors`` is not given).
    fit : {"modal", "rayleigh", "prony"}, default "modal"
        What is fitted (:data:`DAMPING_FITS`).
    quality_factors : str or Path, optional
        Measured modes for ``"rayleigh"``/``"prony"``: a CSV with columns ``label,
        quality_factor`` (or ``damping_ratio``) [, ``freq_hz``]; every row is checked before
        any work.
    relaxation_time : str or float, optional
        ``"prony"`` only: tau fixed (``"1 ms"``, or a number in s); only the modulus ratio is
        fitted.
    modes_json : str or Path, optional
        An FE modes.json whose coupled frequencies set the reduced model's added masses
        (default ``reduced.modes_json``).
    window : float, default 0.15
        Relative half-width of the peak search around each mode, in (0, 1).
    allow_large : bool, default False
        ``"rayleigh"``/``"prony"``: start even when the FE problem is estimated above the
        size limit.
    progress : callable(str), optional
        As :func:`solve`'s.
    out : str, Path, Claim or Output, optional
        Where to write the result (claimed after the inputs are checked, before any work;
        :meth:`DampingCalibrationResult.write`); default: nothing written.

    Returns
    -------
    DampingCalibrationResult

    Raises
    ------
    StudyError
        A bad study file or key, a missing or malformed input file, a bad option or option
        combination, or an FE problem above the size limit (without ``allow_large``).
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    ReducedModelError
        The reduced model cannot be built or calibrated, or the measured damping cannot be
        fitted by the FE (the CLI's exit 3).
    SolveFailed, PrestressError
        An FE solve of ``"rayleigh"``/``"prony"`` fails (as in :func:`solve`).
    """
    study = as_study(study)
    if fit not in DAMPING_FITS:
        raise StudyError(f"--fit = {fit!r} is not allowed; allowed: one of "
                         + ", ".join(DAMPING_FITS))
    modes_json = _existing(modes_json, "--modes-json") if modes_json else \
        _existing(study.reduced.modes_json, "reduced.modes_json")
    inputs = [*input_files(study), _existing(spectrum, "spectrum file"), modes_json,
              _existing(quality_factors, "--quality-factors")]
    tau = _relaxation_time(relaxation_time, fit)
    if spectrum is not None:
        from copdea_fem.reduced.io import check_window
        check_window(window)
    if fit == "modal" and (spectrum is None or quality_factors):
        raise StudyError("--fit modal (the reduced model's b/m) needs SPECTRUM.csv and no "
                         "--quality-factors; allowed: a spectrum CSV, or --fit rayleigh|prony "
                         "with --quality-factors Q.csv or a SPECTRUM.csv")
    measured = None
    if fit != "modal":
        if quality_factors is not None:     # every row checked before any work
            from copdea_fem.damping_fit import check_measured, read_quality_csv
            measured = read_quality_csv(quality_factors)
            check_measured(measured)
        if spectrum is None and quality_factors is None:
            raise StudyError(f"--fit {fit} needs measured damping; allowed: "
                             "--quality-factors Q.csv or a SPECTRUM.csv")
        check_size(study, allow_large)
    with claiming(out, "calibrate-damping", inputs, study.output.directory) as folder, \
            solving(study), reporting_to(progress):
        if fit == "modal":
            from copdea_fem.reduced.io import calibrate_on_spectrum
            calibration, setup, columns = calibrate_on_spectrum(study, spectrum, modes_json,
                                                                window)
            result = DampingCalibrationResult(study, fit, calibration=calibration, setup=setup,
                                              spectrum=columns, inputs=inputs)
        else:
            from copdea_fem.damping_fit import calibrate_structural_damping, measured_damping
            if measured is None:
                measured = measured_damping(study, spectrum, None, modes_json, window)
            structural = calibrate_structural_damping(study, measured, fit, tau)
            result = DampingCalibrationResult(study, fit, measured=measured,
                                              structural=structural, inputs=inputs)
        if folder is not None:
            result.write(folder)
    return result


@dataclass
class DampingCalibrationResult:
    """The result of :func:`calibrate_damping`: the reduced model's calibrated b/m
    (``fit="modal"``: ``calibration``, ``setup``) or the FE's fitted damping keys
    (``"rayleigh"``, ``"prony"``: ``structural``, fitted to ``measured``).

    Parameters
    ----------
    study : Study
        The study calibrated.
    fit : str
        ``"modal"``, ``"rayleigh"`` or ``"prony"``.
    calibration : copdea_fem.reduced.chirp_response.DampingCalibration, optional
        ``"modal"``: b/m [1/s] and the measured and model peaks [m/s] of each mode.
    setup : copdea_fem.reduced.model.ReducedSetup, optional
        ``"modal"``: the reduced model calibrated.
    spectrum : dict, optional
        ``"modal"``: the measured spectrum's columns (SI).
    measured : copdea_fem.damping_fit.MeasuredDamping, optional
        ``"rayleigh"``/``"prony"``: the measured damping ratios fitted.
    structural : copdea_fem.damping_fit.DampingFit, optional
        ``"rayleigh"``/``"prony"``: the fitted keys and, per mode, the FE's damping with them.
    inputs : list
        The input files (the folder checks of ``write`` protect them).
    """

    study: Study
    fit: str
    calibration: DampingCalibration | None = None
    setup: ReducedSetup | None = None
    spectrum: dict | None = None
    measured: MeasuredDamping | None = None
    structural: DampingFit | None = None
    inputs: list = field(default_factory=list)
    files: list = field(default_factory=list, repr=False)

    @property
    def keys(self) -> dict[str, Any]:
        """The calibrated study keys, as ``--set`` takes them: ``reduced.damping_*`` [1/s]
        (modal; a key shared by several modes takes the lowest one's), else
        ``membrane.rayleigh_alpha`` [1/s] and ``membrane.rayleigh_beta`` [s], or
        ``membrane.prony``."""
        if self.structural is not None:
            return dict(self.structural.keys)
        from copdea_fem.reduced.model import damping_key
        keys: dict[str, float] = {}
        for label, value in zip(self.calibration.labels, self.calibration.damping_per_mass):
            keys.setdefault(damping_key(label), float(value))
        return keys

    @property
    def damping_per_mass(self) -> dict[str, float]:
        """Modal: b/m [1/s] of each calibrated mode (empty for the FE's fits)."""
        if self.calibration is None:
            return {}
        return dict(zip(self.calibration.labels, map(float, self.calibration.damping_per_mass)))

    @property
    def table(self) -> pd.DataFrame:
        """damping_calibration.csv (modal: ``label, freq_hz, measured_peak, model_peak,
        damping_per_mass``) or damping_fit.csv (``rayleigh``, ``prony``: the FE frequency,
        the measured, radiation and fitted damping ratios, the residual, ...)."""
        import pandas as pd
        if self.structural is not None:
            from copdea_fem.damping_fit import FIT_COLUMNS, damping_fit_columns
            columns = FIT_COLUMNS, damping_fit_columns(self.structural)
        else:
            from copdea_fem.reduced.io import CALIBRATION_COLUMNS, damping_calibration_columns
            columns = CALIBRATION_COLUMNS, damping_calibration_columns(self.calibration,
                                                                       self.setup)
        return pd.DataFrame({name: list(values) for name, values in zip(*columns)})

    def summary_lines(self, folder: str | Path | None = None) -> list[str]:
        """What ``copdea-fem calibrate-damping`` prints: per mode the measured and the
        calibrated damping, the notes and the ``--set`` options to reuse; ``folder``: where
        the result was written (a fit of the FE names it)."""
        if self.structural is None:
            from copdea_fem.reduced.io import damping_calibration_lines
            return damping_calibration_lines(self.calibration, self.setup)
        from copdea_fem.damping_fit import damping_fit_lines
        lines = damping_fit_lines(self.structural, self.measured.source)
        if folder is not None:
            lines.append(f"wrote {len(self.files)} files to {folder}")
        return lines

    def write(self, folder: str | Path | Claim) -> Path:
        """Write damping_calibration.csv (and, with ``output.plots``,
        damping_calibration.png) for the modal fit, damping_fit.csv for the FE's, in
        ``folder``; or into a held :class:`~copdea_fem.folders.Claim`.  Parameters, return
        and errors as :meth:`Solution.write`."""
        from copdea_fem.folders import result_directory
        with claimed(folder, "calibrate-damping", [i for i in self.inputs if i]) as target:
            with result_directory(target, "calibrate-damping") as staging:
                if self.structural is not None:
                    from copdea_fem.damping_fit import write_damping_fit
                    files = write_damping_fit(staging, self.structural)
                else:
                    from copdea_fem.reduced.io import write_damping_calibration
                    files = write_damping_calibration(staging, self.study, self.calibration,
                                                      self.setup, self.spectrum)
                self.files = [target / path.name for path in files]
        return target
