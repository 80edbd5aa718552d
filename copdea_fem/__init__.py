"""copdea-fem: vibro-acoustic FE and reduced models of circular out-of-plane DEAs.

Pipeline (see DESIGN notes): study -> geometry/mesh -> prestress -> linearised
operators -> eigen step -> modes -> outputs; reduced model and diagnosis on top.

The Python API (:mod:`copdea_fem.api`) is available from the package; ``import copdea_fem``
stays light (NGSolve, pyvista and pandas load on first use)::

    import copdea_fem as cf
    sol = cf.solve(cf.load_study("studies/g1_z16_v2_quick.yaml"))
"""

import sys as _sys
import types as _types

__version__ = "0.1.0"

#: Names of :mod:`copdea_fem.api` exported here, imported on first access.
_API = ("load_study", "solve", "response", "force", "spectrum", "sweep", "diagnose",
        "Solution", "ResponseSolution", "ForceCurve", "Spectrum", "SweepResult", "Diagnosis",
        "SolveFailed", "StudyError", "OutputFolderError")

__all__ = list(_API)

#: API functions named like a submodule: ``copdea_fem.solve`` is the module
#: :mod:`copdea_fem.solve` (so ``copdea_fem.solve.run_solve`` and ``import
#: copdea_fem.solve`` keep working) and, called, the function :func:`copdea_fem.api.solve`.
_COMMAND_MODULES = ("solve", "response", "sweep", "diagnose")


class _CommandModule(_types.ModuleType):
    """A submodule that is also the API function of its name (:data:`_COMMAND_MODULES`)."""

    def __call__(self, *args, **kwargs):
        from . import api
        return getattr(api, self.__name__.rpartition(".")[2])(*args, **kwargs)


class _Package(_types.ModuleType):
    """The package: a command submodule becomes callable when it is bound to the package.

    The import system binds every imported submodule to its parent with ``setattr`` (once,
    however it was imported: ``import copdea_fem.solve``, a sibling's ``from .solve import
    ...``, or :func:`__getattr__` below), so the class is set there, once; attribute reads
    of the package are not intercepted.  The knowledge stays here, at the top: a command
    module that made itself callable would reference the API from below (an import circle,
    ``tests/test_imports.py``)."""

    def __setattr__(self, name, value):
        if name in _COMMAND_MODULES and type(value) is _types.ModuleType:
            value.__class__ = _CommandModule
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package


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
