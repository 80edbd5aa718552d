"""The velocity spectra under the study's chirp: the FE's forced response with its sound
(:func:`response`, :class:`ResponseSolution`) and the reduced model's (:func:`spectrum`,
:class:`Spectrum`)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from copdea_fem.api.calls import as_study, check_size, input_files, reporting_to, solving
from copdea_fem.api.folders import Output, claimed, claiming
from copdea_fem.folders import Claim
from copdea_fem.study import Study, StudyError

if TYPE_CHECKING:
    import pandas as pd

    from copdea_fem.forced_response.run import ResponseResult
    from copdea_fem.reduced.chirp_response import SpectrumResult
    from copdea_fem.reduced.model import ReducedSetup

logger = logging.getLogger("copdea_fem")


def response(study: Study | str | Path, *, allow_large: bool = False,
             progress: Callable[[str], None] | None = None,
             out: str | Path | Claim | Output | None = None) -> ResponseSolution:
    """Forced response of the coupled FE under the study's chirp, with radiated sound
    (``copdea-fem response``, nothing written).

    Parameters
    ----------
    study : Study, str or Path
        From :func:`load_study`, or a study file (``load.voltage`` > 0: the forcing is
        V_b dC/du; the ``response`` keys set the method, microphones and peaks).
    allow_large : bool, default False
        Start even when the problem is estimated above the size limit.
    progress : callable(str), optional
        As :func:`solve`'s.
    out : str, Path, Claim or Output, optional
        As :func:`solve`'s (:meth:`ResponseSolution.write`).

    Returns
    -------
    ResponseSolution
        The velocity spectra, the SPL at the microphones and the modal basis;
        :meth:`ResponseSolution.write` writes the files.

    Raises
    ------
    StudyError
        A bad study file or key, ``load.voltage = 0``, an air domain the membrane would
        lift out of, or a problem above the size limit (without ``allow_large``).
    SolveFailed
        The air mesh cannot follow the membrane, or the modal basis's eigen solve fails.
    PrestressError
        The prestress (Newton) solve fails (as in :func:`solve`).
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    """
    from copdea_fem.fe import engine_for
    from copdea_fem.forced_response.run import prepare_order_zero
    from copdea_fem.forced_response.segments import segment_response

    study = as_study(study)
    engine = engine_for(study, forced_response=True)
    check_size(study, allow_large, engine)
    with claiming(out, "response", input_files(study), study.output.directory) \
            as folder:
        with solving(study), reporting_to(progress):
            problem = prepare_order_zero(study, engine=engine)
            result = segment_response(problem, engine)
        solution = ResponseSolution(result)
        if folder is not None:
            solution.write(folder, progress)
    return solution


def _average_table(result):
    """The average velocity spectra of a response or reduced-model result as a DataFrame
    (the columns of ``*_average.csv``: ``freq_hz, v_axial, v_radial`` [Hz, m/s])."""
    import pandas as pd

    from copdea_fem.forced_response.run import AVERAGE_COLUMNS
    return pd.DataFrame(dict(zip(AVERAGE_COLUMNS, (result.frequency_hz, result.average_axial,
                                                   result.average_radial))))


def _points_table(result):
    """The point velocity spectra at Q1-Q3 as a DataFrame (``*_points.csv``) [m/s]."""
    import pandas as pd

    from copdea_fem.forced_response.run import POINT_COLUMNS
    columns = (result.frequency_hz,) + tuple(values[:, i] for i in range(3)
                                             for values in (result.point_axial,
                                                            result.point_radial))
    return pd.DataFrame(dict(zip(POINT_COLUMNS, columns)))


class ResponseSolution:
    """The result of :func:`response`: spectra and SPL as DataFrames, ``write``.

    Parameters
    ----------
    result : copdea_fem.forced_response.run.ResponseResult
        The spectra per line and what produced them (kept as ``self.result``).
    """

    def __init__(self, result: ResponseResult) -> None:
        self.result = result

    @property
    def average(self) -> pd.DataFrame:
        """response_average.csv: ``freq_hz, v_axial, v_radial`` [Hz, m/s]."""
        return _average_table(self.result)

    @property
    def points(self) -> pd.DataFrame:
        """response_points.csv: ``freq_hz`` and the axial/radial velocity at Q1-Q3 [m/s]."""
        return _points_table(self.result)

    @property
    def spl(self) -> pd.DataFrame:
        """spl.csv: ``freq_hz, spl_<microphone>`` [Hz, dB re 20 uPa]."""
        import pandas as pd
        r = self.result
        data = {"freq_hz": r.frequency_hz}
        for j, (name, _) in enumerate(r.microphones):
            data[f"spl_{name}"] = r.spl_db[:, j]
        return pd.DataFrame(data)

    @property
    def modes(self) -> pd.DataFrame:
        """response_modes.csv: the modal basis (label, kind, frequencies, damping b/m [1/s],
        membrane energy fraction); empty for a direct solve."""
        import pandas as pd

        from copdea_fem.forced_response.run import MODE_COLUMNS
        r = self.result
        if not r.modes:
            return pd.DataFrame(columns=list(MODE_COLUMNS))
        columns = ([m.label for m in r.modes], [m.kind for m in r.modes],
                   [m.freq_hz for m in r.modes], [m.freq_im_hz for m in r.modes],
                   list(r.basis.damping_per_mass),
                   [m.membrane_energy_fraction for m in r.modes])
        return pd.DataFrame(dict(zip(MODE_COLUMNS, columns)))

    @property
    def modal_forcing(self) -> pd.DataFrame:
        """modal_forcing.csv: ``segment, label, freq_hz, force_re, force_im`` -- the modal
        force of each in-band structural mode per volt of each segment's AC input
        [N/(V sqrt(kg))], the mode mass-normalised
        (:mod:`copdea_fem.forced_response.segments`)."""
        import pandas as pd

        from copdea_fem.forced_response.segments import MODAL_FORCING_COLUMNS
        rows = self.result.modal_forcing
        return pd.DataFrame(dict(zip(MODAL_FORCING_COLUMNS, (
            [r.segment for r in rows], [r.label for r in rows], [r.freq_hz for r in rows],
            [r.force.real for r in rows], [r.force.imag for r in rows]))))

    @property
    def peaks_hz(self) -> list[float]:
        return list(self.result.peaks_hz)

    def summary_lines(self) -> list[str]:
        """What ``copdea-fem response`` prints: the modal basis, the peaks with their
        velocities and SPL, the timings
        (:func:`copdea_fem.forced_response.run.summary_lines`)."""
        from copdea_fem.forced_response.run import summary_lines
        return summary_lines(self.result)

    def write(self, folder: str | Path | Claim,
              progress: Callable[[str], None] | None = None) -> Path:
        """Write every file of ``copdea-fem response --out folder``; or into a held
        :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        import time

        from copdea_fem.forced_response.files import write_response
        from copdea_fem.forced_response.run import reduced_spectrum

        result = self.result
        study = result.problem.study
        with claimed(folder, "response", input_files(study)) as target:
            with reporting_to(progress):
                logger.info("writing results ...")
            start = time.perf_counter()
            write_response(result, target, reduced_spectrum(study, result))
            result.timings["output"] = time.perf_counter() - start
        return target


