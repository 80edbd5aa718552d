"""Python API: the commands of ``copdea-fem`` as functions that return their results.

::

    import copdea_fem as cf
    study = cf.load_study("studies/g1_z16_v2.yaml", {"load.voltage": "1 kV"})  # validated, SI
    sol = cf.solve(study)          # nothing written unless asked
    sol.modes                      # pandas.DataFrame: the columns of modes.csv, one row per mode
    sol.membrane("(0,1)")          # pyvista grid of the whole membrane with that mode's fields
    sol.air("(0,1)")               # pyvista grid of the air with its pressure fields (coupled)
    sol.write("results/g1")        # the files and folder rules of `copdea-fem solve --out`

:func:`response`, :func:`force`, :func:`spectrum`, :func:`sweep` and :func:`diagnose`
have the same shape: a result object with its tables as :class:`pandas.DataFrame` and a
``write(folder)`` that writes the command's files under the rules of
:mod:`copdea_fem.folders`.  The command line (:mod:`copdea_fem.cli`) calls these.

Progress messages go to the :mod:`logging` loggers ``"copdea_fem.*"`` at level INFO, so
nothing is printed unless asked (``logging.basicConfig(level=logging.INFO)``); a callable
passed as ``progress`` receives each message (a handler forwards them to it while the call
runs, and nothing is printed).  Errors are the command line's, with the same messages:
:class:`~copdea_fem.study.StudyError` (bad input; the CLI's exit 2),
:class:`~copdea_fem.folders.OutputFolderError` (a folder that may not be written; exit 2),
:class:`SolveFailed` and :class:`~copdea_fem.fe.prestress.PrestressError` (a solve that
failed for a physical or numerical reason; exit 3), and
:class:`~copdea_fem.reduced.rings.ReducedModelError` (the reduced model, or the diagnosis's
model, cannot be built or evaluated for these inputs; exit 3).  Each function's *Raises*
section says which it can raise.

A :class:`~copdea_fem.study.Study` given to a function is validated again first
(:meth:`~copdea_fem.study.Study.checked`): a study changed by hand after :func:`load_study`
is checked like a file (an unknown key, a wrong type or a value out of range is a
:class:`~copdea_fem.study.StudyError`; a deleted key takes its default), so no hand edit
reaches the solver unchecked.  A Netgen failure while meshing is a :class:`SolveFailed`
naming the mesh keys.
"""

from __future__ import annotations

import contextlib
import logging
import shutil
import tempfile
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Sequence

from copdea_fem.folders import Claim, OutputFolderError
from copdea_fem.study import Study, StudyError

if TYPE_CHECKING:
    import numpy as np
    import pandas as pd
    import pyvista as pv

    from copdea_fem.diagnosis.select import DiagnosisResult
    from copdea_fem.fe.engines import Engine
    from copdea_fem.fe.pipeline import SolveResult
    from copdea_fem.forced_response.run import ResponseResult
    from copdea_fem.reduced.model import ReducedSetup
    from copdea_fem.reduced.response import SpectrumResult
    from copdea_fem.sweeps.gather import SweepOutcome
    from copdea_fem.sweeps.spec import Sweep
    from copdea_fem.vibrometer.scan import IdentifiedSet

__all__ = ["load_study", "solve", "response", "force", "spectrum", "sweep", "diagnose",
           "Solution", "ResponseSolution", "ForceCurve", "Spectrum", "SweepResult",
           "Diagnosis", "SolveFailed", "StudyError", "OutputFolderError", "identify",
           "IdentifyResult"]

logger = logging.getLogger("copdea_fem")

#: Study -> the file it was read from (the folder checks of ``write`` need it).
_SOURCES: "weakref.WeakKeyDictionary[Study, Path]" = weakref.WeakKeyDictionary()


class SolveFailed(RuntimeError):
    """A solver failure, described for the user: what failed, at which load, which key to
    change (the CLI's exit 3).

    Raised by :func:`solve` and :func:`response` in place of the FE's own errors (the air
    mesh that cannot follow the membrane, an eigen solve that fails or finds too many
    modes); a failed prestress is a :class:`~copdea_fem.fe.prestress.PrestressError`.

    Parameters
    ----------
    message : str
        What failed, at which ``load.z`` and ``load.voltage``, and which keys to change.
    """


def _progress(progress):
    """While inside, each progress message (INFO record of the ``copdea_fem`` loggers) goes
    to ``progress(message)`` if it is a callable; otherwise the loggers alone."""
    if callable(progress):
        from copdea_fem.progress import progress_to
        return progress_to(progress, only_info=True)
    return contextlib.nullcontext()


