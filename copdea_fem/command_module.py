"""Pipeline modules that are also the API function of their name: ``cf.solve(study)``.

``copdea_fem.solve``, ``copdea_fem.response``, ``copdea_fem.sweep`` and
``copdea_fem.diagnose`` are modules (``from copdea_fem.solve import run_solve``, ``import
copdea_fem.sweep``) and, called, the functions :func:`copdea_fem.api.solve`,
:func:`~copdea_fem.api.response`, :func:`~copdea_fem.api.sweep` and
:func:`~copdea_fem.api.diagnose` (issue 25's API: ``sol = cf.solve(study)``).

Each of those modules ends with ``make_callable(__name__)``, which sets its class to
:class:`CommandModule`, a :class:`types.ModuleType` with ``__call__`` (Python allows a
module's ``__class__`` to be a ModuleType subclass: "Customizing module attribute access"
in the reference).  So the module is callable however it was imported -- by the package's
lazy ``__getattr__``, by ``import copdea_fem.solve`` or by a sibling's ``from .solve import
...`` -- and the package needs no hook on its attribute look-ups.  Renaming the modules
(``solve.py`` -> ``solving.py`` with re-exports) would have broken ``from copdea_fem.solve
import ...`` in user code and the other branches.
"""

from __future__ import annotations

import sys
import types


class CommandModule(types.ModuleType):
    """A module that, called, runs the :mod:`copdea_fem.api` function of its last name."""

    def __call__(self, *args, **kwargs):
        from . import api
        return getattr(api, self.__name__.rpartition(".")[2])(*args, **kwargs)


def make_callable(name: str) -> None:
    """Make the imported module ``name`` a :class:`CommandModule` (call it at its end)."""
    sys.modules[name].__class__ = CommandModule