def spectrum(study: Study | str | Path, modes_json: str | Path | None = None, *,
             out: str | Path | Claim | Output | None = None) -> Spectrum:
    """Reduced-model velocity spectra under the study's chirp (Sect. 3.2, eq. 19;
    ``copdea-fem spectrum``, nothing written).

    Parameters
    ----------
    study : Study, str or Path
        From :func:`load_study`, or a study file (a membrane with a disc).
    modes_json : str or Path, optional
        An FE modes.json whose coupled frequencies set the added masses (default
        ``reduced.modes_json``; without one the ``reduced.*`` and ``effects.*`` keys set
        them, :mod:`copdea_fem.reduced.model`).
    out : str, Path, Claim or Output, optional
        As :func:`solve`'s (:meth:`Spectrum.write`).

    Returns
    -------
    Spectrum
        The reduced model and its spectra; :meth:`Spectrum.write` writes the files.

    Raises
    ------
    StudyError
        A bad study file or key, a membrane without a disc, a modes.json that is missing
        or not one.
    ReducedModelError
        The reduced model cannot be built or solved for these inputs (the CLI's exit 3).
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    """
    from copdea_fem.inputs import read_text
    from copdea_fem.reduced.io import fe_frequencies
    from copdea_fem.reduced.model import build_reduced, spectra_of

    study = as_study(study)
    if modes_json is not None:
        read_text(modes_json, "--modes-json", error=StudyError)
    elif study.reduced.modes_json:
        read_text(study.reduced.modes_json, "reduced.modes_json", error=StudyError)
    inputs = [*input_files(study), modes_json or study.reduced.modes_json]
    with claiming(out, "spectrum", inputs, study.output.directory) as folder:
        fe, fe_path = fe_frequencies(study, modes_json)
        setup = build_reduced(study, fe)
        result = Spectrum(study, setup, spectra_of(setup), modes_json, fe_path)
        if folder is not None:
            result.write(folder)
    return result