def load_study(path: str | Path, overrides: dict[str, Any] | list[str] | None = None) -> Study:
    """Read, override, validate and resolve a study file (every value in SI).

    Parameters
    ----------
    path : str or Path
        A study YAML file (``copdea-fem schema`` lists its keys).
    overrides : dict or list of str, optional
        ``{"load.voltage": "1 kV"}`` (values with units, as in the file) or the command
        line's ``["load.voltage=1 kV"]``.

    Returns
    -------
    Study
        The resolved study (defaults filled in, every value in SI); the file it was read
        from is remembered for the folder checks of the results' ``write``.

    Raises
    ------
    StudyError
        A missing or unreadable file, an unknown key, a value out of range or in a wrong
        unit, a malformed override.
    """
    from copdea_fem.study import load_study as _load
    from copdea_fem.study import parse_overrides

    if isinstance(overrides, (list, tuple)):
        overrides = parse_overrides(list(overrides))
    elif overrides is not None and not isinstance(overrides, dict):
        parse_overrides(overrides)          # refused, naming what is allowed
    study = _load(path, overrides=overrides)
    _SOURCES[study] = Path(path)
    return study


def _as_study(study: Study | str | Path) -> Study:
    """A study file read, or a :class:`Study` validated again (:meth:`Study.checked`: a hand
    edit after :func:`load_study` is checked like a file), remembering its source file."""
    if not isinstance(study, Study):
        if not isinstance(study, (str, Path)):
            raise StudyError(f"study = {type(study).__name__} is not allowed; allowed: a "
                             "Study from load_study or a study file's path")
        return load_study(study)
    checked = study.checked()
    if study in _SOURCES:
        _SOURCES[checked] = _SOURCES[study]
    return checked


def _inputs(study: Study) -> list:
    source = _SOURCES.get(study)
    return [source] if source is not None else []


def _load_text(study) -> str:
    load = study["load"]
    return f"load.z = {load['z'] * 1e3:g} mm, load.voltage = {load['voltage']:g} V"


@contextlib.contextmanager
def solving(study):
    """Solver failures -> :class:`SolveFailed`: what failed, at which load, which key to change
    (a Netgen failure, ``NgException``: the mesh keys)."""
    from copdea_fem.fe.ale import MeshMotionError
    from copdea_fem.fe.eigen import EigenResidualError, EigenSolverError, TooManyModesError
    eigen = study["eigen"]
    advice = {
        MeshMotionError: ("the air mesh motion", "air.domain_radius, mesh.membrane_size or "
                          "load.z"),
        EigenResidualError: ("the eigen solve", f"eigen.residual_tol (now "
                             f"{eigen['residual_tol']:g}) or eigen.backend"),
        TooManyModesError: ("the eigen solve", f"eigen.max_modes (now {eigen['max_modes']}) or "
                            "the band eigen.f_min..eigen.f_max"),
        EigenSolverError: ("the eigen solve", "the band eigen.f_min..eigen.f_max, "
                           "eigen.max_damping_ratio or eigen.backend"),
    }
    try:
        yield
    except tuple(advice) as error:
        what, keys = next(item for kind, item in advice.items() if isinstance(error, kind))
        raise SolveFailed(f"{what} failed at {_load_text(study)}: {error}; change {keys}") \
            from None
    except Exception as error:
        if type(error).__name__ != "NgException":     # Netgen's one error type
            raise
        message = " ".join(str(error).split()) or "an error"
        raise SolveFailed(f"Netgen failed ({message}); change mesh.membrane_size, "
                          "mesh.air_size or mesh.grading (or the geometry.* radii)") from None


def check_size(study: Study, allow_large: bool = False, engine: Engine | None = None) -> None:
    """The resource guard (:func:`copdea_fem.fe.engines.check_size`) unless ``allow_large``."""
    if not allow_large:
        from copdea_fem.fe.engines import check_size as guard
        guard(study, engine=engine)


@contextlib.contextmanager
def _claimed(folder: str | Path | Claim, command: str, inputs) -> Path:
    """The target of ``folder``, claimed for ``command`` (a held :class:`Claim`: as it is)."""
    from copdea_fem.folders import held
    with held(folder, command, inputs=inputs) as record:
        yield record.target


def _frame(rows: list[dict], columns) -> "pandas.DataFrame":  # noqa: F821
    import pandas as pd
    return pd.DataFrame(rows, columns=list(columns))


