"""The FE's modes and static forces: :func:`solve` (:class:`Solution`) and :func:`force`
(:class:`ForceCurve`)."""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from copdea_fem.api.calls import (
    as_study,
    check_size,
    data_frame,
    input_files,
    reporting_to,
    solve_checked,
    solving,
)
from copdea_fem.api.folders import Output, claimed, claiming
from copdea_fem.folders import Claim
from copdea_fem.study import Study, StudyError

if TYPE_CHECKING:
    import numpy as np
    import pandas as pd
    import pyvista as pv

    from copdea_fem.fe import Engine, SolveResult

logger = logging.getLogger("copdea_fem")


def solve(study: Study | str | Path, *, allow_large: bool = False,
          mesh_cache: str | Path | None = None,
          progress: Callable[[str], None] | None = None,
          out: str | Path | Claim | Output | None = None) -> Solution:
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
    out : str, Path, Claim or Output, optional
        Where to write the result too (:meth:`Solution.write`), claimed after the inputs
        are checked and before any work (an :class:`Output` without a folder: the study's
        ``output.directory``); default: nothing written.

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
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    """
    study = as_study(study)
    check_size(study, allow_large)        # before the folder is claimed
    with claiming(out, "solve", input_files(study), study.output.directory) as folder:
        with reporting_to(progress):
            result = solve_checked(study, allow_large=True, mesh_cache=mesh_cache)
        solution = Solution(result)
        if folder is not None:
            solution.write(folder, progress)
    return solution


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
        return data_frame(self.rows, MODE_COLUMNS)

    @property
    def rows(self) -> list[dict]:
        """The rows of modes.csv (:func:`copdea_fem.output.tables.mode_rows`)."""
        if self._rows is None:
            from copdea_fem.output.tables import mode_rows
            coupled = self.result.coupled
            self._rows = mode_rows(self.result.modes,
                                   None if coupled is None else coupled.dry_partner_hz)
        return self._rows

    def summary_lines(self, folder: str | Path | None = None) -> list[str]:
        """What ``copdea-fem solve`` prints: the frequency table, the prestress and
        (``folder``: where the result was written) the folder."""
        from copdea_fem.output.tables import frequency_table
        state = self.result.state
        lines = [frequency_table(self.rows),
                 f"prestress: z = {state.z * 1e3:g} mm, V_b = {state.voltage:g} V, disc force "
                 f"{state.disc_force:.4g} N, {state.newton_iterations} Newton iterations"]
        if folder is not None:
            lines.append(f"results in {folder}")
        return lines

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
        from copdea_fem.fe import IN_PLANE, OUT_OF_PLANE, PUMPING
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
        with claimed(folder, "solve", input_files(result.study)) as target:
            with result.timings.stage("output"), result.engine.threads(), reporting_to(progress):
                logger.info("writing results ...")
                with result_directory(target, "solve") as staging:
                    write_solve_files(staging, result, self.rows)
        return target


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

    if study.geometry.inner_radius == 0:
        raise StudyError("geometry.inner_radius = 0 is not allowed for `force`; allowed: > 0 "
                         "(a full membrane has no disc to pull)")
    voltage_list = _quantity_list(voltages, "--voltages", "V")
    if z_max is None:
        z_max = max(study.load.z, 0.018)
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
          progress: Callable[[str], None] | None = None,
          out: str | Path | Claim | Output | None = None) -> ForceCurve:
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
    out : str, Path, Claim or Output, optional
        As :func:`solve`'s (:meth:`ForceCurve.write`).

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
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    """
    study, z_values, voltage_list = prepare_force(as_study(study), voltages, z_max, points,
                                                  allow_large)
    with claiming(out, "force", input_files(study), study.output.directory) as folder:
        curve = compute_force(study, z_values, voltage_list, mesh_cache=mesh_cache,
                              progress=progress)
        if folder is not None:
            curve.write(folder)
    return curve


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
    from copdea_fem.fe import engine_for, run_force

    engine = engine_for(study)
    with solving(study), reporting_to(progress):
        forces = run_force(study, z_values, voltages, cache_dir=mesh_cache, engine=engine)
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

    def summary_lines(self, folder: str | Path | None = None) -> list[str]:
        """What ``copdea-fem force`` prints: F [N] at each z [mm] (rows) and voltage
        (columns), and (``folder``: where the result was written) the folder."""
        lines = [f"{'z [mm]':>8}" + "".join(f"{f'F @ {v / 1e3:g} kV [N]':>16}"
                                            for v in self.voltages)]
        for j, z in enumerate(self.z_values):
            lines.append(f"{z * 1e3:8.3f}" + "".join(f"{self.forces[i, j]:16.5f}"
                                                     for i in range(len(self.voltages))))
        if folder is not None:
            lines.append(f"results in {folder}")
        return lines

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
        with claimed(folder, "force", input_files(self.study)) as target:
            with result_directory(target, "force") as staging:
                write_force_files(staging, self.study, self.z_values, self.voltages,
                                  self.forces)
        return target