@dataclass
class Spectrum:
    """The result of :func:`spectrum`: the reduced model (``setup``) and its spectra.

    Parameters
    ----------
    study : Study
        The study.
    setup : copdea_fem.reduced.model.ReducedSetup
        The reduced model, its chirp and its modes.
    result : copdea_fem.reduced.chirp_response.SpectrumResult
        The velocity spectra, ``|FFT|/N`` per line [m/s].
    modes_json : str or Path, optional
        The FE modes.json given to :func:`spectrum`, if any.
    fe_path : str or Path, optional
        The modes.json whose coupled frequencies set the added masses (``modes_json`` or
        ``reduced.modes_json``), if any.
    """

    study: Study
    setup: ReducedSetup
    result: SpectrumResult
    modes_json: str | Path | None = None   # as given to :func:`spectrum`
    fe_path: str | Path | None = None      # the modes.json read (that or reduced.modes_json)

    @property
    def summary(self) -> dict:
        """What ``copdea-fem spectrum`` prints (``lines``), the rows of reduced_modes.csv with
        the source of each added mass (``modes``) and Annex I's P1-P3 (``pumping_hz``)."""
        from copdea_fem.reduced.io import spectrum_summary
        return spectrum_summary(self.study, self.setup, self.fe_path)

    def summary_lines(self, folder: str | Path | None = None) -> list[str]:
        """What ``copdea-fem spectrum`` prints: :attr:`summary`'s lines and (``folder``:
        where the result was written) the folder."""
        return self.summary["lines"] + ([f"results in {folder}"] if folder is not None else [])

    @property
    def average(self) -> pd.DataFrame:
        """spectrum_average.csv: ``freq_hz, v_axial, v_radial`` [Hz, m/s]."""
        return _average_table(self.result)

    @property
    def points(self) -> pd.DataFrame:
        """spectrum_points.csv: the velocities at Q1-Q3 [m/s]."""
        return _points_table(self.result)

    @property
    def modes(self) -> pd.DataFrame:
        """reduced_modes.csv: ``label, freq_hz, modal_mass, added_mass, damping`` (SI)."""
        import pandas as pd
        reduced = self.setup.reduced
        return pd.DataFrame({"label": list(reduced.labels), "freq_hz": reduced.frequency_hz,
                             "modal_mass": reduced.modal_mass,
                             "added_mass": reduced.added_mass, "damping": reduced.damping})

    def write(self, folder: str | Path | Claim) -> Path:
        """Write every file of ``copdea-fem spectrum --out folder``; or into a held
        :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        from copdea_fem.folders import result_directory
        from copdea_fem.reduced.io import write_spectrum_files
        inputs = input_files(self.study) + ([self.modes_json] if self.modes_json else [])
        with claimed(folder, "spectrum", inputs) as target:
            with result_directory(target, "spectrum") as staging:
                write_spectrum_files(staging, self.study, self.setup, self.result)
        return target