# -- solve ---------------------------------------------------------------------------------
def solve(study: Study | str | Path, *, allow_large: bool = False,
          mesh_cache: str | Path | None = None,
          progress: Callable[[str], None] | None = None) -> Solution:
    """Prestress and modes of a study (``copdea-fem solve``, nothing written).

    Parameters
    ----------
    study : Study, str or Path
        From :func:`load_study`, or a study file.
    allow_large : bool, default False
        Start even when the problem is estimated above the size limit.
    mesh_cache : str or Path, optional
        Mesh cache folder of the 3-D engine (default as the CLI's ``--mesh-cache``).
    progress : callable(str), optional
        Receives each progress message while the call runs (default: the ``copdea_fem``
        logger at INFO only, nothing printed unless logging is configured).

    Returns
    -------
    Solution
        The modes (dry, or coupled with the air when ``air.enabled``), the prestress and
        the timings; :meth:`Solution.write` writes the files.

    Raises
    ------
    StudyError
        A bad study file or key, an ``eigen.backend`` this machine lacks, an air domain
        the membrane would lift out of, or a problem above the size limit (without
        ``allow_large``).
    SolveFailed
        Netgen cannot mesh the geometry, the air mesh cannot follow the membrane, or the
        eigen solve fails (residuals, too many modes in the band, a band it cannot cover).
    PrestressError
        The prestress (Newton) solve fails: a loss of tension (the membrane would
        wrinkle), pull-in, or no convergence after ``prestress.max_cuts`` step halvings.
    """
    from copdea_fem.fe.engines import engine_for
    from copdea_fem.fe.pipeline import run_solve

    study = _as_study(study)
    engine = engine_for(study)
    check_size(study, allow_large, engine)
    with solving(study), _progress(progress):
        result = run_solve(study, cache_dir=mesh_cache, engine=engine)
    return Solution(result)


