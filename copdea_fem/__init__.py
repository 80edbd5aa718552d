"""copdea-fem: vibro-acoustic FE and reduced models of circular out-of-plane DEAs.

Pipeline (see DESIGN notes): study -> geometry/mesh -> prestress -> linearised
operators -> eigen step -> modes -> outputs; reduced model and diagnosis on top.

The Python API (:mod:`copdea_fem.api`) is available from the package; ``import copdea_fem``
stays light (NGSolve, pyvista and pandas load on first use)::

    import copdea_fem as cf
    sol = cf.solve(cf.load_study("studies/g1_z16_v2_quick.yaml"))
"""

__version__ = "0.1.0"

#: Names of :mod:`copdea_fem.api` exported here, imported on first access.
_API = ("load_study", "solve", "response", "force", "spectrum", "sweep", "diagnose",
        "Solution", "ResponseSolution", "ForceCurve", "Spectrum", "SweepResult", "Diagnosis",
        "SolveFailed", "StudyError", "OutputFolderError")

__all__ = list(_API)

#: API functions named like a submodule: ``copdea_fem.solve`` is the module
#: :mod:`copdea_fem.solve` (so ``copdea_fem.solve.run_solve`` and ``import
#: copdea_fem.solve`` keep working) and, called, the function :func:`copdea_fem.api.solve`
#: (each of these modules makes itself callable: :mod:`copdea_fem.command_module`).
_COMMAND_MODULES = ("solve", "response", "sweep", "diagnose")


def __getattr__(name):
    if name in _COMMAND_MODULES:
        import importlib
        return importlib.import_module(f"{__name__}.{name}")
    if name in _API:
        from . import api
        return getattr(api, name)
    raise AttributeError(f"module 'copdea_fem' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_API))
