"""A parameter sweep with tracked modes: :func:`sweep` (:class:`SweepResult`), run in the
folder asked for or a private one."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from copdea_fem.api.calls import check_size, reporting_to
from copdea_fem.api.folders import Output, RunFolder, claiming, run_folder
from copdea_fem.folders import Claim

if TYPE_CHECKING:
    import pandas as pd

    from copdea_fem.sweeps.gather import SweepOutcome
    from copdea_fem.sweeps.spec import Sweep


def sweep(sweep_file: str | Path, overrides: dict[str, Any] | list[str] | None = None, *,
          out: str | Path | Claim | Output | None = None, executor: str | None = None,
          workers: int | None = None, scheduler: str | Any | None = None,
          chain_length: int | str | None = None, reuse: bool | dict | None = None,
          allow_large: bool = False,
          progress: Callable[[str], None] | None = None) -> SweepResult:
    """A parameter sweep with tracked modes (``copdea-fem sweep``).

    Parameters
    ----------
    sweep_file : str or Path
        A sweep YAML file: the base study, the axes over study keys, the model.
    overrides : dict or list of str, optional
        Overrides of the base study's keys, as :func:`load_study`'s.
    out : str, Path, Claim or Output, optional
        The result folder (resumable: a second call continues), the
        :class:`~copdea_fem.folders.Claim` of one the caller holds, or an :class:`Output`
        (claimed here after the checks; without a folder, the file's
        ``output.directory``); without it the sweep runs in a private temporary folder,
        kept while the result lives (``write`` copies it).
    executor : str, optional
        ``"inline"`` (in this process), ``"processes"`` (worker processes) or ``"dask"`` (a
        Dask cluster; :mod:`copdea_fem.parallel`); default the file's
        ``execution.executor``, else inline.  The old ``"local"`` and ``"pool"`` work with a
        deprecation warning.
    workers : int, optional
        Worker processes of the ``processes`` executor, or of the local Dask cluster
        (default: the file's ``execution.workers`` for ``processes``, one per core for
        ``dask``).
    scheduler : str or distributed.Client, optional
        With ``executor="dask"``: a running Dask scheduler's address (``tcp://HOST:PORT``)
        or a connected client; without it (and no ``execution.scheduler``) a local cluster
        is started for the sweep and closed at its end.  Refused with another executor.
    chain_length : "auto" or int, optional
        Points per continuation chain (default ``execution.chain_length``).
    reuse : bool or dict, optional
        What neighbouring points share, as ``execution.reuse`` (default the file's):
        ``False`` solves every point from scratch.
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
        :class:`~copdea_fem.sweeps.axes.SweepError`), an unknown executor, a bad worker
        count, chain length or reuse, a scheduler without ``executor="dask"`` or one that
        does not answer, or a point above the size limit (without ``allow_large``).
    OutputFolderError
        ``out`` may not be written (as in :meth:`Solution.write`).
    """
    from copdea_fem.parallel import check_scheduler, check_scheduler_answers
    from copdea_fem.study import parse_overrides
    from copdea_fem.sweeps import load_sweep, parse_reuse, run_sweep

    if isinstance(overrides, (list, tuple)):
        overrides = parse_overrides(list(overrides))
    spec = load_sweep(sweep_file, overrides=overrides)
    check_scheduler(executor or spec.execution.executor, scheduler)
    address = spec.execution.scheduler if scheduler is None else scheduler
    if (executor or spec.execution.executor) == "dask" and isinstance(address, str):
        check_scheduler_answers(address)             # before the folder is claimed
    if spec.model != "reduced":
        for point in spec.points:
            check_size(point.study, allow_large, point.engine)
    settings = {"executor": executor, "workers": workers, "scheduler": scheduler,
                "chain_length": chain_length,
                "reuse": None if reuse is None else parse_reuse(reuse)}
    with reporting_to(progress):
        if out is not None:
            with claiming(out, "sweep", [sweep_file], spec.output_directory) as record:
                folder = run_folder("sweep", record)
                outcome = run_sweep(spec, out_dir=record, **settings)
        else:
            folder = run_folder("sweep", out)
            outcome = run_sweep(spec, out_dir=folder.path, **settings)
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
    folder : RunFolder
        The folder the sweep ran in (``out``, or a private temporary one).
    source : Path, optional
        The sweep file (an input the folder checks of ``write`` protect).
    """

    spec: Sweep
    outcome: SweepOutcome
    folder: RunFolder = field(repr=False)
    source: Path | None = None

    @property
    def table(self) -> pd.DataFrame:
        """sweep.csv: one row per point and tracked mode."""
        import pandas as pd
        return pd.read_csv(self.folder.path / "sweep.csv")

    @property
    def failed(self) -> dict:
        return dict(self.outcome.failed)

    @property
    def all_failed(self) -> bool:
        """No point produced a result (the CLI's exit 3)."""
        return len(self.outcome.failed) == len(self.spec.points)

    def summary_lines(self) -> list[str]:
        """What ``copdea-fem sweep`` prints: points computed, resumed and failed, the
        tracked modes, the files (:func:`copdea_fem.sweeps.format_summary`)."""
        from copdea_fem.sweeps import format_summary
        return format_summary(self.spec, self.outcome).splitlines()

    def write(self, folder: str | Path | Claim) -> Path:
        """Write the sweep's files (sweep.csv/json/png, the point store) in ``folder``; or
        into a held :class:`~copdea_fem.folders.Claim`.  Parameters, return and errors as
        :meth:`Solution.write`."""
        return self.folder.copy_to(folder, "sweep", [self.source] if self.source else [])