class Solution:
    """The result of :func:`solve`: the mode table, mode fields as grids, ``write``.

    Parameters
    ----------
    result : copdea_fem.fe.pipeline.SolveResult
        The engine, prestress state, modes with their vectors, eigen summary and timings
        (kept as ``self.result``).
    """

    def __init__(self, result: SolveResult) -> None:
        self.result = result
        self._fields = None
        self._rows = None

    @property
    def study(self) -> Study:
        return self.result.study

    @property
    def modes(self) -> pd.DataFrame:
        """:class:`pandas.DataFrame` of the modes: the columns of modes.csv (SI: Hz, kg)."""
        from copdea_fem.output.tables import MODE_COLUMNS
        return _frame(self.rows, MODE_COLUMNS)

    @property
    def rows(self) -> list[dict]:
        """The rows of modes.csv (:func:`copdea_fem.output.tables.mode_rows`)."""
        if self._rows is None:
            from copdea_fem.output.tables import mode_rows
            coupled = self.result.coupled
            self._rows = mode_rows(self.result.modes,
                                   None if coupled is None else coupled.dry_partner_hz)
        return self._rows

    @property
    def prestress(self) -> dict:
        """The prestress block of modes.json: z [m], voltage [V], disc force [N], steps."""
        from copdea_fem.output.results import prestress_summary
        return prestress_summary(self.result.state)

    @property
    def timings(self) -> dict[str, float]:
        """Wall time per stage [s]."""
        return dict(self.result.timings.seconds)

    @property
    def labels(self) -> list[str]:
        """Labels of the modes with a membrane file (all but air modes), in file order."""
        return [mode.label for mode in self._structural()]

    @property
    def engine(self) -> Engine:
        """The engine that solved it (:class:`copdea_fem.fe.engines.Engine`)."""
        return self.result.engine

    @property
    def axisymmetric(self) -> bool:
        return self.engine.name == "axisymmetric"

    def _output(self):
        """The engine's result fields for every structural mode (as the files are written)."""
        if self._fields is None:
            self._fields = self.engine.output(self.result.state, self._structural())
        return self._fields

    def _structural(self) -> list:
        from copdea_fem.fe.modes import IN_PLANE, OUT_OF_PLANE, PUMPING
        return [mode for mode in self.result.modes
                if mode.kind in (OUT_OF_PLANE, PUMPING, IN_PLANE)]

    def _find(self, label: str) -> int:
        labels = self.labels
        if label not in labels:
            raise KeyError(f"no mode labelled {label!r}; labels: {', '.join(labels)}")
        return labels.index(label)

    def membrane(self, label: str) -> pv.UnstructuredGrid:
        """pyvista grid of the whole membrane with mode ``label``'s fields, equal to its
        ``mode_NNN_<label>.vtu`` (displacement re/im/abs, normal displacement re/im, normal
        velocity; peak ``|u| = 1``; points on the prestressed shape).

        Parameters
        ----------
        label : str
            A mode label of :attr:`labels`, e.g. ``"(0,1)"``.

        Returns
        -------
        pyvista.UnstructuredGrid

        Raises
        ------
        KeyError
            No structural mode has that label (the message lists the labels).
        """
        mode = self._structural()[self._find(label)]
        with self.engine.threads():
            _, mesh = next(self._output().mode_meshes([mode]))
        return mesh.to_pyvista()

    def air(self, label: str) -> pv.UnstructuredGrid:
        """pyvista grid of the air with mode ``label``'s pressure (re/im/abs, Pa per unit peak
        membrane displacement; cell data ``pml``, ``lower_half`` and, with an enclosure,
        ``cavity``), the blocks of its ``air_NNN_<label>*.vtu`` in one grid.  Only for a
        coupled solve (``air.enabled: true``).

        Parameters
        ----------
        label : str
            A mode label of :attr:`labels`, e.g. ``"(0,1)"``, or an enclosure's cavity mode,
            e.g. ``"cavity(1,0,0)a"`` (docs/enclosures.md).

        Returns
        -------
        pyvista.UnstructuredGrid

        Raises
        ------
        StudyError
            A dry solve (``air.enabled: false``): there is no air field.
        KeyError
            No structural mode has that label (the message lists the labels).
        """
        coupled = self.result.coupled
        if coupled is None:
            raise StudyError("air.enabled = false has no air field; allowed: a coupled solve "
                             "(air.enabled: true)")
        cavity = [mode for mode in self.result.modes if mode.cavity_orders
                  and mode.label == label]
        mode = cavity[0] if cavity else self._structural()[self._find(label)]
        k = next(k for k, item in enumerate(self.result.modes) if item is mode)
        pressure = coupled.pressures[k]
        with self.engine.threads():
            _, mesh = next(self._output().air_meshes(coupled.operators, [mode], [pressure]))
        return mesh.to_pyvista()

    def write(self, folder: str | Path | Claim,
              progress: Callable[[str], None] | None = None) -> Path:
        """Write every file of ``copdea-fem solve --out folder``.

        Parameters
        ----------
        folder : str, Path or Claim
            The result folder (modes.csv/json, resolved study, ParaView files and plots as
            ``output.*`` asks), checked first under the rules of :mod:`copdea_fem.folders`
            (an earlier result of ``solve`` is replaced only when the new one is complete);
            or the :class:`~copdea_fem.folders.Claim` of a folder the caller holds.
        progress : callable(str), optional
            As :func:`solve`'s.

        Returns
        -------
        Path
            The folder written.

        Raises
        ------
        OutputFolderError
            A folder that may not be written (:mod:`copdea_fem.folders`: the working or
            home folder, one holding an input file, a file, a folder with another
            command's result or foreign files, one another run is writing).
        copdea_fem.folders.ResultWriteError
            The files could not be written or put in place (a full disk, a refused
            rename); the message says where the complete result is.
        """
        from copdea_fem.folders import result_directory
        from copdea_fem.output.results import write_solve_files

        result = self.result
        with _claimed(folder, "solve", _inputs(result.study)) as target:
            with result.timings.stage("output"), result.engine.threads(), _progress(progress):
                logger.info("writing results ...")
                with result_directory(target, "solve") as staging:
                    write_solve_files(staging, result, self.rows)
        return target


