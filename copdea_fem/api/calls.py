"""What every function of the API shares: the study it is given (:func:`load_study`, a
:class:`Study` as it is, the file it came from), the resource guard, the progress callable,
the solver's failures as :class:`SolveFailed`, the FE solve behind both
(:func:`solve_checked`), and tables as DataFrames.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

from copdea_fem.study import Study, StudyError

if TYPE_CHECKING:
    from copdea_fem.fe import Engine, SolveResult


class SolveFailed(RuntimeError):
    """A solver failure, described for the user: what failed, at which load, which key to
    change (the CLI's exit 3).

    Raised by :func:`solve`, :func:`correlate` and :func:`response` in place of the FE's own
    errors (the air mesh that cannot follow the membrane, an eigen solve that fails or finds
    too many modes); a failed prestress is a :class:`~copdea_fem.fe.prestress.PrestressError`.

    Parameters
    ----------
    message : str
        What failed, at which ``load.z`` and ``load.voltage``, and which keys to change.
    """


def reporting_to(progress):
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
        The resolved study (defaults filled in, every value in SI, frozen); its ``source``,
        the file it was read from, serves the folder checks of the results' ``write``.

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
    return _load(path, overrides=overrides)


def as_study(study: Study | str | Path) -> Study:
    """A study file read, or a :class:`Study` as it is (checked when it was made, and
    frozen)."""
    if isinstance(study, Study):
        return study
    if not isinstance(study, (str, Path)):
        raise StudyError(f"study = {type(study).__name__} is not allowed; allowed: a "
                         "Study from load_study or a study file's path")
    return load_study(study)


def input_files(study: Study) -> list:
    """The file ``study`` was read from, if any (``study.source``): the folder checks of
    the results' ``write`` keep results away from it."""
    return [study.source] if study.source is not None else []


def _load_text(study) -> str:
    load = study.load
    return f"load.z = {load.z * 1e3:g} mm, load.voltage = {load.voltage:g} V"


@contextlib.contextmanager
def solving(study):
    """Solver failures -> :class:`SolveFailed`: what failed, at which load, which key to change
    (a Netgen failure, ``NgException``: the mesh keys)."""
    from copdea_fem.fe import (
        EigenResidualError,
        EigenSolverError,
        MeshMotionError,
        TooManyModesError,
    )
    eigen = study.eigen
    advice = {
        MeshMotionError: ("the air mesh motion", "air.domain_radius, mesh.membrane_size or "
                          "load.z"),
        EigenResidualError: ("the eigen solve", f"eigen.residual_tol (now "
                             f"{eigen.residual_tol:g}) or eigen.backend"),
        TooManyModesError: ("the eigen solve", f"eigen.max_modes (now {eigen.max_modes}) or "
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
    """The resource guard (:func:`copdea_fem.fe.check_size`) unless ``allow_large``.

    ``engine``: the study's engine where the caller has resolved it (the API's functions
    resolve it once and pass it here and down); else it is resolved here
    (:func:`copdea_fem.fe.engine_for`), and only when the guard runs."""
    if not allow_large:
        from copdea_fem.fe import check_size as guard
        from copdea_fem.fe import engine_for
        guard(study, engine=engine if engine is not None else engine_for(study))


def solve_checked(study: Study, *, allow_large: bool = False,
                  mesh_cache: str | Path | None = None) -> SolveResult:
    """The FE solve of every API function that solves one (:func:`copdea_fem.api.solve`,
    :func:`copdea_fem.api.correlate`): the resource guard unless ``allow_large``
    (:func:`check_size`, a :class:`StudyError` before meshing), then
    :func:`copdea_fem.fe.pipeline.run_solve` with the solver's failures as
    :class:`SolveFailed` (:func:`solving`)."""
    from copdea_fem.fe import engine_for, run_solve

    engine = engine_for(study)
    check_size(study, allow_large, engine)
    with solving(study):
        return run_solve(study, cache_dir=mesh_cache, engine=engine)


def data_frame(rows: list[dict], columns) -> pandas.DataFrame:  # noqa: F821
    import pandas as pd
    return pd.DataFrame(rows, columns=list(columns))
