"""Python API: the commands of ``copdea-fem`` as functions that return their results.

::

    import copdea_fem as cf
    study = cf.load_study("studies/g1_z16_v2.yaml", {"load.voltage": "1 kV"})  # validated, SI
    sol = cf.solve(study)          # nothing written unless asked
    sol.modes                      # pandas.DataFrame: the columns of modes.csv, one row per mode
    sol.membrane("(0,1)")          # pyvista grid of the whole membrane with that mode's fields
    sol.air("(0,1)")               # pyvista grid of the air with its pressure fields (coupled)
    sol.write("results/g1")        # the files and folder rules of `copdea-fem solve --out`

Every command has this shape (:func:`response`, :func:`force`, :func:`spectrum`,
:func:`fit_material`, :func:`calibrate_damping`, :func:`sweep`, :func:`diagnose`,
:func:`identify`, :func:`correlate`, :func:`synthesise`, :func:`excite`,
:func:`statespace`): a function that checks its inputs
and options before any work and returns a result object with its tables as
:class:`pandas.DataFrame`, its printed summary (``summary_lines``) and a ``write(folder)``
that writes the command's files under the rules of :mod:`copdea_fem.folders` (the only
writer of those files).  Given ``out`` (a folder, or an :class:`Output` as the command line
asks for one), the function claims that folder after its checks and before any work and
writes the result there itself.  The command line (:mod:`copdea_fem.cli`) is one call of
these per command, and imports nothing else of the package.

Progress messages go to the :mod:`logging` loggers ``"copdea_fem.*"`` at level INFO, so
nothing is printed unless asked (``logging.basicConfig(level=logging.INFO)``); a callable
passed as ``progress`` receives each message (a handler forwards them to it while the call
runs, and nothing is printed).  Errors are the command line's, with the same messages:
:class:`~copdea_fem.study.StudyError` (bad input; the CLI's exit 2),
:class:`~copdea_fem.folders.OutputFolderError` (a folder that may not be written; exit 2),
:class:`SolveFailed` and :class:`~copdea_fem.fe.prestress.PrestressError` (a solve that
failed for a physical or numerical reason; exit 3), and
:class:`~copdea_fem.reduced.rings.ReducedModelError` (the reduced model, or the diagnosis's
model, cannot be built or evaluated for these inputs; exit 3).  ``PrestressError`` and
``ReducedModelError`` are importable from here too (loaded on first access, as are
:data:`MAX_UNKNOWNS` and :data:`MESH_CACHE_VARIABLE`, so that ``import copdea_fem.api``
stays light).  A name of an old spelling (``executor="local"``, ``fe_workers``) still works
for one release, with a :class:`FutureWarning`.  Each function's *Raises*
section says which it can raise.

:func:`diagnose`, :func:`identify` and :func:`correlate` take a measured.yaml's path or the
:class:`~copdea_fem.measured.MeasuredSet` :func:`load_measured` read from it, as the others
take a study file or a :class:`~copdea_fem.study.Study`: each file is then read once.

A :class:`~copdea_fem.study.Study` is checked where it is made (:func:`load_study`, its
:meth:`~copdea_fem.study.Study.replace`, :func:`dataclasses.replace`) and is frozen, so a
function takes it as it is: no hand edit can reach the solver unchecked (a changed copy is
checked like a file; an unknown key, a wrong type or a value out of range is a
:class:`~copdea_fem.study.StudyError`).  A study file's path is accepted too, and read.
A Netgen failure while meshing is a :class:`SolveFailed` naming the mesh keys.

The modules: :mod:`~copdea_fem.api.calls` (what every function shares: the study given,
the resource guard, progress, :class:`SolveFailed`), :mod:`~copdea_fem.api.folders` (the
result folders of ``write`` and of ``out``), then the functions with their results:
:mod:`~copdea_fem.api.fe_results` (:func:`solve`, :func:`force`),
:mod:`~copdea_fem.api.response_results` (:func:`response`, :func:`spectrum`),
:mod:`~copdea_fem.api.calibration_results` (:func:`fit_material`,
:func:`calibrate_damping`), :mod:`~copdea_fem.api.sweep_results` (:func:`sweep`),
:mod:`~copdea_fem.api.control_results` (:func:`excite`, :func:`statespace`),
:mod:`~copdea_fem.api.measured_results` (:func:`load_measured`, :func:`diagnose`,
:func:`identify`, :func:`identify_file`, :func:`correlate`) and
:mod:`~copdea_fem.api.synthetic_results` (:func:`synthesise`, :func:`catalogue_table`).
Their public names are imported from here.
"""

from copdea_fem.api.calibration_results import (
    DampingCalibrationResult,
    MaterialFitResult,
    calibrate_damping,
    fit_material,
)
from copdea_fem.api.calls import SolveFailed, check_size, load_study, solving
from copdea_fem.api.control_results import Excitation, StateSpace, excite, statespace
from copdea_fem.api.fe_results import (
    ForceCurve,
    Solution,
    compute_force,
    force,
    prepare_force,
    solve,
)
from copdea_fem.api.measured_results import (
    CorrelateResult,
    Diagnosis,
    FileIdentifyResult,
    IdentifyResult,
    correlate,
    diagnose,
    identify,
    identify_file,
    load_measured,
)
from copdea_fem.api.response_results import ResponseSolution, Spectrum, response, spectrum
from copdea_fem.api.folders import Output
from copdea_fem.api.sweep_results import SweepResult, sweep
from copdea_fem.api.synthetic_results import SyntheticData, catalogue_table, synthesise
from copdea_fem.folders import Claim as Claim
from copdea_fem.folders import OutputFolderError
from copdea_fem.progress import progress_to
from copdea_fem.study import Study as Study
from copdea_fem.study import StudyError, reference_table

#: The API's names in the order of the API page (autodoc's ``bysource`` follows it).
__all__ = ["load_study", "solve", "Solution", "response", "ResponseSolution",  # noqa: RUF022
           "force", "prepare_force", "compute_force", "ForceCurve", "spectrum", "Spectrum",
           "fit_material", "MaterialFitResult", "calibrate_damping",
           "DampingCalibrationResult", "sweep", "SweepResult", "load_measured", "diagnose",
           "Diagnosis", "identify", "IdentifyResult", "identify_file",
           "FileIdentifyResult", "correlate", "CorrelateResult",
           "synthesise", "SyntheticData", "catalogue_table", "excite", "Excitation",
           "statespace", "StateSpace", "reference_table", "Output",
           "SolveFailed", "StudyError", "OutputFolderError", "PrestressError",
           "ReducedModelError", "solving", "check_size", "progress_to"]

#: Names loaded on first access (PEP 562), from modules that import NumPy or NGSolve: the
#: errors of a failed solve, and the FE's settings the command line names (the resource
#: guard's limit of unknowns, the environment variable of the mesh cache folder:
#: :mod:`copdea_fem.fe`).
_LAZY = {"PrestressError": ("copdea_fem.fe", "PrestressError"),
         "ReducedModelError": ("copdea_fem.reduced.rings", "ReducedModelError"),
         "MAX_UNKNOWNS": ("copdea_fem.fe", "MAX_UNKNOWNS"),
         "MESH_CACHE_VARIABLE": ("copdea_fem.fe", "MESH_CACHE_VARIABLE")}


def __getattr__(name):
    if name in _LAZY:
        import importlib
        module, attribute = _LAZY[name]
        return getattr(importlib.import_module(module), attribute)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