# -- response ------------------------------------------------------------------------------
def response(study: Study | str | Path, *, allow_large: bool = False,
             progress: Callable[[str], None] | None = None) -> ResponseSolution:
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
    """
    from copdea_fem.fe.engines import engine_for
    from copdea_fem.forced_response.run import forced_response, prepare_order_zero

    study = _as_study(study)
    engine = engine_for(study)
    check_size(study, allow_large, engine)
    with solving(study), _progress(progress):
        problem = prepare_order_zero(study, engine)
        result = forced_response(problem)
    return ResponseSolution(result)


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
    def peaks_hz(self) -> list[float]:
        return list(self.result.peaks_hz)

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
        with _claimed(folder, "response", _inputs(study)) as target:
            with _progress(progress):
                logger.info("writing results ...")
            start = time.perf_counter()
            write_response(result, target, reduced_spectrum(study, result))
            result.timings["output"] = time.perf_counter() - start
        return target


# -- force ---------------------------------------------------------------------------------
def _quantity_list(values, key: str, unit: str) -> list[float]:
    from copdea_fem.study import Key, convert_value
    spec = Key(unit, 0.0, key, minimum=0)
    items = values.split(",") if isinstance(values, str) else list(values)
    return [convert_value(key, spec, item.strip() if isinstance(item, str) else item)
            for item in items if not isinstance(item, str) or item.strip()]


def prepare_force(study: Study, voltages: str | Sequence[str | float] = "0 kV, 3 kV",
                  z_max: str | float | None = None, points: int = 10,
                  allow_large: bool = False) -> tuple[Study, np.ndarray, list[float]]:
    """Check the inputs of :func:`force` before any work.

    Parameters
    ----------
    study : Study
        From :func:`load_study`; its ``load.z`` is set to ``z_max`` (and checked).
    voltages, z_max, points, allow_large
        As :func:`force`'s.

    Returns
    -------
    tuple of (Study, numpy.ndarray, list of float)
        The study, the z values to solve [m] (0 left out) and the voltages [V].

    Raises
    ------
    StudyError
        The bad input, named: a membrane without a disc, a voltage or z that is not a
        quantity, fewer than 2 points, no voltage, a ``z_max`` the geometry refuses, or a
        problem above the size limit (without ``allow_large``).
    """
    import numpy as np

    if study["geometry"]["inner_radius"] == 0:
        raise StudyError("geometry.inner_radius = 0 is not allowed for `force`; allowed: > 0 "
                         "(a full membrane has no disc to pull)")
    voltage_list = _quantity_list(voltages, "--voltages", "V")
    if z_max is None:
        z_max = max(study["load"]["z"], 0.018)
    else:
        z_max = _quantity_list(z_max if isinstance(z_max, str) else [z_max], "--z-max", "m")[0]
    if points < 2:
        raise StudyError(f"--points = {points} is not allowed; allowed: >= 2")
    if not voltage_list:
        raise StudyError(f"--voltages = {voltages!r} is not allowed; allowed: a comma "
                         "separated list such as '0 kV, 3 kV'")
    study.replace({"load.z": z_max})  # validates z_max against the geometry
    check_size(study, allow_large)
    return study, np.linspace(0.0, z_max, points)[1:], voltage_list


def force(study: Study | str | Path, voltages: str | Sequence[str | float] = "0 kV, 3 kV",
          z_max: str | float | None = None, points: int = 10, *, allow_large: bool = False,
          mesh_cache: str | Path | None = None,
          progress: Callable[[str], None] | None = None) -> ForceCurve:
    """Static disc force F(z) at each voltage (Fig. 4b; ``copdea-fem force``, nothing
    written).

    Parameters
    ----------
    study : Study, str or Path
        From :func:`load_study`, or a study file (a membrane with a disc:
        ``geometry.inner_radius`` > 0).
    voltages : str or sequence of str or float, default "0 kV, 3 kV"
        ``"0 kV, 3 kV"`` or a list of quantities (``"2 kV"``, or numbers in V).
    z_max : str or float, optional
        The largest z (``"18 mm"``, or a number in m); default max(load.z, 18 mm).
    points : int, default 10
        z values from 0 to ``z_max``, 0 included (0 is not solved); at least 2.
    allow_large : bool, default False
        Start even when the problem is estimated above the size limit.
    mesh_cache : str or Path, optional
        As :func:`solve`'s.
    progress : callable(str), optional
        As :func:`solve`'s.

    Returns
    -------
    ForceCurve
        ``forces[i, j]`` [N] at ``voltages[i]`` and ``z_values[j]``.

    Raises
    ------
    StudyError
        A bad study file or key, or a bad input of :func:`prepare_force`.
    PrestressError
        The prestress (Newton) solve fails at one of the loads (as in :func:`solve`).
    """
    study, z_values, voltage_list = prepare_force(_as_study(study), voltages, z_max, points,
                                                  allow_large)
    return compute_force(study, z_values, voltage_list, mesh_cache=mesh_cache,
                         progress=progress)


def compute_force(study: Study, z_values: Sequence[float] | np.ndarray,
                  voltages: Sequence[float], *, mesh_cache: str | Path | None = None,
                  progress: Callable[[str], None] | None = None) -> ForceCurve:
    """F(z) [N] at the checked inputs of :func:`prepare_force`.

    Parameters
    ----------
    study : Study
        The study :func:`prepare_force` returned.
    z_values : sequence of float or numpy.ndarray
        The z values [m].
    voltages : sequence of float
        The voltages [V].
    mesh_cache, progress
        As :func:`solve`'s.

    Returns
    -------
    ForceCurve

    Raises
    ------
    PrestressError
        The prestress (Newton) solve fails at one of the loads.
    """
    from copdea_fem.fe.pipeline import run_force

    with solving(study), _progress(progress):
        forces = run_force(study, z_values, voltages, cache_dir=mesh_cache)
    return ForceCurve(study, z_values, list(voltages), forces)


@dataclass
class ForceCurve:
    """The result of :func:`force`: ``forces[i, j]`` [N] at ``voltages[i]`` [V] and
    ``z_values[j]`` [m].

    Parameters
    ----------
    study : Study
        The study solved (its ``load.z`` set to the largest z).
    z_values : numpy.ndarray
        The z values [m], shape (n_z,).
    voltages : list of float
        The voltages [V].
    forces : numpy.ndarray
        The disc force [N], shape (len(voltages), n_z).
    """

    study: Study
    z_values: np.ndarray
    voltages: list[float]
    forces: np.ndarray

    @property
    def table(self) -> pd.DataFrame:
        """force_displacement.csv: ``voltage_v, z_m, force_n`` (long format)."""
        import pandas as pd
        rows = [(voltage, z, self.forces[i, j]) for i, voltage in enumerate(self.voltages)
                for j, z in enumerate(self.z_values)]
        return pd.DataFrame(rows, columns=["voltage_v", "z_m", "force_n"])

    def write(self, folder: str | Path | Claim) -> Path:
        """Write every file of ``copdea-fem force --out folder``; or into a held
        :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        from copdea_fem.folders import result_directory
        from copdea_fem.output.results import write_force_files
        with _claimed(folder, "force", _inputs(self.study)) as target:
            with result_directory(target, "force") as staging:
                write_force_files(staging, self.study, self.z_values, self.voltages,
                                  self.forces)
        return target


# -- spectrum (reduced model) ----------------------------------------------------------------
def spectrum(study: Study | str | Path, modes_json: str | Path | None = None) -> Spectrum:
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
    """
    from copdea_fem.inputs import read_text
    from copdea_fem.reduced.io import fe_frequencies
    from copdea_fem.reduced.model import build_reduced, spectra_of

    study = _as_study(study)
    if modes_json is not None:
        read_text(modes_json, "--modes-json", error=StudyError)
    elif study["reduced"]["modes_json"]:
        read_text(study["reduced"]["modes_json"], "reduced.modes_json", error=StudyError)
    fe, fe_path = fe_frequencies(study, modes_json)
    setup = build_reduced(study, fe)
    return Spectrum(study, setup, spectra_of(setup), modes_json, fe_path)


@dataclass
class Spectrum:
    """The result of :func:`spectrum`: the reduced model (``setup``) and its spectra.

    Parameters
    ----------
    study : Study
        The study.
    setup : copdea_fem.reduced.model.ReducedSetup
        The reduced model, its chirp and its modes.
    result : copdea_fem.reduced.response.SpectrumResult
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
        inputs = _inputs(self.study) + ([self.modes_json] if self.modes_json else [])
        with _claimed(folder, "spectrum", inputs) as target:
            with result_directory(target, "spectrum") as staging:
                write_spectrum_files(staging, self.study, self.setup, self.result)
        return target


# -- sweep and diagnose: run in a private folder unless one is given -------------------------
@dataclass
class _Folder:
    """A command's result folder: the one asked for, or a private temporary one."""

    path: Path
    temporary: Any = None

    def copy_to(self, folder, command: str, inputs) -> Path:
        from copdea_fem.folders import result_directory
        with _claimed(folder, command, inputs) as target:
            if target.resolve() == self.path.resolve():
                return target
            with result_directory(target, command) as staging:
                for item in self.path.iterdir():
                    if item.name.startswith(".copdea-fem"):
                        continue
                    if item.is_dir():
                        shutil.copytree(item, staging / item.name)
                    else:
                        shutil.copy2(item, staging / item.name)
        return target


def _private(command: str, out) -> _Folder:
    if out is not None:
        return _Folder(Path(out))
    temporary = tempfile.TemporaryDirectory(prefix=f"copdea-fem-{command}-")
    return _Folder(Path(temporary.name) / "result", temporary)


def sweep(sweep_file: str | Path, overrides: dict[str, Any] | list[str] | None = None, *,
          out: str | Path | None = None, executor: str | None = None,
          workers: int | None = None, allow_large: bool = False,
          progress: Callable[[str], None] | None = None) -> SweepResult:
    """A parameter sweep with tracked modes (``copdea-fem sweep``).

    Parameters
    ----------
    sweep_file : str or Path
        A sweep YAML file: the base study, the axes over study keys, the model.
    overrides : dict or list of str, optional
        Overrides of the base study's keys, as :func:`load_study`'s.
    out : str or Path, optional
        The result folder (resumable: a second call continues); without it the sweep runs
        in a private temporary folder, kept while the result lives (``write`` copies it).
    executor : str, optional
        ``"local"`` (default), ``"pool"`` (worker processes) or ``"dask"``.
    workers : int, optional
        Worker processes of the ``pool`` executor.
    allow_large : bool, default False
        Start even when a point's problem is estimated above the size limit.
    progress : callable(str), optional
        As :func:`solve`'s (one line per point and a few more).

    Returns
    -------
    SweepResult
        The tracked-mode table and the points that failed (a failed point is recorded,
        not raised).

    Raises
    ------
    StudyError
        A bad sweep file, base study, axis or override (a
        :class:`~copdea_fem.sweeps.axes.SweepError`), an unknown executor or a bad worker
        count, or a point above the size limit (without ``allow_large``).
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    """
    from copdea_fem.study import parse_overrides
    from copdea_fem.sweeps import load_sweep, run_sweep

    if isinstance(overrides, (list, tuple)):
        overrides = parse_overrides(list(overrides))
    spec = load_sweep(sweep_file, overrides=overrides)
    if spec.model != "reduced":
        for point in spec.points:
            check_size(point.study, allow_large)
    folder = _private("sweep", out)
    with _progress(progress):
        if out is not None:
            from copdea_fem.folders import held
            with held(out, "sweep", [sweep_file]) as record:
                outcome = run_sweep(spec, out_dir=record, executor=executor, workers=workers)
        else:
            outcome = run_sweep(spec, out_dir=folder.path, executor=executor, workers=workers)
    return SweepResult(spec, outcome, folder, Path(sweep_file))


@dataclass
class SweepResult:
    """The result of :func:`sweep`: ``outcome`` (:class:`copdea_fem.sweeps.gather.SweepOutcome`).

    Parameters
    ----------
    spec : copdea_fem.sweeps.spec.Sweep
        The sweep as read (its points, their studies, the continuation path).
    outcome : copdea_fem.sweeps.gather.SweepOutcome
        What the run did: the folder, the table, the computed, resumed and failed points.
    folder : _Folder
        The folder the sweep ran in (``out``, or a private temporary one).
    source : Path, optional
        The sweep file (an input the folder checks of ``write`` protect).
    """

    spec: Sweep
    outcome: SweepOutcome
    folder: _Folder = field(repr=False)
    source: Path | None = None

    @property
    def table(self) -> pd.DataFrame:
        """sweep.csv: one row per point and tracked mode."""
        import pandas as pd
        return pd.read_csv(self.folder.path / "sweep.csv")

    @property
    def failed(self) -> dict:
        return dict(self.outcome.failed)

    def write(self, folder: str | Path | Claim) -> Path:
        """Write the sweep's files (sweep.csv/json/png, the point store) in ``folder``; or
        into a held :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        return self.folder.copy_to(folder, "sweep", [self.source] if self.source else [])


def diagnose(measured: str | Path, *, alpha: float = 0.05, model: str | None = None,
             fe_cache: str | Path | None = None, fe_workers: int | None = None,
             progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Which catalogued effects the model lacks, from measured resonances and spectra
    (``copdea-fem diagnose``, nothing written).

    Parameters
    ----------
    measured : str or Path
        A measured.yaml: the base study, the conditions and their measured files.
    alpha : float, default 0.05
        Significance level of each step (false-alarm probability), in (0, 1).
    model : str, optional
        ``"fe"`` or ``"reduced"``: the model of record, in place of measured.yaml's
        ``model``.
    fe_cache : str or Path, optional
        Cache folder of the FE solves (``model: fe``; default as the CLI's
        ``--fe-cache``).
    fe_workers : int, optional
        Processes solving FE studies side by side (``model: fe``; default as the CLI's
        ``--fe-workers``).
    progress : callable(str), optional
        As :func:`solve`'s.

    Returns
    -------
    Diagnosis
        The verdict, the missing effects and the report's content;
        :meth:`Diagnosis.write` writes the report.

    Raises
    ------
    StudyError
        ``alpha`` outside (0, 1), a bad measured.yaml, measured file or base study (a
        :class:`~copdea_fem.diagnosis.measured.MeasuredDataError`), or conditions the
        base model cannot evaluate.
    ReducedModelError
        The model cannot be built or evaluated (with ``model: fe``, an FE that cannot be
        solved: :class:`~copdea_fem.diagnosis.anchored.FEFailure`; the CLI's exit 3).
    """
    from copdea_fem.diagnosis import diagnose_measured

    with _progress(progress):
        result = diagnose_measured(measured, alpha=alpha, model=model, fe_cache=fe_cache,
                                   fe_workers=fe_workers)
    return Diagnosis(result, Path(measured))


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

    def write(self, folder: str | Path | Claim) -> Path:
        """Write report.md, diagnosis.json, figures and final_study.yaml in ``folder``; or
        into a held :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        from copdea_fem.diagnosis.report import write_report
        from copdea_fem.folders import result_directory
        inputs = [self.source] + [path for condition in self.result.measured.conditions
                                  for path in condition.files.values()]
        with _claimed(folder, "diagnose", inputs) as target:
            with result_directory(target, "diagnose") as staging:
                write_report(self.result, staging)
        return target


# -- identify (vibrometer scans) -------------------------------------------------------------
def identify(measured: str | Path, *, progress: Callable[[str], None] | None = None,
             **options) -> IdentifyResult:
    """The modes of every scan of a measured.yaml (``copdea-fem identify``, nothing written).

    Each condition with ``scan: FILE`` is read (:func:`copdea_fem.vibrometer.uff.read_scan`,
    checked on the device) and identified automatically in its ``band`` (default: the
    scan's lines above 0 Hz): LSCF poles stable over the model orders, LSFD residues as
    shapes (:mod:`copdea_fem.vibrometer.identify`; nothing from the FE).

    Parameters
    ----------
    measured : str or Path
        A measured.yaml with at least one condition with a ``scan``.
    progress : callable(str), optional
        As :func:`solve`'s.
    **options
        Passed to :func:`copdea_fem.vibrometer.identify.identify_scan` (``f_min``,
        ``f_max`` [Hz] in place of the conditions' bands, ``max_order``, ``components``, ``frequency_tolerance``,
        ``damping_tolerance``, ``max_damping``, ``min_stable_orders``).

    Returns
    -------
    IdentifyResult

    Raises
    ------
    StudyError
        A bad measured.yaml, scan file or option, or no condition with a scan (a
        :class:`~copdea_fem.diagnosis.measured.MeasuredDataError`).
    """
    from copdea_fem.diagnosis.measured import MeasuredDataError, load_measured
    from copdea_fem.vibrometer.identify import OPTIONS, identify_scan
    from copdea_fem.vibrometer.scan import IdentifiedSet

    for name in options:
        if name not in OPTIONS:
            raise StudyError(f"identify option {name!r} is not allowed (unknown option); "
                             f"allowed: {', '.join(OPTIONS)}")
    measured_set = load_measured(measured)
    scanned = [c for c in measured_set.conditions if c.scan is not None]
    if not scanned:
        raise MeasuredDataError(f"measured file {measured}: no condition has a scan; "
                                "allowed: at least one condition with scan: FILE (.uff/.unv)")
    sets = []
    with _progress(progress):
        for condition in scanned:
            logger.info("identifying %s (%d channels, %d lines, largest distance off the "
                        "device %.2f mm)", condition.name, condition.scan.n_channels,
                        condition.scan.frequencies.size, 1e3 * condition.scan_distance)
            frequencies = condition.scan.frequencies
            band = {"f_min": max(condition.band[0], float(frequencies[frequencies > 0][0])),
                    "f_max": min(condition.band[1], float(frequencies[-1]))}
            found = identify_scan(condition.scan, **{**band, **options})
            sets.append(IdentifiedSet(condition.name, condition.scan, found.modes,
                                      found.diagram))
    return IdentifyResult(tuple(sets), Path(measured),
                          [p for c in measured_set.conditions for p in c.files.values()])


@dataclass
class IdentifyResult:
    """The result of :func:`identify`: ``sets`` (one
    :class:`~copdea_fem.vibrometer.scan.IdentifiedSet` per scanned condition), ``table``,
    ``write``."""

    sets: tuple[IdentifiedSet, ...]
    source: Path | None = None
    files: list = field(default_factory=list)

    @property
    def table(self) -> pd.DataFrame:
        """identified.csv as a DataFrame (condition, test_mode, freq_hz, damping_ratio, mpc)."""
        from copdea_fem.vibrometer.identify import IDENTIFIED_COLUMNS, identified_rows
        return _frame(identified_rows(self.sets), IDENTIFIED_COLUMNS)

    def write(self, folder: str | Path | Claim) -> Path:
        """Write identified.csv, stabilisation_<condition>.png and shapes_<condition>/
        (VTU per mode, shapes.pvd) in ``folder``; or into a held
        :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        from copdea_fem.folders import result_directory
        from copdea_fem.vibrometer.identify import write_identified
        with _claimed(folder, "identify", [self.source, *self.files]) as target:
            with result_directory(target, "identify") as staging:
                write_identified(staging, self.sets)
        return target
